#!/usr/bin/env bash
# Cost, size and stack of lssi-core's identifier on the Cortex-M4F, as two tables.
#
#   scripts/firmware-bench.sh            # builds 4 images, runs 3 under QEMU (about 1 min)
#   LSSI_BENCH_RAW=1 scripts/firmware-bench.sh   # also print the firmware's raw lines
#
# The configuration is the device default: Identifier<f32, 256, 16, 2> (ring buffers for two
# channels; the firmware's `three-channels` feature gives 3), x and a measured x',
# window 255, the eq. 18 library (1, monomials of (x, x') to order 3, sin/cos(kΩt) for
# k = 1..3), a screening every 10 000 samples; the signal is eq. 17, made on the device
# (crates/lssi-firmware/src/bench_identifier.rs). Four release images of lssi-firmware:
#   bench-identifier  30 000 samples through Identifier::push, each timed; flash and RAM
#   bench-baseline    the same image without the identifier: the flash difference is its own
#   bench-profile     the stages of a regression row timed one by one
#   bench-weak        the stream again under the configuration `lssi identify` chooses for
#                     this signal (test-function rows), printed as a second table
# Costs are executed instructions: SysTick under `qemu-system-arm -icount shift=0` (one tick
# = 40 instructions, calibrated at start-up). Stack is measured by painting: while streaming,
# over the screenings, and while configuring the identifier in place in .bss (as lssi-device's
# Configure does: IdentifierSlot::configure on the empty slot, and once more at the end on
# the used identifier); the RAM row is static RAM plus the deepest of the three.
# Flash = .vector_table + .text + .rodata + .data image; static RAM = .data + .bss + .uninit
# (llvm-size from `rustup component add llvm-tools`).
# Needs qemu-system-arm and defmt-print (cargo install defmt-print --locked).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root/crates/lssi-firmware"

host=$(rustc -vV | sed -n 's/^host: //p')
llvm_size="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-size"
for tool in "$llvm_size" qemu-system-arm defmt-print; do
    if ! command -v "$tool" >/dev/null; then
        echo "firmware-bench: $tool not found (llvm-tools: rustup component add llvm-tools;" \
            "apt-get install qemu-system-arm; cargo install defmt-print --locked)" >&2
        exit 1
    fi
done

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
elf=target/thumbv7em-none-eabihf/release/lssi-firmware

for image in bench-identifier bench-baseline bench-profile bench-weak; do
    cargo build --release --locked --quiet --features "$image"
    cp "$elf" "$work/$image.elf"
done
# The same configuration on a device built with 64-sample rings (`window-64`: a part with
# 8-16 KiB of RAM), and the device image (lssi-device's command loop) both ways.
cargo build --release --locked --quiet --features "bench-weak window-64"
cp "$elf" "$work/bench-weak-64.elf"
cargo build --release --locked --quiet --bin lssi-firmware
cp "$elf" "$work/device.elf"
cargo build --release --locked --quiet --bin lssi-firmware --features window-64
cp "$elf" "$work/device-64.elf"

run() { # run IMAGE: the image under QEMU, its defmt lines decoded into IMAGE.out
    local e="$work/$1.elf"
    timeout "${LSSI_TIMEOUT:-300}" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 \
        -nographic -monitor none -serial null \
        -semihosting-config enable=on,target=native -icount shift=0 -kernel "$e" |
        defmt-print -e "$e" >"$work/$1.out"
    if ! grep -q 'bench-id end' "$work/$1.out"; then
        cat "$work/$1.out" >&2
        echo "firmware-bench: $1 did not finish" >&2
        exit 1
    fi
    if [[ -n ${LSSI_BENCH_RAW:-} ]]; then cat "$work/$1.out"; fi
}
run bench-identifier
run bench-profile
run bench-weak
run bench-weak-64

sizes() { # sizes IMAGE: "flash_code flash_total static_ram"
    "$llvm_size" -A "$work/$1.elf" | awk '
        { s[$1] = $2 }
        END {
            code = s[".text"] + s[".rodata"]
            print code, s[".vector_table"] + code + s[".data"], s[".data"] + s[".bss"] + s[".uninit"]
        }'
}
read -r code total ram < <(sizes bench-identifier)
read -r base_code _ base_ram < <(sizes bench-baseline)

# Every figure line reads "INFO  bench-id KEY ..." (key=value pairs or one value).
out="$work/bench-identifier.out"
prof="$work/bench-profile.out"
field() { # field FILE KEY NAME: the value of NAME=... on KEY's line
    sed -n "s/.*bench-id $2 .*$3=\([0-9]*\).*/\1/p" "$1" | head -1
}
value() { # value FILE KEY: the number after KEY
    sed -n "s/.*bench-id $2 \([0-9]*\).*/\1/p" "$1" | head -1
}

all_mean=$(field "$out" push_all mean)
steady_mean=$(field "$out" push_steady mean)
steady_max=$(field "$out" push_steady max)
idle_mean=$(field "$out" push_idle mean)
row_mean=$(field "$out" push_row mean)
row_max=$(field "$out" push_row max)
merge_mean=$(field "$out" push_row_merge mean)
merge_max=$(field "$out" push_row_merge max)
warmup=$(field "$out" push_warmup max)
screen_count=$(field "$out" push_screen count)
screen_mean=$(field "$out" push_screen mean)
screen_max=$(field "$out" push_screen max)
final_screen=$(value "$out" final_screen)
push_stack=$(value "$out" push_stack)
screen_stack=$(value "$out" screen_stack)
configure_cost=$(value "$out" configure_cost)
configure_stack=$(value "$out" configure_stack)
reconfigure_cost=$(value "$out" reconfigure_cost)
reconfigure_stack=$(value "$out" reconfigure_stack)
id_size=$(value "$out" size_of_identifier)
fir=$(field "$prof" stage_fir4 mean)
knn_plain=$(field "$prof" stage_knn2_plain mean)
knn_eval=$(field "$prof" stage_knn2_eval mean)
library=$(field "$prof" stage_library mean)
givens=$(field "$prof" stage_givens mean)
merge=$(field "$prof" stage_merge mean)
for v in all_mean steady_max screen_max push_stack screen_stack configure_stack reconfigure_stack \
    fir knn_plain givens merge; do
    if [[ -z ${!v} ]]; then
        cat "$out" "$prof" >&2
        echo "firmware-bench: no figure for $v in the firmware's output" >&2
        exit 1
    fi
done

# The identifier lives in .bss (static RAM); the stack at its deepest is one of: streaming,
# a screening, or configuring it (in place, the first time or again, as the device does).
max() { echo $(($1 > $2 ? $1 : $2)); }
config_stack=$(max "$configure_stack" "$reconfigure_stack")
stack_peak=$(max "$(max "$push_stack" "$screen_stack")" "$config_stack")
ram_total=$((ram + stack_peak))
ram_stream=$((ram + push_stack))
worst=$((steady_max > final_screen ? steady_max : final_screen))
worst=$((screen_max > worst ? screen_max : worst))
# A row every 4 samples, a block merge every 127 rows (508 samples), a screening every 10 000.
# The smoothing is off on this signal: ε(K) on one row in 16, the others only buffered.
knn_row=$(((15 * knn_plain + knn_eval) / 16))

check() { # check VALUE LIMIT: "ok" or "OVER"
    if (($1 <= $2)); then echo "ok"; else echo "OVER"; fi
}
pct() { # pct PART WHOLE
    awk -v p="$1" -v w="$2" 'BEGIN { printf "%.0f %%", 100 * p / w }'
}

echo
echo "lssi-core Identifier<f32, 256, 16, 2> on a Cortex-M4F (QEMU mps2-an386, -icount shift=0)"
echo "eq. 17 signal, x and x' measured, window 255, eq. 18 library (16 terms); $(rustc -V | cut -d' ' -f1-2)"
echo
printf '| %-52s | %12s | %-14s | %-14s |\n' "figure" "measured" "target" "goal 32K/8K/2000"
printf '|%s|%s|%s|%s|\n' "$(printf -- '-%.0s' {1..54})" "$(printf -- '-%.0s' {1..14})" \
    "$(printf -- '-%.0s' {1..16})" "$(printf -- '-%.0s' {1..16})"
row() { printf '| %-52s | %12s | %-14s | %-14s |\n' "$@"; }
row "flash, .text+.rodata (identifier image)" "$code B" "<= 65536 $(check "$code" 65536)" "<= 32768 $(check "$code" 32768)"
row "  of which the identifier (image - baseline)" "$((code - base_code)) B" "" ""
row "  of which start-up, UART, defmt, meter, signal" "$base_code B" "" ""
row "static RAM, .data+.bss" "$ram B" "" ""
row "  of which the Identifier struct" "$id_size B" "" ""
row "peak stack, streaming (push, no screening)" "$push_stack B" "" ""
row "peak stack, screening" "$screen_stack B" "" ""
row "peak stack, configuring in place (first / again)" "$configure_stack / $reconfigure_stack B" "" ""
row "RAM, static + peak stack (of the three above)" "$ram_total B" "<= 16384 $(check "$ram_total" 16384)" "<= 8192 $(check "$ram_total" 8192)"
row "  without the screening's stack" "$ram_stream B" "<= 16384 $(check "$ram_stream" 16384)" "<= 8192 $(check "$ram_stream" 8192)"
row "instructions/sample, mean (screening spread over it)" "$all_mean" "<= 5000 $(check "$all_mean" 5000)" "<= 2000 $(check "$all_mean" 2000)"
row "  mean without the screening" "$steady_mean" "" ""
row "  of which screenings ($screen_count in 30000 samples)" "$((all_mean - steady_mean)) (mean $screen_mean)" "" ""
row "instructions/sample, worst outside screening" "$steady_max" "" ""
row "  sample with a row, mean / worst" "$row_mean / $row_max" "" ""
row "  sample with a row closing a block, mean / worst" "$merge_mean / $merge_max" "" ""
row "  sample without a row, mean" "$idle_mean" "" ""
row "screening (threshold sweep + MES), worst" "$screen_max" "stated" ""
row "  at 64 MHz, at least: ms, samples at 10 kHz" \
    "$(awk -v n="$screen_max" 'BEGIN { printf "%.0f ms, %.0f", n / 64e3, n / 6400 }')" "" ""
row "one-off: warm-up flush (64 rows at once)" "$warmup" "" ""
row "one-off: configuring, taps in f64 (first / again)" "$configure_cost / $reconfigure_cost" "" ""
row "row stage: 3 FIR filters of 255 taps, folded" "$fir" "/row" "$(pct $((fir / 4)) "$steady_mean")"
row "row stage: kNN smoothing of x and v" "$knn_row" "/row" "$(pct $((knn_row / 4)) "$steady_mean")"
row "row stage: library row (phasor, 16 terms)" "$library" "/row" "$(pct $((library / 4)) "$steady_mean")"
row "row stage: Givens update of the block factor" "$givens" "/row" "$(pct $((givens / 4)) "$steady_mean")"
row "block merge into A or B (every 127 rows)" "$merge" "/block" "$(pct $((merge / 508)) "$steady_mean")"
echo
echo "The last column shares out the mean without screening: a row every 4 samples, a block every 508."
echo "Instructions, not cycles: a 64 MHz Cortex-M4F at 10 kHz has 6400 cycles a sample, and takes"
echo "more than one cycle for some instructions (loads, branches, VDIV/VSQRT 14)."

# The same signal under the configuration `lssi identify` sends a device for it: test-function
# rows (520 rows, a third of the period), a row every sample, a 33-sample window.
weak="$work/bench-weak.out"
read -r _ _ weak_ram < <(sizes bench-weak)
weak_all=$(field "$weak" push_all mean)
weak_steady=$(field "$weak" push_steady mean)
weak_steady_max=$(field "$weak" push_steady max)
weak_screen_mean=$(field "$weak" push_screen mean)
weak_screen_max=$(field "$weak" push_screen max)
weak_push_stack=$(value "$weak" push_stack)
weak_screen_stack=$(value "$weak" screen_stack)
weak_config_stack=$(max "$(value "$weak" configure_stack)" "$(value "$weak" reconfigure_stack)")
for v in weak_all weak_steady weak_steady_max weak_screen_max weak_push_stack weak_screen_stack; do
    if [[ -z ${!v} ]]; then
        cat "$weak" >&2
        echo "firmware-bench: no figure for $v in the bench-weak image's output" >&2
        exit 1
    fi
done
weak_peak=$(max "$(max "$weak_push_stack" "$weak_screen_stack")" "$weak_config_stack")
weak_total=$((weak_ram + weak_peak))
echo
echo "As configured by \`lssi identify\` for this signal (bench-weak image): test-function rows"
echo "of 520 rows, a row every sample, window 33, degree 5"
echo
printf '| %-52s | %12s | %-14s | %-14s |\n' "figure" "measured" "target" "goal 32K/8K/2000"
printf '|%s|%s|%s|%s|\n' "$(printf -- '-%.0s' {1..54})" "$(printf -- '-%.0s' {1..14})" \
    "$(printf -- '-%.0s' {1..16})" "$(printf -- '-%.0s' {1..16})"
row "RAM, static + peak stack" "$weak_total B" "<= 16384 $(check "$weak_total" 16384)" "<= 8192 $(check "$weak_total" 8192)"
row "  peak stack, streaming / screening" "$weak_push_stack / $weak_screen_stack B" "" ""
row "instructions/sample, mean (screening spread over it)" "$weak_all" "<= 5000 $(check "$weak_all" 5000)" "<= 2000 $(check "$weak_all" 2000)"
row "  mean without the screening" "$weak_steady" "" ""
row "instructions/sample, worst outside screening" "$weak_steady_max" "" ""
row "screening (threshold sweep + MES), mean / worst" "$weak_screen_mean / $weak_screen_max" "stated" ""

# The window-64 build of the same: the model is the same (the window is 33 either way).
w64="$work/bench-weak-64.out"
read -r _ _ w64_ram < <(sizes bench-weak-64)
w64_peak=$(max "$(max "$(value "$w64" push_stack)" "$(value "$w64" screen_stack)")" \
    "$(max "$(value "$w64" configure_stack)" "$(value "$w64" reconfigure_stack)")")
w64_total=$((w64_ram + w64_peak))
w64_all=$(field "$w64" push_all mean)
read -r _ dev_flash dev_ram < <(sizes device)
read -r _ dev64_flash dev64_ram < <(sizes device-64)
row "the same, built with window-64: static RAM" "$w64_ram B" "" "<= 8192 $(check "$w64_ram" 8192)"
row "  static RAM + peak stack" "$w64_total B" "" "<= 12288 $(check "$w64_total" 12288)"
row "  instructions/sample, mean" "$w64_all" "" ""
row "device image (lssi-device loop): flash" "$dev_flash B" "<= 65536 $(check "$dev_flash" 65536)" "<= 32768 $(check "$dev_flash" 32768)"
row "  static RAM: W = 256 / window-64" "$dev_ram / $dev64_ram B" "" "<= 8192 $(check "$dev64_ram" 8192)"

# Energy: what a sample costs a part that runs the identifier and sleeps (WFI) in between.
# Active energy per sample = V x (run current per MHz) x instructions, taking one cycle per
# instruction (a floor: loads, branches and VDIV/VSQRT take more). Run currents are the
# datasheets' headline figures (3.3 V, code from flash, peripherals off): STM32F411 100 uA/MHz,
# STM32L432 84 uA/MHz (LDO). The Sleep-mode current between samples comes on top and depends
# on the clock tree kept running for the timer and ADC (see the part's Sleep-mode table).
echo
echo "Energy per sample, core active for the measured mean instructions, 3.3 V, 1 cycle/instruction"
echo
printf '| %-40s | %-12s | %10s | %10s | %10s |\n' "configuration" "part" "uJ/sample" "mW @ 1 kHz" "mW @ 10 kHz"
printf '|%s|%s|%s|%s|%s|\n' "$(printf -- '-%.0s' {1..42})" "$(printf -- '-%.0s' {1..14})" \
    "$(printf -- '-%.0s' {1..12})" "$(printf -- '-%.0s' {1..12})" "$(printf -- '-%.0s' {1..13})"
energy() { # energy LABEL INSTRUCTIONS
    for part in "STM32F411 100" "STM32L432 84"; do
        set -- "$1" "$2" $part
        awk -v label="$1" -v n="$2" -v name="$3" -v k="$4" 'BEGIN {
            uj = 3.3 * k * n * 1e-6
            printf "| %-40s | %-12s | %10.3f | %10.3f | %11.2f |\n", label, name, uj, uj, 10 * uj  # uJ x 1000 /s = mW
        }'
    done
}
energy "default (eq. 18 library, a row every 4)" "$all_mean"
energy "as lssi identify configures (weak form)" "$weak_all"
echo
echo "Harvesters make 0.1-10 mW; the power is proportional to the rate (harvesters ring at 3-50 Hz)."
echo "scripts/lowest-rate.sh: the lowest rate that still identifies data/eveh-bistable.csv within 1 %."

# Average power of a device identifying the eveh harvester at the row rate `lssi identify`
# proposes, continuously and duty-cycled: scripts/firmware-power.sh (every constant and its
# source are listed there), with the F4 decimator's cost measured above.
conv_cost=$(field "$prof" sampler_conversion mean)
dec_cost=$(field "$prof" decimate_conversion mean)
if [[ -z $conv_cost || -z $dec_cost ]]; then
    cat "$prof" >&2
    echo "firmware-bench: no decimation figures in the bench-profile image's output" >&2
    exit 1
fi
CONV_COST=$conv_cost DEC_COST=$dec_cost bash "$root/scripts/firmware-power.sh"
echo "The identifier's own instructions dominate on the L432 (its rows, then a screening every 5"
echo "minutes); duty-cycled, Stop 2 between windows and the window's rows (a model, one screening,"
echo "every few windows: lssi monitor/replay --duty-model-every). Constants marked CHECK"
echo "in scripts/firmware-power.sh are read from memory of the datasheets' tables; none was checked"
echo "against a current revision here."

echo
echo "What the device image's flash holds (scripts/flash-breakdown.sh):"
echo
bash "$root/scripts/flash-breakdown.sh" "$work/device.elf" 15

# One channel against two (x and V: a harvester's x'' and V'), and the device image's size.
bash "$root/scripts/firmware-bench-system.sh"
