#!/usr/bin/env bash
# The lowest sample rate at which the device's model of data/eveh-bistable.csv (2 kHz, 20 s,
# x only, 0.5 % noise) is still within 1 % of the truth: the recording decimated by keeping
# every d-th sample (as a device sampling d times slower would see it, no anti-alias filter:
# the harvester's motion is band-limited to a few harmonics of its 3.4 Hz forcing), then
# `lssi identify --family odd --no-refine` in f32, as the device computes (the streaming model).
#
#   scripts/lowest-rate.sh          # about 10 s after the release build
#   LSSI=/tmp/lssi-main scripts/lowest-rate.sh   # another binary (no build)
#
# Prints one row a rate: mean and worst coefficient error over the four true terms, spurious
# terms, and whether it is within 1 % (mean and worst). Then a second table: what a user's
# plain `lssi identify FILE` (refined, the gate judging the model it prints) gives at the same
# rates and at 2000/60, 2000/80 Hz: the true model's worst error and the damping's, with its
# standard errors, or the withhold's reason.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
L=${LSSI:-}
if [ -z "$L" ]; then
    cargo build --release --locked --quiet -p lssi-host
    L=target/release/lssi
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "| rate Hz | samples a forcing period | mean % | worst % | spurious | within 1 % |"
echo "|---:|---:|---:|---:|---:|---|"
for d in 1 2 4 5 8 10 16 20 25 40; do
    f="$work/d$d.csv"
    awk -v d="$d" 'NR == 1 || (NR - 2) % d == 0' data/eveh-bistable.csv >"$f"
    if ! "$L" identify "$f" --family odd --no-refine --json >"$work/d$d.json" 2>"$work/d$d.err"; then
        echo "| $((2000 / d)) | | no model: $(head -c 120 "$work/d$d.err" | tr '\n' ' ') | | | no |"
        continue
    fi
    python3 - "$work/d$d.json" data/eveh-bistable.json "$d" <<'PY'
import json, sys
got = json.load(open(sys.argv[1]))
truth = json.load(open(sys.argv[2]))
d = int(sys.argv[3])
def kind(name):  # the harmonic terms are named by the Ω in use: compare by kind
    return name.split("(")[0]
est = {kind(t["term"]): t["coef"] for t in got["terms"]}
errs = []
for t in truth["terms"]:
    c = est.get(kind(t["term"]))
    errs.append(100.0 if c is None else 100 * abs(c - t["coef"]) / abs(t["coef"]))
spurious = len(set(est) - {kind(t["term"]) for t in truth["terms"]})
rate = 2000 / d
per_period = rate * 2 * 3.141592653589793 / truth["omega"]
mean = sum(errs) / len(errs)
ok = "yes" if max(errs) <= 1 and spurious == 0 else "no"
print(f"| {rate:g} | {per_period:.0f} | {mean:.3f} | {max(errs):.3f} | {spurious} | {ok} |")
PY
done
echo
echo "| rate Hz | samples a forcing period | \`lssi identify FILE\` | worst % (not v) | v % | v within 2 ± |"
echo "|---:|---:|---|---:|---:|---|"
for d in 1 2 4 5 8 10 16 20 25 40 60 80; do
    f="$work/r$d.csv"
    awk -v d="$d" 'NR == 1 || (NR - 2) % d == 0' data/eveh-bistable.csv >"$f"
    if ! "$L" identify "$f" --json >"$work/r$d.json" 2>"$work/r$d.err"; then
        echo "| $(python3 -c "print(f'{2000 / $d:g}')") | | withheld: $(tail -1 "$work/r$d.err" | cut -d: -f3- | head -c 110 | tr '\n|' ' /') | | | |"
        continue
    fi
    python3 - "$work/r$d.json" data/eveh-bistable.json "$d" <<'PY'
import json, sys
got = json.load(open(sys.argv[1]))
truth = json.load(open(sys.argv[2]))
d = int(sys.argv[3])
kind = lambda name: name.split("(")[0]
est = {kind(t["term"]): (t["coef"], t.get("se") or 0.0) for t in got["terms"]}
want = {kind(t["term"]): t["coef"] for t in truth["terms"]}
rate = 2000 / d
per_period = rate * 2 * 3.141592653589793 / truth["omega"]
if set(est) != set(want):
    print(f"| {rate:g} | {per_period:.0f} | other terms: {', '.join(sorted(est))} | | | |")
    sys.exit()
worst = max(100 * abs(est[k][0] / w - 1) for k, w in want.items() if k != "v")
c, se = est["v"]
verr = 100 * abs(c / want["v"] - 1)
cover = "yes" if abs(c - want["v"]) <= 2 * se else "no"
print(f"| {rate:g} | {per_period:.0f} | the truth's terms | {worst:.2f} | {verr:.1f} (± {100 * se / abs(want['v']):.1f}) | {cover} |")
PY
done
