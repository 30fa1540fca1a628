#!/usr/bin/env bash
# Builds the STM32F411 images (crates/lssi-f411: the standalone instrument with stm32f4xx-hal,
# one ADC channel and, with `--features system`, two) and prints their flash and static RAM.
# CI runs it: the real board's images must build.
# flash = .vector_table + .text + .rodata + .data; static RAM = .data + .bss + .uninit
# (defmt-rtt's buffer lies in .uninit).
#
# The deepest stack is measured, not guessed: the QEMU standalone image (crates/lssi-firmware,
# lssi-standalone, the same lssi-device and lssi-core code: the reporter, the screening, the
# identify task and the row interrupts nested on them) paints its stack at reset and logs
# "stack: N bytes at the deepest" at the end of `bash scripts/ci-qemu.sh`
# (tests/tests/e2e/standalone_qemu.rs, standalone_system_qemu.rs). Only the board's own main
# frame differs: the F411's is read from its disassembly (`sub sp` in __cortex_m_rt_main) and
# put in place of the QEMU image's. LSSI_STACK_ONE / LSSI_STACK_SYSTEM (with
# LSSI_QEMU_MAIN_ONE / LSSI_QEMU_MAIN_SYSTEM) give newer measurements.
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
objdump="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-objdump"
# Measured by scripts/ci-qemu.sh at the commit that set them: the QEMU standalone image's
# deepest stack and its main's frame, one channel then two.
stack_one=${LSSI_STACK_ONE:-9800}
qemu_main_one=${LSSI_QEMU_MAIN_ONE:-2840}
stack_system=${LSSI_STACK_SYSTEM:-9596}
qemu_main_system=${LSSI_QEMU_MAIN_SYSTEM:-2984}
# A function's frame: the bytes its `sub sp, #…` instructions reserve.
main_frame() {
    "$objdump" -d --no-show-raw-insn "$1" | awk '
        function hex(s,    i, v) {
            v = 0
            for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(s, i, 1)) - 1
            return v
        }
        /^[0-9a-f]+ <.*>:$/ { inside = ($0 ~ /__cortex_m_rt_main/) }
        inside && /\tsub(\.w|w)?\tsp, (sp, )?#0x/ {
            match($0, /#0x[0-9a-f]+/); frame += hex(substr($0, RSTART + 3, RLENGTH - 3))
        }
        END { print frame + 0 }'
}
status=0
for features in "" "system"; do
    cargo build --release --locked --quiet ${features:+--features "$features"}
    label="one channel (x)"
    [[ -n $features ]] && label="two channels (x and V, --features $features)"
    echo "lssi-f411 (STM32F411CEU6: 512 KiB flash, 128 KiB RAM), release, $label"
    if [[ -n $features ]]; then
        measured=$stack_system; qemu_main=$qemu_main_system
    else
        measured=$stack_one; qemu_main=$qemu_main_one
    fi
    board_main=$(main_frame "$elf")
    "$llvm_size" -A "$elf" | awk -v measured="$measured" -v qemu_main="$qemu_main" -v board_main="$board_main" '
        { size[$1] = $2 }
        END {
            vt = size[".vector_table"] + 0; text = size[".text"] + 0; ro = size[".rodata"] + 0
            data = size[".data"] + 0; bss = size[".bss"] + 0; uninit = size[".uninit"] + 0
            flash = vt + text + ro + data; ram = data + bss + uninit
            stack = measured - qemu_main + board_main; total = ram + stack
            printf "  flash:      %7d bytes (.text %d, .rodata %d, .vector_table %d, .data image %d): %s 128 KiB\n",
                flash, text, ro, vt, data, (flash <= 131072 ? "fits" : "DOES NOT FIT")
            printf "  static RAM: %7d bytes (.data %d, .bss %d, .uninit %d)\n", ram, data, bss, uninit
            printf "  stack:      %7d bytes at the deepest (%d measured under QEMU, its main frame %d replaced by this board'"'"'s %d)\n",
                stack, measured, qemu_main, board_main
            printf "  static RAM + stack: %d bytes (%.1f KiB): %s 32 KiB (%d bytes to spare)\n",
                total, total / 1024, (total <= 32768 ? "fits" : "DOES NOT FIT"), 32768 - total
            exit (flash <= 131072 && total <= 32768) ? 0 : 1
        }' || status=1
done
exit $status
