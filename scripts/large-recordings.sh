#!/usr/bin/env bash
# Large recordings through `lssi identify` (issue 16, item 4): harvester recordings of 10^6,
# 5·10^6 and 10^7 rows (`lssi gen eveh --rate 10000`, bistable, x only, 0.5 % noise) written
# to a temporary folder, each identified with `lssi identify FILE --json` (streamed: files over
# 8 MiB are read in chunks, configured on their first 2^16 rows, Ω refined on probes across
# the file). Wall time and peak RSS from /usr/bin/time (or bash's `time` and /proc when it is
# missing), the mean error over the four true coefficients, and Ω's error.
#
#   scripts/large-recordings.sh            # about 2 min after the release build (mostly gen)
#   scripts/large-recordings.sh 1000000    # only the sizes given
#
# Needs about 350 MB in $TMPDIR for the 10^7-row file.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
cargo build --release --locked --quiet -j 2 -p lssi-host
lssi="$root/target/release/lssi"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(1000000 5000000 10000000)
echo "| rows | file MB | wall s | CPU s (user + sys) | peak RSS MB | mean coefficient error % | Ω error rad/s | terms |"
echo "|---:|---:|---:|---:|---:|---:|---:|---|"
for rows in "${sizes[@]}"; do
    f="$work/r$rows.csv"
    # rows samples from t = 0: t_end one sample short of rows / rate.
    t_end=$(python3 -c "print(($rows - 1) / 10000)")
    "$lssi" gen eveh --rate 10000 --t-end "$t_end" "$f" >/dev/null
    size=$(stat -c %s "$f")
    if [ -x /usr/bin/time ]; then
        /usr/bin/time -f "%e %U %S %M" -o "$work/time" "$lssi" identify "$f" --no-refine --json >"$work/out.json"
        read -r wall user sys rss <"$work/time"
    else
        start=$(date +%s.%N)
        "$lssi" identify "$f" --no-refine --json >"$work/out.json" &
        pid=$!
        rss=0
        while kill -0 "$pid" 2>/dev/null; do
            hwm=$(awk '/VmHWM/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
            [ -n "$hwm" ] && rss=$hwm
            sleep 0.05
        done
        wait "$pid"
        wall=$(python3 -c "import time; print(round(time.time() - $start, 2))")
        user=NA sys=NA
    fi
    python3 - "$work/out.json" "${f%.csv}.json" "$rows" "$size" "$wall" "$user" "$sys" "$rss" <<'PY'
import json, sys
got = json.load(open(sys.argv[1]))
truth = json.load(open(sys.argv[2]))
rows, size, wall, user, sys_, rss = sys.argv[3:9]
def kind(name):  # the harmonic terms are named by the Ω in use: compare by kind
    return name.split("(")[0]
est = {kind(t["term"]): t["coef"] for t in got["terms"]}
errs = []
for t in truth["terms"]:
    c = est.get(kind(t["term"]))
    errs.append(100.0 if c is None else 100 * abs(c - t["coef"]) / abs(t["coef"]))
same = "as the truth" if set(est) == {kind(t["term"]) for t in truth["terms"]} else "DIFFER: " + ", ".join(t["term"] for t in got["terms"])
cpu = "" if user == "NA" else f"{float(user) + float(sys_):.2f}"
assert got["samples"] == int(rows), (got["samples"], rows)
print(f"| {int(rows):,} | {int(size) / 1e6:.0f} | {float(wall):.2f} | {cpu} | {int(rss) / 1024:.0f} | "
      f"{sum(errs) / len(errs):.3f} | {abs(got['omega'] - truth['omega']):.1e} | {same} |")
PY
    rm -f "$f"
done
