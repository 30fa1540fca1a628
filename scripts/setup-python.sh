#!/usr/bin/env bash
# The Python package: a virtual environment in .venv with the pinned tools
# (crates/lssi-py/requirements.txt), the `lssi` package built by maturin and installed into
# it. Its tests compare the package with the `lssi` command (target/release/lssi), which
# scripts/setup.sh builds (or, when it is missing, this script).
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
# In the host's target directory (CARGO_TARGET_DIR): the crates it shares with the `lssi`
# command, built alike, are compiled once (crates/lssi-py/Cargo.toml keeps the same profile).
(cd crates/lssi-py && CARGO_TARGET_DIR="$root/target" VIRTUAL_ENV="$root/.venv" \
    PATH="$root/.venv/bin:$PATH" maturin develop --release --locked --quiet)
if [[ ! -x target/release/lssi ]]; then
    cargo test --workspace --release --locked --no-run
fi
.venv/bin/python -c "import lssi; print('lssi', lssi.__name__, 'ready')"
