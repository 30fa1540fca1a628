#!/usr/bin/env bash
# One-time set-up on a fresh machine: the Cortex-M4F target and the size tools, the firmware
# images, QEMU (to run them: `lssi monitor --qemu`, the QEMU tests) and the Python package.
# (rustup does not install anything by itself here: RUSTUP_AUTO_INSTALL=0.)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
rustup target add thumbv7em-none-eabihf
rustup component add llvm-tools rustfmt clippy
# The firmware images for QEMU's mps2-an386: lssi-firmware (the replay target) and
# lssi-standalone (the instrument that samples its own sensor).
(cd crates/lssi-firmware && cargo build --release --locked)
# QEMU, from the distribution's packages, when it is missing and apt-get is there.
if ! command -v qemu-system-arm >/dev/null; then
    if command -v apt-get >/dev/null; then
        sudo=""
        if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
        $sudo apt-get update -qq
        $sudo apt-get install -y -qq --no-install-recommends qemu-system-arm
    else
        echo "qemu-system-arm is missing and there is no apt-get: install it to run the firmware (lssi monitor --qemu, the QEMU tests)." >&2
    fi
fi
# The `lssi` command (target/release/lssi) and the tests, in one build: the tests' dependencies
# switch features on in crates the command shares with them (rand, lssi-testkit, ...), so
# `cargo build -p lssi-host` alone would compile those crates, and the host library, a second
# time for README's test command (`cargo test --workspace --release`).
cargo test --workspace --release --locked --no-run
# The Python package in .venv (maturin, numpy, pandas, dask, pytest).
bash "$root/scripts/setup-python.sh"
