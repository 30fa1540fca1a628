#!/usr/bin/env bash
# The quality gate over whole streamed files (issue 25, 3): recordings over 8 MiB (read in
# chunks), clean ones of many variants and ones whose dynamics break after the first 65,536
# rows (flat: the sensor died; noise: a loose wire; other: the monostable harvester's x from
# there on), or only in their last 5 % (tail*). Prints one line per file: its exit status (0 model, 3 withheld) and the first
# line of the model or of the refusal, for $LSSI and, when set, $LSSI_BEFORE.
#   LSSI=target/release/lssi [LSSI_BEFORE=/path/to/old/lssi] scripts/stream-gate.sh [DIR]
# Also the peak memory and time of a 10 MB and a 100 MB file by path and by pipe (STREAM_BENCH=1).
set -euo pipefail
LSSI=${LSSI:-target/release/lssi}
LSSI=$(realpath "$LSSI")
DIR=${1:-$(mktemp -d)}
mkdir -p "$DIR"
cd "$DIR"
gen() { # name, gen args...
  local name=$1; shift
  [ -f "$name.csv" ] || "$LSSI" gen eveh "$@" "$name.csv" >/dev/null
}
# Row 100,000 on (or $KEEP on): x replaced (t kept).
splice() { # kind, source, out, [other]
  awk -F, -v kind="$1" -v keep="${KEEP:-100000}" -v other="${4:-}" 'BEGIN { srand(7) }
    NR == 1 { print; next }
    NR <= keep + 1 { print; xs += $2 * $2; n++; last = $2; next }
    {
      if (kind == "flat") print $1 "," last;
      else if (kind == "noise") {
        # Box-Muller, RMS of the kept part.
        u = rand(); v = rand(); if (u < 1e-12) u = 1e-12;
        printf "%s,%.9g\n", $1, sqrt(xs / n) * sqrt(-2 * log(u)) * cos(6.283185307179586 * v)
      } else {
        if ((getline line < other) <= 0) exit;
        split(line, f, ","); print $1 "," f[2]
      }
    }' "$2" > "$3"
}
# Clean variants (all over 8 MiB).
gen b50k-s1 --rate 50000 --t-end 10 --seed 1
gen b50k-s2 --rate 50000 --t-end 10 --seed 2
gen b50k-s3 --rate 50000 --t-end 12 --seed 3 --amplitude 1.5
gen m50k-s1 --wells monostable --rate 50000 --t-end 10 --seed 1
gen m50k-s2 --wells monostable --rate 50000 --t-end 10 --seed 2 --amplitude 0.6
gen b20k-s4 --rate 20000 --t-end 30 --seed 4
gen b2k-s5 --rate 2000 --t-end 300 --seed 5
gen b50k-xv --rate 50000 --t-end 8 --seed 6 --observe xv
gen b50k-noisy --rate 50000 --t-end 10 --seed 7 --delta 0.02
gen b50k-u --rate 50000 --t-end 8 --seed 8 --input
gen m10k-s9 --wells monostable --rate 10000 --t-end 60 --seed 9
# Broken after 100,000 rows (2 s at 50 kHz).
gen m50k-other --wells monostable --rate 50000 --t-end 10 --seed 11
for base in b50k-s1 b50k-s2; do
  [ -f "$base-flat.csv" ] || splice flat "$base.csv" "$base-flat.csv"
  [ -f "$base-noise.csv" ] || splice noise "$base.csv" "$base-noise.csv"
  if [ ! -f "$base-other.csv" ]; then
    tail -n +2 m50k-other.csv > other.rows
    # getline reads from row 1: skip the first 100,000 rows of the other file.
    tail -n +100001 other.rows > other.tail
    splice other "$base.csv" "$base-other.csv" other.tail
  fi
  # Broken in the last 5 % only (from row 475,000 of 500,001): between the gate's kept
  # blocks, within the file's last block.
  [ -f "$base-tailflat.csv" ] || KEEP=475000 splice flat "$base.csv" "$base-tailflat.csv"
  [ -f "$base-tailnoise.csv" ] || KEEP=475000 splice noise "$base.csv" "$base-tailnoise.csv"
  if [ ! -f "$base-tailother.csv" ]; then
    tail -n +2 m50k-other.csv | tail -n +475001 > other.tail
    KEEP=475000 splice other "$base.csv" "$base-tailother.csv" other.tail
  fi
done
run() { # binary, file: the exit status, then the model's first line or the refusal
  local rc=0
  "$1" identify "$2" >out.txt 2>err.txt || rc=$?
  printf 'exit %s\t%s\n' "$rc" "$( (head -1 out.txt; grep -v "warning" err.txt) | head -c 400)"
}
for f in b50k-s1 b50k-s2 b50k-s3 m50k-s1 m50k-s2 b20k-s4 b2k-s5 b50k-xv b50k-noisy b50k-u m10k-s9 \
  b50k-s1-flat b50k-s1-noise b50k-s1-other b50k-s2-flat b50k-s2-noise b50k-s2-other \
  b50k-s1-tailflat b50k-s1-tailnoise b50k-s1-tailother b50k-s2-tailflat b50k-s2-tailnoise \
  b50k-s2-tailother; do
  size=$(stat -c %s "$f.csv")
  printf '%s (%s bytes)\n  after:  %s\n' "$f" "$size" "$(run "$LSSI" "$f.csv")"
  if [ -n "${LSSI_BEFORE:-}" ]; then
    printf '  before: %s\n' "$(run "$LSSI_BEFORE" "$f.csv")"
  fi
done
if [ -n "${STREAM_BENCH:-}" ]; then
  gen big100 --rate 50000 --t-end 100
  for f in b50k-s1 big100; do
    for how in path pipe; do
      if [ $how = path ]; then
        /usr/bin/time -f "$f $how: %e s, max RSS %M KiB" "$LSSI" identify "$f.csv" >/dev/null 2>time.txt || true
      else
        cat "$f.csv" | /usr/bin/time -f "$f $how: %e s, max RSS %M KiB" "$LSSI" identify - >/dev/null 2>time.txt || true
      fi
      tail -1 time.txt
    done
  done
fi
