#!/usr/bin/env bash
# Everything CI needs for the firmware, on a fresh Debian/Ubuntu machine:
#   1. qemu-system-arm (apt) when missing, and `lssi defmt` as defmt-print when that is missing;
#   2. the firmware's release ELF (crates/lssi-firmware, thumbv7em-none-eabihf);
#   3. its smoke test under QEMU (crates/lssi-firmware/scripts/qemu-check.sh);
#   4. the end-to-end tests: the bundled recording replayed through the firmware under QEMU
#      must give the model of `lssi identify --f32 --no-refine` (tests/tests/qemu.rs), and the standalone
#      image sampling a 10 kHz recording by its timer must lose no sample and end with that
#      model (tests/tests/standalone_qemu.rs), and a simulated piezo harvester (x and V) through
#      the `system` image must give the host's f32 SystemIdentifier's two equations
#      (tests/tests/e2e/system_qemu.rs), and the standalone instrument built with `system`
#      sampling x and V (two ADC channels) must end with the host's f32 system model
#      (tests/tests/e2e/standalone_system_qemu.rs); ignored by a plain `cargo test`, run here with
#      --include-ignored (a missing QEMU or ELF fails them);
#   5. the identifier's cost, size and stack table (scripts/firmware-bench.sh).
# Exits non-zero at the first failure. LSSI_CI_SKIP_BENCH=1 leaves out step 5.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

step() { echo; echo "== ci-qemu: $*"; }

step "tools"
if ! command -v qemu-system-arm >/dev/null; then
    sudo=""
    if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
    $sudo apt-get update
    $sudo apt-get install -y --no-install-recommends qemu-system-arm
fi
qemu-system-arm --version | head -1
if ! command -v defmt-print >/dev/null; then
    # `lssi defmt -e ELF` decodes as `defmt-print -e ELF` does, with the same defmt-decoder
    # crate, and is built already: it stands in for defmt-print on PATH (a `cargo install
    # defmt-print` compiles for about two minutes on a fresh machine).
    if [[ ! -x target/release/lssi ]]; then
        cargo build --release --locked -q -p lssi-host --bin lssi
    fi
    shim=$(mktemp -d)
    trap 'rm -rf "$shim"' EXIT
    printf '#!/bin/sh\nexec "%s" defmt "$@"\n' "$root/target/release/lssi" >"$shim/defmt-print"
    chmod +x "$shim/defmt-print"
    export PATH="$shim:$PATH"
    echo "defmt-print: lssi defmt ($root/target/release/lssi)"
fi
rustup target add thumbv7em-none-eabihf >/dev/null
rustup component add llvm-tools >/dev/null

step "firmware release ELF"
elf="$root/crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-firmware"
# The replay image that also identifies systems (x and V), kept beside the default one.
(cd crates/lssi-firmware && cargo build --release --locked --features system)
cp "$elf" "$elf-system"
# The standalone instrument with two ADC channels (x and V: a harvester's system), kept
# beside the one-channel standalone image.
standalone="$root/crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-standalone"
(cd crates/lssi-firmware && cargo build --release --locked --bin lssi-standalone --features system)
cp "$standalone" "$standalone-system"
(cd crates/lssi-firmware && cargo build --release --locked)
ls -l "$elf" "$elf-system" "$standalone" "$standalone-system"

step "firmware smoke test under QEMU"
crates/lssi-firmware/scripts/qemu-check.sh

step "replay through the QEMU firmware == lssi identify --f32 --no-refine; the standalone instrument at 10 kHz"
LSSI_FIRMWARE_ELF="$elf" LSSI_SYSTEM_FIRMWARE_ELF="$elf-system" \
    LSSI_STANDALONE_SYSTEM_ELF="$standalone-system" \
    cargo test --locked --release --workspace --test e2e -- qemu --include-ignored --nocapture

if [[ -z ${LSSI_CI_SKIP_BENCH:-} ]]; then
    step "identifier cost, size and stack on the Cortex-M4F"
    scripts/firmware-bench.sh
fi
