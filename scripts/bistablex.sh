#!/usr/bin/env bash
# BistableX (a measured bistable piezo-magneto-elastic harvester; ../shared/data/real/bistablex,
# not in the repository: its licence, CC BY-NC-ND, allows no derived copies to be shipped)
# converted into the columns lssi reads, and identified on the first half of each record with
# the command a user runs. Issue 26, item 6 (preparation): today lssi identifies the mechanical
# equation x'' only and ignores V; this script is what the system identification will build on.
#
# Each record's channels (README.txt beside the data) become, in SI units:
#   t  seconds (t_s as measured)
#   u  base acceleration, m/s²  = base_acc_g · 9.80665 (the relative motion obeys
#      x'' + … = −u, so u's coefficient is about −1 in the modal coordinate of the tip)
#   v  beam-tip velocity RELATIVE to the base, m/s = vibrometer_velocity_V_raw / 10 (the
#      authors' 0.1 m/s per V; the vibrometer measures absolute velocity) minus the base
#      velocity, which is u integrated (trapezoid) with its least-squares line removed (the
#      accelerometer's offset and the unknown initial velocity); the result has its own
#      least-squares line removed (the vibrometer's offset)
#   x  tip displacement relative to the base, m = v integrated (trapezoid) with its
#      least-squares line removed: a zero-mean displacement, so in an intrawell record x is
#      measured from the centre of the orbit in its well, not from the symmetric position
#   V  piezo voltage across the load, volts, as recorded (R_L = 1 MΩ per the setup PDF;
#      measured through a 10x probe, so the true voltage may be 10 V per recorded volt)
#
# Usage: scripts/bistablex.sh [KEEP_DIR]   (KEEP_DIR: where to leave the CSVs; default a
# temporary directory that is removed on exit). LSSI=path/to/lssi to use a built binary.
# Not part of CI: it needs the data beside the clone.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data="$root/../shared/data/real/bistablex/continuous_6p5Hz"
if [[ ! -d $data ]]; then
    echo "$data is not beside this clone: the BistableX check cannot run." >&2
    exit 0
fi
lssi=${LSSI:-}
if [[ -z $lssi ]]; then
    (cd "$root" && cargo build --release --locked -q -p lssi-host --bin lssi)
    lssi="$root/target/release/lssi"
fi
if [[ $# -ge 1 ]]; then
    work=$1
    mkdir -p "$work"
else
    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
fi

# convert IN OUT: the columns t,x,v,V,u of one record (see the top of this file).
convert() {
    awk -F, '
    # Removes the least-squares line in t from y[1..n].
    function detrend(y,    i, st, sy, stt, sty, d, slope, icpt) {
        st = 0; sy = 0; stt = 0; sty = 0
        for (i = 1; i <= n; i++) { st += t[i]; sy += y[i]; stt += t[i] * t[i]; sty += t[i] * y[i] }
        d = n * stt - st * st
        slope = (n * sty - st * sy) / d
        icpt = (sy - slope * st) / n
        for (i = 1; i <= n; i++) y[i] -= icpt + slope * t[i]
    }
    # y = the running trapezoid integral of f, from 0.
    function integrate(f, y,    i) {
        y[1] = 0
        for (i = 2; i <= n; i++) y[i] = y[i - 1] + 0.5 * (f[i] + f[i - 1]) * (t[i] - t[i - 1])
    }
    NR == 1 { next }
    {
        n++
        t[n] = $1 + 0; u[n] = ($2 + 0) * 9.80665; V[n] = $3 + 0; vabs[n] = ($4 + 0) / 10
    }
    END {
        integrate(u, vb); detrend(vb)
        for (i = 1; i <= n; i++) v[i] = vabs[i] - vb[i]
        detrend(v)
        integrate(v, x); detrend(x)
        print "t,x,v,V,u"
        for (i = 1; i <= n; i++) printf "%.9g,%.9g,%.9g,%.9g,%.9g\n", t[i], x[i], v[i], V[i], u[i]
    }' "$1" >"$2"
}

# first_half IN OUT: the header and the first half of the data rows.
first_half() {
    local rows
    rows=$(($(wc -l <"$1") - 1))
    head -n $((1 + rows / 2)) "$1" >"$2"
}

for file in "$data"/*.csv; do
    name=$(basename "$file" .csv)
    convert "$file" "$work/$name.csv"
    first_half "$work/$name.csv" "$work/$name-first-half.csv"
    awk -F, -v name="$name" '
        NR == 1 { next }
        NR == 2 { t0 = $1 }
        NR == 3 { dt = $1 - t0 }
        { n++; t1 = $1
          for (c = 2; c <= 5; c++) { s[c] += $c; q[c] += $c * $c } }
        END {
          printf "%s: %d samples at %.0f Hz over %.2f s; RMS x %.3g m, v %.3g m/s, V %.3g V, u %.3g m/s²\n",
            name, n, 1 / dt, t1 - t0 + dt, sqrt(q[2] / n), sqrt(q[3] / n), sqrt(q[4] / n), sqrt(q[5] / n)
        }' "$work/$name.csv"
    echo "\$ lssi identify $name-first-half.csv"
    "$lssi" identify "$work/$name-first-half.csv" 2>&1 || echo "(exit status $?)"
    echo
done
