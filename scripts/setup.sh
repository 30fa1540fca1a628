#!/usr/bin/env bash
# One-time set-up on a fresh machine: the Cortex-M4F target and the size tools.
# (rustup does not install anything by itself here: RUSTUP_AUTO_INSTALL=0.)
set -euo pipefail
rustup target add thumbv7em-none-eabihf
rustup component add llvm-tools rustfmt clippy
# The Python package in .venv (maturin, numpy, pandas, dask, pytest; the `lssi` command too).
bash "$(dirname "$0")/setup-python.sh"
