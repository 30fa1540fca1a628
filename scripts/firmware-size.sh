#!/usr/bin/env bash
# Flash and static RAM of the firmware image (crates/lssi-firmware), built in release.
#
#   scripts/firmware-size.sh                     # the default image (QEMU, echo demo)
#   scripts/firmware-size.sh --features bench    # any cargo build flags pass through
#   scripts/firmware-size.sh --no-default-features --features rtt
#
# flash      = .vector_table + .text + .rodata + .data (the initial values live in flash)
# static RAM = .data + .bss + .uninit; the stack takes the rest of RAM (memory.x).
# Needs llvm-size from `rustup component add llvm-tools` (scripts/setup.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/../crates/lssi-firmware"

cargo build --release --locked --quiet "$@"
elf=target/thumbv7em-none-eabihf/release/lssi-firmware
host=$(rustc -vV | sed -n 's/^host: //p')
llvm_size="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
if [[ ! -x $llvm_size ]]; then
    echo "firmware-size: $llvm_size not found; run: rustup component add llvm-tools" >&2
    exit 1
fi

echo "lssi-firmware, release${*:+, $*}"
"$llvm_size" -A "$elf" | awk '
    { size[$1] = $2 }
    END {
        vt = size[".vector_table"] + 0; text = size[".text"] + 0; ro = size[".rodata"] + 0
        data = size[".data"] + 0; bss = size[".bss"] + 0; uninit = size[".uninit"] + 0
        printf "  flash:      %7d bytes (.text+.rodata %d; .vector_table %d, .data image %d)\n",
            vt + text + ro + data, text + ro, vt, data
        printf "  static RAM: %7d bytes (.data %d, .bss %d, .uninit %d)\n",
            data + bss + uninit, data, bss, uninit
    }'
