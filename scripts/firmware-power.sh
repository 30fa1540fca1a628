#!/usr/bin/env bash
# Average power of a standalone device identifying the eveh harvester at the row rate `lssi
# identify` proposes for it, continuously and duty-cycled (10 s every 10 minutes): the
# `average power:` line and its table (scripts/firmware-bench.sh runs this at its end).
#
#   bash scripts/firmware-power.sh                 # about 1 min (2-3 more to build the images)
#   ROW_HZ=200 bash scripts/firmware-power.sh      # another row rate than the proposed one
#   SECONDS_PLAYED=570 bash scripts/firmware-power.sh   # else about 600 s: half-way
#                                                  # between two scheduled screenings
#   CONV_COST=N DEC_COST=N ...                     # the F4 decimator's cost (firmware-bench.sh
#                                                  # passes its bench-profile figures; else
#                                                  # the bench-profile image is built and run)
#   DUTY_MODEL_EVERY=N ...                         # a model every N windows (else the host's
#                                                  # default, as the image logs it)
#
# What is measured, under QEMU (-icount shift=4: 2.5 instructions a 25 MHz tick): the
# standalone image (crates/lssi-firmware/src/bin/lssi-standalone.rs) at its defaults for a
# device on a harvester's power (a model every MODEL_INTERVAL_S = 5 min, Model and Health
# every 60 s), with the configuration `lssi identify` picks for the recording (stored as a
# host's Configure by `lssi monitor --qemu`), sampling SECONDS_PLAYED (≈ 600) s of `lssi gen
# eveh --rate ROW_HZ --observe x`, one conversion a row (the L432's hardware oversampler
# delivers one value a row). The image counts every tick the core is awake while sampling
# (rows, the sampling and identify interrupts, thread mode, the frames, the screenings run,
# spread over rows) and logs it at the end; its final Health gives the final screening's
# cost (after the recording nothing interrupts it: one screening's instructions).
#
# Duty-cycled, the device identifies for a 10 s window every 10 minutes and sleeps in Stop 2
# between; a window's rows cost what the continuous run's rows cost, and a model (one
# screening) is made every N-th window only (Configure's duty cycle, `lssi monitor/replay
# --duty-model-every N`), the windows between ending with Health alone. N is the one the
# host sends: a 3 s recording through the image with `--duty-window 10 --duty-interval 590`
# (well under a second of QEMU), whose log says "a model every N window(s)" (the host's
# default: the windows of about 40 minutes, 4 here; `DUTY_MODEL_EVERY=N` gives another).
# Not counted: a Health-only window's end still copies the identifier into the snapshot
# (its worst row with that copy is about 32,000 ticks, 80 k instructions: at most 0.04 µW
# at one a window) and sends one Health frame instead of two frames.
#
# Every constant and where it comes from (CHECK: read from memory of the datasheet's tables,
# not verified against a PDF here; the stored docs hold no ST datasheet, and a search of the
# stored pages found the STM32L4 application notes AN4621 and AN4746 and STM32L0/L1 tables,
# not the L432's):
#
#   V            3.3 V supply (both parts run from 1.7-3.6 V; typical currents, 25 °C).
#   cycles       one cycle an executed instruction (QEMU counts instructions; flash wait
#                states, loads and VDIV/VSQRT make the real count higher: a floor).
#   conversion   the F4's software decimation: bench-profile's `sampler_conversion` (the
#                standalone Sampler with a CIC of order 3, 50 conversions a row, as TIM2's
#                interrupt calls it) + 24 cycles of exception entry and exit (ARM Cortex-M4
#                Technical Reference Manual r0p1, 3.9 "Exceptions": 12-cycle entry latency,
#                12-cycle return with the FPU context not stacked).
#   STM32F411 (DS10314 "STM32F411xC STM32F411xE" datasheet; the revision on st.com):
#     run        100 µA/MHz: title page, "Power consumption: Run: 100 µA/MHz (peripheral off)".
#     sleep      1000 µA at fHCLK = 16 MHz (HSI, PLL off) with TIM2 and ADC1 clocked:
#                table "Typical and maximum current consumption in Sleep mode" - CHECK.
#     adc        1600 µA while the ADC is on: table "ADC characteristics", IDDA - CHECK.
#     stop       9 µA + 1 µA RTC between windows: title page ("Stop ... down to 9 µA",
#                "VBAT supply for RTC: 1 µA").
#     wake       100 µs from Stop (flash in deep power-down) at run current: table
#                "Low-power mode wakeup timings" - CHECK.
#     clock      16 MHz HSI, PLL off.
#   STM32L432 (DS11451 "STM32L432KB STM32L432KC" datasheet; the revision on st.com):
#     run        K_RUN µA/MHz, default 84: title page, "84 µA/MHz run mode" (LDO). The
#                title's figure is the part's best (CHECK: Range 2 at its highest clock, as
#                remembered); at the 4 MHz of the path below the table "Current consumption
#                in Run and Low-power run modes" gives more per MHz (a fixed part): the table
#                prints the K_RUN under which the goal still holds.
#     stop2      1.28 µA: title page, "1.0 µA Stop 2 mode, 1.28 µA with RTC" (LPTIM1 wakes it).
#     wake       4 µs from Stop: title page, "4 µs wakeup from Stop mode".
#     adc        200 µA/Msps: title page, "... 12-bit ADC 5 Msps ... 200 µA/Msps" (taken as
#                the same charge a conversion at a slower ADC clock).
#     adcvreg    20 µs of the ADC's voltage regulator start-up after each Stop 2: table "ADC
#                characteristics", tADCVREG_STUP - CHECK (corroborated only by ST's G0 LL
#                driver's LL_ADC_DELAY_INTERNAL_REGUL_STAB_US).
#     tconv      15 ADC clock cycles a 12-bit conversion (12.5 + the shortest sampling time
#                2.5): reference manual RM0394, "ADC conversion time" - CHECK. The ADC is
#                clocked from HCLK (CKMODE = HCLK/1), so a burst of OVSR conversions keeps
#                the core awake 15·OVSR cycles whatever the clock.
#   The L432's path: LPTIM1 (LSE) wakes it from Stop 2 at the row rate; the ADC's regulator
#   starts, a burst of OVSR conversions is averaged by the hardware oversampler (ADC_CFGR2
#   OVSR, a power of two) into one row; the core computes the row at F_MHZ (MSI, voltage
#   Range 2) and returns to Stop 2. The ADC cannot run in Stop 2, so the burst averages noise
#   but does not band-limit: the front end's RC filter must do that below half the row rate.
#   OVSR 4 (the path's default, OVSR=N to change it): eveh's recording has a sensor noise of
#   5.3 µm rms on a 5 mm full scale; a 12-bit LSB is 1.2 µm, its quantisation 0.35 µm rms, and
#   the L4's ADC noise about an LSB (CHECK: the datasheet's ENOB), so one conversion adds
#   ≈ 5 % to the noise power a row and a burst of 4 ≈ 1.3 %: the sensor's noise, not the
#   ADC's, sets the accuracy here. A quieter sensor (or a smaller signal in the full scale)
#   wants a longer burst: 16 costs 6 µW more, 64 costs 54 (the table's levers).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
seconds=${SECONDS_PLAYED:-600}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build --release --locked --quiet -p lssi-host --bin lssi
lssi="${CARGO_TARGET_DIR:-$root/target}/release/lssi"
fw="$root/crates/lssi-firmware"
(cd "$fw" && cargo build --release --locked --quiet --bin lssi-standalone)
standalone="$work/standalone.elf"
cp "$fw/target/thumbv7em-none-eabihf/release/lssi-standalone" "$standalone"

# The rate `lssi identify` proposes for eveh, from a 20 s recording at 10 kHz.
proposal=""
if [[ -z ${ROW_HZ:-} ]]; then
    "$lssi" gen eveh "$work/eveh10k.csv" --rate 10000 --t-end 20 --observe x >/dev/null
    proposal=$("$lssi" identify "$work/eveh10k.csv" 2>&1 | grep -m1 "a device needs" || true)
    ROW_HZ=$(sed -n 's/.*a device needs \([0-9.]*\) Hz.*/\1/p' <<<"$proposal")
    if [[ -z $ROW_HZ ]]; then
        echo "firmware-power: lssi identify proposed no rate for eveh" >&2
        exit 1
    fi
fi

if [[ -z ${CONV_COST:-} || -z ${DEC_COST:-} ]]; then
    (cd "$fw" && cargo build --release --locked --quiet --features bench-profile)
    cp "$fw/target/thumbv7em-none-eabihf/release/lssi-firmware" "$work/profile.elf"
    timeout 300 qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic -monitor none \
        -serial null -semihosting-config enable=on,target=native -icount shift=0 \
        -kernel "$work/profile.elf" | defmt-print -e "$work/profile.elf" >"$work/profile.out"
    CONV_COST=$(sed -n 's/.*bench-id sampler_conversion .*mean=\([0-9]*\).*/\1/p' "$work/profile.out" | head -1)
    DEC_COST=$(sed -n 's/.*bench-id decimate_conversion .*mean=\([0-9]*\).*/\1/p' "$work/profile.out" | head -1)
    if [[ -z $CONV_COST ]]; then
        cat "$work/profile.out" >&2
        echo "firmware-power: no decimation figures from the bench-profile image" >&2
        exit 1
    fi
fi

# The recording ends half-way between two of the image's scheduled screenings (one every
# MODEL_INTERVAL_S = 300 s, rounded down to whole screenings of `lssi identify`'s 10 000
# rows): a scheduled screening at the very end would run after it, beside the final one,
# and be taken for the final screening's cost (checked below).
if [[ -z ${SECONDS_PLAYED:-} ]]; then
    seconds=$(awk -v r="$ROW_HZ" -v s="$seconds" 'BEGIN {
        every = 10000 / r; n = int(300 / every); if (n < 1) n = 1; i = n * every
        k = int(s / i); if (k < 1) k = 1; printf "%.3f", (k + 0.5) * i }')
fi
"$lssi" gen eveh "$work/eveh.csv" --rate "$ROW_HZ" --t-end "$seconds" --observe x >/dev/null
"$lssi" monitor --qemu "$work/eveh.csv" --json --firmware "$standalone" \
    --log "$work/eveh.tlm" >"$work/eveh.json"
"$lssi" log "$work/eveh.tlm" --elf "$standalone" >"$work/eveh.log" 2>&1 || true
awake=$(sed -n 's/.*awake while sampling: \([0-9]*\) ticks over \([0-9]*\) sampling.*/\1 \2/p' "$work/eveh.log" | head -1)
read -r awake_ticks interrupts <<<"$awake"
run=$(sed -n 's/.*screenings run while sampling: \([0-9]*\) (a model every \([0-9]*\) .*/\1 \2/p' "$work/eveh.log" | head -1)
read -r screenings stride <<<"$run"
period=$(sed -n 's/.*screening every \([0-9]*\).*/\1/p' "$work/eveh.log" | head -1)
# The final screening is sliced over the timer's ticks like the rest: its cost is the ticks
# awake after the recording ended (it and its two frames), not its clock time.
final_screen=$(sed -n 's/.*awake after the recording ended: \([0-9]*\) ticks.*/\1/p' "$work/eveh.log" | head -1)
read -r row_push overruns <<<"$(python3 -c '
import json, sys
health = [json.loads(l) for l in open(sys.argv[1]) if "\"health\"" in l]
h = health[-1]
print(h["cost_mean"], h["overruns"])' "$work/eveh.json")"
if [[ -z ${awake_ticks:-} || -z ${final_screen:-} || -z ${stride:-} || -z ${period:-} ]]; then
    cat "$work/eveh.log" >&2
    echo "firmware-power: no awake figure from the standalone image on eveh at $ROW_HZ Hz" >&2
    exit 1
fi
config_line=$(grep -m1 "lssi standalone:" "$work/eveh.log" | sed 's/.*lssi standalone: //')
# The duty cycle as the host configures it: the image's own log of its stored Configure.
duty_flags=(--duty-window 10 --duty-interval 590)
if [[ -n ${DUTY_MODEL_EVERY:-} ]]; then duty_flags+=(--duty-model-every "$DUTY_MODEL_EVERY"); fi
"$lssi" gen eveh "$work/duty.csv" --rate "$ROW_HZ" --t-end 3 --observe x >/dev/null
"$lssi" monitor --qemu "$work/duty.csv" --json --firmware "$standalone" "${duty_flags[@]}" \
    --log "$work/duty.tlm" >/dev/null
"$lssi" log "$work/duty.tlm" --elf "$standalone" >"$work/duty.log" 2>&1 || true
duty_line=$(grep -m1 "duty cycle:" "$work/duty.log" | sed 's/.*duty cycle: //')
every=$(sed -n 's/.*a model every \([0-9]*\) window.*/\1/p' <<<"$duty_line")
if [[ -z $every ]]; then
    cat "$work/duty.log" >&2
    echo "firmware-power: the duty-cycled image logged no duty cycle" >&2
    exit 1
fi
# No scheduled screening may have begun in the last tenth of an interval (it would run after
# the recording, counted with the final one).
if ! awk -v n="$interrupts" -v st="$stride" -v p="$period" 'BEGIN {
    i = st * p; exit !((n % i) > 0.1 * i) }'; then
    echo "firmware-power: the recording ends at a scheduled screening ($interrupts rows, one every $((stride * period))): give another SECONDS_PLAYED" >&2
    exit 1
fi
echo
echo "Average power, eveh (3.41 Hz forcing) at $ROW_HZ rows/s; 10 s windows every 10 min duty-cycled"
if [[ -n $proposal ]]; then echo "(lssi identify on 20 s at 10 kHz: $proposal)"; fi
echo "(the standalone image under QEMU, as lssi identify configures it: $config_line;"
echo " $seconds s played: $interrupts rows, $overruns overruns, awake $awake_ticks ticks of 25 MHz = $((awake_ticks * 5 / 2)) instructions"
echo " while sampling, of which $screenings screenings (a model every $stride scheduled screenings of $period rows);"
echo " a screening $((final_screen * 5 / 2)) instructions, a row's push $((row_push * 5 / 2));"
echo " the F4's conversion through its CIC-3 decimator $CONV_COST, of which $DEC_COST the filter;"
echo " duty-cycled as lssi monitor --duty-window 10 --duty-interval 590 configures it: $duty_line)"
echo
awk -v awake="$awake_ticks" -v n="$interrupts" -v scr_ticks="$final_screen" -v R="$ROW_HZ" \
    -v nscr="$screenings" -v stride="$stride" -v period="$period" -v conv="$CONV_COST" \
    -v krun="${K_RUN:-84}" -v fmhz="${F_MHZ:-4}" -v ovsr_default="${OVSR:-4}" -v every="$every" '
function out(label, cont, duty) {
    printf "| %-66s | %10.0f | %10.1f |\n", label, cont, duty
}
function part(label, cont) {
    printf "| %-66s | %10.1f | %10s |\n", label, cont, ""
}
# The L432 path: per_s instructions a second of rows (no screening), scr_s screenings a
# second, ovsr conversions a row, f the clock (Hz), k the run current (µA/MHz), scr_w
# screenings a duty window. Sets L_cont, L_duty (µW) and L_cycles (core cycles/s).
function l432(per_s, scr_s, ovsr, f, k, scr_w,   wait, adc, cont, win) {
    wait = (wake4 + adcvreg) * f + 15 * ovsr           # cycles a row awake for the ADC
    adc = R * ovsr * 200e-6                            # µA: 200 µA/Msps
    L_cycles = per_s + R * wait + scr_s * scr
    cont = V * (k * L_cycles / 1e6 + adc + stop2)
    win = V * (k * (W * (per_s + R * wait) + scr_w * scr) / 1e6 + W * adc)
    L_cont = cont; L_duty = win / T + V * stop2 * (T - W) / T
    L_wait = wait
}
BEGIN {
    V = 3.3; W = 10; T = 600
    secs = n / R                                   # seconds of sampling
    ins = awake * 2.5                              # instructions awake while sampling
    scr = scr_ticks * 2.5                          # instructions a screening
    base = (ins - nscr * scr) / secs               # a second of sampling, no screening
    scr_rate = 1 / (stride * period / R)           # the image: a screening a model interval
    # STM32F411: 10 kHz conversions, an interrupt each (CIC 3, D = 50), Sleep in between;
    # a screening every 10 000 rows as before (its image samples at 10 kHz: the same base).
    A = 10000; isr = 24; f = 16e6
    k = 100; sleep = 1000; adcf = 1600; stop = 10; wake = 100e-6
    rows = base + A * (conv + isr)
    fscr = scr * scr_rate
    cont_f = V * (k * (rows + fscr) / 1e6 + sleep * (1 - (rows + fscr) / f) + adcf)
    win = V * (k * (W * rows + scr / every) / 1e6 + sleep * W + adcf * W) + V * k * (f / 1e6) * wake
    duty_f = win / T + V * stop * (T - W) / T
    # STM32L432
    stop2 = 1.28; wake4 = 4e-6; adcvreg = 20e-6
    f4 = fmhz * 1e6
    l432(base, scr_rate, ovsr_default, f4, krun, 1 / every); cont_l = L_cont; duty_l = L_duty
    cyc_l = L_cycles; wait_l = L_wait
    # The run current under which the goals hold (everything else as above).
    adc_l = R * ovsr_default * 200e-6
    kmax_c = ((250 / V) - adc_l - stop2) * 1e6 / cyc_l
    win_cyc = W * (base + R * wait_l) + scr / every
    kmax_d = ((10 - V * stop2 * (T - W) / T) * T / V - W * adc_l) * 1e6 / win_cyc
    printf "| %-66s | %10s | %10s |\n", "part and path", "µW cont.", "µW duty"
    printf "|%s|%s|%s|\n", "--------------------------------------------------------------------", "------------", "------------"
    out("STM32F411, 16 MHz, TIM2+ADC1 10 kHz, CIC-3 in the ISR, WFI", cont_f, duty_f)
    part("  of which the ADC, left on", V * adcf)
    part("  of which Sleep between conversions", V * sleep * (1 - (rows + fscr) / f))
    part("  of which the conversions through the decimator", V * k * A * (conv + isr) / 1e6)
    part("  of which the rows, frames and screenings (measured)", V * k * (base + fscr) / 1e6)
    out(sprintf("STM32L432, Stop 2 between rows, %g MHz, a burst of %d", fmhz, ovsr_default), cont_l, duty_l)
    part("  of which the rows, interrupts, frames (measured)", V * krun * base / 1e6)
    part(sprintf("  of which a screening every %.0f s (measured)", 1 / scr_rate), V * krun * scr * scr_rate / 1e6)
    part("  of which awake for the wake-up, ADC start and burst", V * krun * R * wait_l / 1e6)
    part("  of which the ADC conversions", V * adc_l)
    part("  of which Stop 2 between rows", V * stop2)
    printf "| %-66s | %10s | %10.1f |\n", "  duty-cycled: the rows of a window", "", V * krun * W * (base + R * wait_l) / 1e6 / T
    printf "| %-66s | %10s | %10.1f |\n", sprintf("  duty-cycled: a model'"'"'s screening every %d windows", every), "", V * krun * scr / every / 1e6 / T
    printf "| %-66s | %10s | %10.1f |\n", "  duty-cycled: Stop 2 between windows", "", V * stop2 * (T - W) / T
    # Levers, each from the measured instructions (one thing changed from the row above it).
    e = 1 / every
    l432(base, scr_rate, 64, 16e6, krun, e); out("  lever: 16 MHz, a burst of 64", L_cont, L_duty)
    l432(base, scr_rate, 16, 16e6, krun, e); out("  lever: 16 MHz, a burst of 16", L_cont, L_duty)
    l432(base, scr_rate, ovsr_default, 2e6, krun, e); out(sprintf("  lever: 2 MHz (MSI, Low-power run; same µA/MHz: CHECK), a burst of %d", ovsr_default), L_cont, L_duty)
    l432(base, scr_rate, 16, f4, krun, e); out(sprintf("  lever: %g MHz, a burst of 16", fmhz), L_cont, L_duty)
    l432(base, scr_rate, 1, f4, krun, e); out(sprintf("  lever: %g MHz, one conversion a row", fmhz), L_cont, L_duty)
    l432(base, R / 10000, ovsr_default, f4, krun, e); out(sprintf("  lever: a screening every %.0f s (every scheduled one)", 10000 / R), L_cont, L_duty)
    l432(base, scr_rate, ovsr_default, f4, krun, 1); out("  lever: duty-cycled, a model every window (--duty-model-every 1)", L_cont, L_duty)
    l432(base, scr_rate, ovsr_default, f4, krun, 1 / 2); out("  lever: duty-cycled, a model every 2nd window (20 min)", L_cont, L_duty)
    l432(base, scr_rate, ovsr_default, f4, krun, 1 / 6); out("  lever: duty-cycled, a model every 6th window (an hour)", L_cont, L_duty)
    printf "\n"
    printf "average power: eveh at %g rows/s (%.0f a forcing period), as lssi identify configures it, measured under QEMU: STM32F411 %.0f µW continuous, %.1f µW duty-cycled (10 s every 10 min, a model every %d windows); STM32L432 at %g MHz %.0f µW continuous (goal <= 250: %s), %.1f µW duty-cycled (goal <= 10: %s)\n", R, R / 3.406, cont_f, duty_f, every, fmhz, cont_l, (cont_l <= 250 ? "met" : "NOT met"), duty_l, (duty_l <= 10 ? "met" : "NOT met")
    printf "  the L432 goals hold while its run current at %g MHz is at most %.1f µA/MHz (continuous) and %.1f µA/MHz (duty-cycled); assumed %g (the datasheet title page'"'"'s best, CHECK at %g MHz)\n", fmhz, kmax_c, kmax_d, krun, fmhz
    printf "  per day: STM32F411 %.2f J / %.3f J, STM32L432 %.2f J / %.3f J (continuous / duty-cycled)\n", cont_f * 86400e-6, duty_f * 86400e-6, cont_l * 86400e-6, duty_l * 86400e-6
    printf "  instructions a second of sampling: %.0f (%.0f a row) without screenings, + %.0f for a screening every %.0f s\n", base, base / R, scr * scr_rate, 1 / scr_rate
}'
