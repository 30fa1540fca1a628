#!/usr/bin/env bash
# Builds the STM32F411 images (crates/lssi-f411: the standalone instrument with stm32f4xx-hal,
# one ADC channel and, with `--features system`, two) and prints their flash and static RAM.
# CI runs it: the real board's images must build.
# flash = .vector_table + .text + .rodata + .data; static RAM = .data + .bss.
set -euo pipefail
cd "$(dirname "$0")/../crates/lssi-f411"
rustup target add thumbv7em-none-eabihf >/dev/null
rustup component add llvm-tools >/dev/null
elf=target/thumbv7em-none-eabihf/release/lssi-f411
host=$(rustc -vV | sed -n 's/^host: //p')
llvm_size="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
# The one-channel image, then the two-channel one (`--features system`: x on PA0, V on PA1,
# identified as a system), each against the smallest part it must fit (128 KiB flash,
# 32 KiB RAM: an STM32F411's smaller sibling, or the budget the issue sets).
for features in "" "system"; do
    cargo build --release --locked --quiet ${features:+--features "$features"}
    label="one channel (x)"
    [[ -n $features ]] && label="two channels (x and V, --features $features)"
    echo "lssi-f411 (STM32F411CEU6: 512 KiB flash, 128 KiB RAM), release, $label"
    "$llvm_size" -A "$elf" | awk '
        { size[$1] = $2 }
        END {
            vt = size[".vector_table"] + 0; text = size[".text"] + 0; ro = size[".rodata"] + 0
            data = size[".data"] + 0; bss = size[".bss"] + 0
            flash = vt + text + ro + data; ram = data + bss
            printf "  flash:      %7d bytes (.text %d, .rodata %d, .vector_table %d, .data image %d): %s 128 KiB\n",
                flash, text, ro, vt, data, (flash <= 131072 ? "fits" : "DOES NOT FIT")
            printf "  static RAM: %7d bytes (.data %d, .bss %d): %s 32 KiB with %d bytes left for the stack\n",
                ram, data, bss, (ram <= 32768 ? "fits" : "DOES NOT FIT"), 32768 - ram
        }'
done
