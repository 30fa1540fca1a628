#!/usr/bin/env bash
# PySINDy against the lssi Python package on the same generated recordings: one table.
# Makes bench/peers/.venv (pinned PySINDy and the lssi package built by maturin), builds
# the `lssi` command (it generates the recordings), and prints the table (RESULTS.md keeps
# the last one).      bench/peers/run.sh
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    # scikit-learn 1.7+ changed a private helper PySINDy 2.0.0 calls; 1.6.1 is the last that works.
    "$venv/bin/pip" install --quiet --disable-pip-version-check "pysindy==2.0.0" "scikit-learn==1.6.1" \
        "numpy==2.4.6" "scipy==1.17.1" "maturin==1.16.0"
fi
(cd "$root/crates/lssi-py" && VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH" maturin develop --release --locked --quiet)
(cd "$root" && cargo build --quiet --release --locked -p lssi-host --bin lssi)
LSSI="${CARGO_TARGET_DIR:-$root/target}/release/lssi" exec "$venv/bin/python" "$here/peers.py" "$@"
