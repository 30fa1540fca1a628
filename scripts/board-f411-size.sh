#!/usr/bin/env bash
# Builds the STM32F411 image (crates/lssi-f411: the standalone instrument with stm32f4xx-hal)
# and prints its flash and static RAM. CI runs it: the real board's image must build.
# flash = .vector_table + .text + .rodata + .data; static RAM = .data + .bss.
set -euo pipefail
cd "$(dirname "$0")/../crates/lssi-f411"
rustup target add thumbv7em-none-eabihf >/dev/null
rustup component add llvm-tools >/dev/null
cargo build --release --locked --quiet
elf=target/thumbv7em-none-eabihf/release/lssi-f411
host=$(rustc -vV | sed -n 's/^host: //p')
llvm_size="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
echo "lssi-f411 (STM32F411CEU6: 512 KiB flash, 128 KiB RAM), release"
"$llvm_size" -A "$elf" | awk '
    { size[$1] = $2 }
    END {
        vt = size[".vector_table"] + 0; text = size[".text"] + 0; ro = size[".rodata"] + 0
        data = size[".data"] + 0; bss = size[".bss"] + 0
        printf "  flash:      %7d bytes (.text %d, .rodata %d, .vector_table %d, .data image %d)\n",
            vt + text + ro + data, text, ro, vt, data
        printf "  static RAM: %7d bytes (.data %d, .bss %d)\n", data + bss, data, bss
    }'
