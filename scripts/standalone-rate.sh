#!/usr/bin/env bash
# The highest sampling rate at which the standalone firmware under QEMU loses no sample
# (-icount shift=4,sleep=off: 62.5 M instructions a guest second, a 64 MHz Cortex-M4F's pace),
# found by bisection, for the image's default configuration and for the one `lssi identify`
# chooses; then the 10 kHz figures (overruns, queue high-water mark, worst latency from the
# timer interrupt to the row done, screenings skipped). Prints a table.
#   bash scripts/standalone-rate.sh            (needs scripts/setup.sh done: QEMU, the images)
# LSSI_RATE_SECONDS (default 4): seconds of recording per trial.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
cargo build --release --locked -p lssi-host --bin lssi >/dev/null 2>&1
(cd crates/lssi-firmware && cargo build --release --locked >/dev/null 2>&1)
lssi=target/release/lssi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
seconds=${LSSI_RATE_SECONDS:-4}

# trial RATE MODE -> prints the summary line (MODE: image or identify)
trial() {
    local rate=$1 mode=$2 csv="$work/r$1.csv"
    [[ -f $csv ]] || "$lssi" gen eveh "$csv" --rate "$rate" --t-end "$seconds" --observe x >/dev/null
    local flags=()
    [[ $mode == image ]] && flags+=(--image-config)
    "$lssi" monitor --qemu "$csv" --json --log "$work/m.tlm" "${flags[@]}" | tail -n 1
}
field() { python3 -c "import json,sys; print(json.loads(sys.argv[1])[sys.argv[2]])" "$1" "$2"; }

bisect() {
    local mode=$1 lo=1000 hi=60000
    while (( hi - lo > lo / 100 )); do
        local mid=$(( (lo + hi) / 2 ))
        local s
        s=$(trial "$mid" "$mode")
        if [[ $(field "$s" overruns) == 0 ]]; then lo=$mid; else hi=$mid; fi
    done
    echo "$lo"
}

printf '%-34s %12s\n' "configuration" "max rate, Hz (0 overruns, ±1 %)"
for mode in image identify; do
    printf '%-34s %12s\n' "$mode" "$(bisect "$mode")"
done
echo
printf '%-12s %10s %10s %16s %18s\n' "at 10 kHz" overruns high-water "worst latency µs" "screenings skipped"
for mode in image identify; do
    s=$(trial 10000 "$mode")
    skipped=$("$lssi" log "$work/m.tlm" --json | python3 -c "
import json,sys
h=[json.loads(l) for l in sys.stdin if '\"kind\":\"health\"' in l]
print(h[-1]['screenings_skipped'] if h else '?')")
    printf '%-12s %10s %10s %16s %18s\n' "$mode" "$(field "$s" overruns)" "$(field "$s" queue_high_water)" "$(field "$s" latency_max_us)" "$skipped"
done
