#!/usr/bin/env bash
# The Python package: a virtual environment in .venv with the pinned tools
# (crates/lssi-py/requirements.txt), the `lssi` package built by maturin and installed into
# it, and the `lssi` command built (the tests compare the package with it).
#   bash scripts/setup-python.sh && .venv/bin/python -m pytest crates/lssi-py/tests -q -n auto
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
python=${PYTHON:-python3}
if [[ ! -x .venv/bin/python ]]; then
    "$python" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check -r crates/lssi-py/requirements.txt
# maturin develop builds the extension (release) and installs the package in the venv.
(cd crates/lssi-py && VIRTUAL_ENV="$root/.venv" PATH="$root/.venv/bin:$PATH" \
    maturin develop --release --locked --quiet)
cargo build --release --locked -p lssi-host --bin lssi
.venv/bin/python -c "import lssi; print('lssi', lssi.__name__, 'ready')"
