#!/usr/bin/env bash
# lssi against PySINDy: makes bench/pysindy/.venv (pinned PySINDy), builds the release
# `lssi`, and prints the comparison table (bench/pysindy/README.md shows the last one).
#
#   bench/pysindy/run.sh            # the table
#   bench/pysindy/run.sh --repeats 1  # faster: one run per wall time
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --upgrade pip
    # scikit-learn 1.7+ changed a private helper PySINDy 2.0.0 calls; 1.6.1 is the last that works.
    "$venv/bin/pip" install --quiet "pysindy==2.0.0" "scikit-learn==1.6.1" "numpy==2.4.6" "scipy==1.17.1"
fi
(cd "$root" && cargo build --quiet --release -p lssi-host)
target="${CARGO_TARGET_DIR:-$root/target}"
LSSI="$target/release/lssi" exec "$venv/bin/python" "$here/compare.py" "$@"
