#!/usr/bin/env bash
# The cost of a system of equations on the Cortex-M4F (issue 26 item 2, issue 27 item 5):
# one channel (x: x'' by Identifier<f32, 256, 16, 2>) against two (x and V: x'' and V' by
# SystemIdentifier<f32, 256, 16, 2, 2>) on the same piezo harvester made on the device
# (crates/lssi-firmware/src/bench_system.rs; window 63, a row every 4 samples, a screening
# every 10 000 samples, 30 000 samples), each push timed in instructions under
# `qemu-system-arm -icount shift=0`; then the flash and RAM of the device image, which
# identifies one equation (default) or either (its `system` feature: lssi-device's
# Configure or ConfigureSystem).
#
#   scripts/firmware-bench-system.sh          # about 1 min; scripts/firmware-bench.sh runs it
#   LSSI_BENCH_RAW=1 scripts/firmware-bench-system.sh
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root/crates/lssi-firmware"
host=$(rustc -vV | sed -n 's/^host: //p')
llvm_size="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
elf=target/thumbv7em-none-eabihf/release/lssi-firmware
cargo build --release --locked --quiet --features bench-system
cp "$elf" "$work/bench-system.elf"
cargo build --release --locked --quiet --bin lssi-firmware
cp "$elf" "$work/device.elf"
cargo build --release --locked --quiet --bin lssi-firmware --features system
cp "$elf" "$work/device-system.elf"

e="$work/bench-system.elf"
timeout "${LSSI_TIMEOUT:-300}" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 \
    -nographic -monitor none -serial null \
    -semihosting-config enable=on,target=native -icount shift=0 -kernel "$e" |
    defmt-print -e "$e" >"$work/out"
if ! grep -q 'bench-sys end' "$work/out"; then
    cat "$work/out" >&2
    echo "firmware-bench-system: the bench image did not finish" >&2
    exit 1
fi
if [[ -n ${LSSI_BENCH_RAW:-} ]]; then cat "$work/out"; fi
field() { sed -n "s/.*bench-sys $1 .*$2=\([0-9]*\).*/\1/p" "$work/out" | head -1; }
value() { sed -n "s/.*bench-sys $1 \([0-9]*\).*/\1/p" "$work/out" | head -1; }
sizes() { # flash (.vector_table+.text+.rodata+.data) and static RAM (.data+.bss+.uninit)
    "$llvm_size" -A "$1" | awk '{ s[$1] = $2 } END {
        print s[".vector_table"] + s[".text"] + s[".rodata"] + s[".data"], s[".data"] + s[".bss"] + s[".uninit"] }'
}
read -r flash ram < <(sizes "$work/device.elf")
read -r sys_flash sys_ram < <(sizes "$work/device-system.elf")
for v in one two; do
    for k in all steady screen; do
        for f in mean max; do
            x=$(field "${v}_$k" "$f")
            if [[ -z $x ]]; then
                echo "firmware-bench-system: no ${v}_$k $f in the firmware's output" >&2
                exit 1
            fi
            printf -v "${v}_${k}_${f}" '%s' "$x"
        done
    done
done
one_stack=$(value one_stack); two_stack=$(value two_stack)
one_size=$(value one_size); two_size=$(value two_size)
one_terms=$(value one_terms); two_terms=$(value two_terms)
peak=$((one_stack > two_stack ? one_stack : two_stack))

echo
echo "One channel against two on a Cortex-M4F (QEMU mps2-an386, -icount shift=0), piezo harvester"
echo "made on the device, 30 000 samples, window 63, a row every 4 samples, a screening every 10 000"
echo
printf '| %-50s | %20s | %20s |\n' "figure" "one channel (x)" "two channels (x, V)"
printf '|%s|%s|%s|\n' "$(printf -- '-%.0s' {1..52})" "$(printf -- '-%.0s' {1..22})" "$(printf -- '-%.0s' {1..22})"
row() { printf '| %-50s | %20s | %20s |\n' "$@"; }
row "equations, library terms" "1 (x''), $one_terms" "2 (x'', V'), $two_terms"
row "instructions/sample, mean (screenings spread)" "$one_all_mean" "$two_all_mean"
row "instructions/sample, mean without the screenings" "$one_steady_mean" "$two_steady_mean"
row "instructions/sample, worst outside a screening" "$one_steady_max" "$two_steady_max"
row "screening, mean / worst" "$one_screen_mean / $one_screen_max" "$two_screen_mean / $two_screen_max"
row "peak stack, streaming and screening" "$one_stack B" "$two_stack B"
row "the identifier in .bss (its slot)" "$one_size B" "$two_size B"
echo
echo "The device image (lssi-firmware, replay), one channel (default) and with its \`system\` feature"
echo "(Configure or ConfigureSystem: both identifiers in .bss):"
echo "  one channel:  flash $flash B, static RAM $ram B, static RAM + the stack above $((ram + one_stack)) B"
echo "  two channels: flash $sys_flash B, static RAM $sys_ram B, static RAM + the deeper stack above $((sys_ram + peak)) B"
echo "instructions/sample: one channel $one_all_mean, two channels $two_all_mean (x and V, 2 equations)"
