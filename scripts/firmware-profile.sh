#!/usr/bin/env bash
# Where the Cortex-M4F's instructions go, by source line: a profile of lssi-core's identifier
# under QEMU, from QEMU's own execution trace (QEMU does not model the DWT cycle counter and
# this machine has no TCG plugins, so the trace is the profiler).
#
#   bash scripts/firmware-profile.sh                 # as `lssi identify` configures (bench-weak)
#   bash scripts/firmware-profile.sh bench-identifier   # the device's default configuration
#   LSSI_PROFILE_SECONDS=40 bash scripts/firmware-profile.sh   # a longer trace (default 25 s)
#
# How: the firmware-bench image runs under `qemu-system-arm -d in_asm,exec,nochain`; every
# translated block's instructions are read once (in_asm) and every execution of a block is
# counted (exec), streamed through awk (about 100 MB of log a second, never written to disk).
# Each instruction's count is then mapped to its source line (`llvm-objdump -d -l`, the
# release profile keeps line tables). Counts are divided by the samples pushed in the trace
# (the entries of the bench's `sample_mark`, called once a sample): instructions a sample. The trace covers the image's
# start-up, calibration and signal generation too; only lssi-core's lines are listed. A
# line of the standard library (an iterator, an `+=`) is code inlined into the function named
# beside it. The first few hundred samples fill the window and the warm-up, so this is a
# profile of the streaming rows, not of a screening (10 000 samples in).
# Needs qemu-system-arm and llvm-tools (rustup component add llvm-tools).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root/crates/lssi-firmware"
image=${1:-bench-weak}
seconds=${LSSI_PROFILE_SECONDS:-25}

host=$(rustc -vV | sed -n 's/^host: //p')
objdump="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-objdump"
for tool in "$objdump" qemu-system-arm; do
    if ! command -v "$tool" >/dev/null; then
        echo "firmware-profile: $tool not found (rustup component add llvm-tools;" \
            "apt-get install qemu-system-arm)" >&2
        exit 1
    fi
done
case "$image" in
bench-weak | bench-identifier) ;;
*)
    echo "firmware-profile: unknown image '$image' (bench-weak or bench-identifier)" >&2
    exit 2
    ;;
esac

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release --locked --quiet --features "$image"
cp target/thumbv7em-none-eabihf/release/lssi-firmware "$work/image.elf"

# Every instruction's execution count: "address count" (hex address).
mkfifo "$work/trace"
timeout "$seconds" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
    -monitor none -serial null -semihosting-config enable=on,target=native \
    -icount shift=0 -kernel "$work/image.elf" -d in_asm,exec,nochain -D "$work/trace" \
    >/dev/null 2>&1 &
awk '
/^IN: /         { inblock = 1; start = ""; list = ""; next }
inblock && /^0x[0-9a-f]+:/ { pc = substr($1, 3, 8); if (start == "") start = pc; list = list " " pc; next }
inblock && /^$/ { if (start != "") block[start] = list; inblock = 0; next }
/^Trace/        { split($4, f, "/"); runs[f[2]]++; next }
END {
    for (b in runs) { n = split(block[b], pcs, " "); for (i = 1; i <= n; i++) count[pcs[i]] += runs[b] }
    for (pc in count) print pc, count[pc]
}' "$work/trace" >"$work/counts"
wait || true

"$objdump" -d -l -C --no-show-raw-insn "$work/image.elf" >"$work/dis"
python3 - "$work/dis" "$work/counts" "$image" <<'EOF'
import collections, re, sys
dis, counts, image = sys.argv[1:]
line_of, func_of, entry, calls = {}, {}, {}, {}
func = line = None
for l in open(dis):
    m = re.match(r'^([0-9a-f]+) <(.*)>:', l)
    if m:
        func, line = m.group(2), None
        entry[func] = int(m.group(1), 16)
        continue
    if l.startswith('; '):
        line = l[2:].strip()
        continue
    m = re.match(r'^\s+([0-9a-f]+):', l)
    if m:
        a = int(m.group(1), 16)
        line_of[a], func_of[a] = line, func
        call = re.search(r'\tbl\s+0x[0-9a-f]+ <(.*)>', l)
        if call:
            calls[a] = call.group(1)
count = {int(a, 16): int(c) for a, c in (l.split() for l in open(counts))}

def short_func(f):
    f = re.sub(r'::h[0-9a-f]{16}$', '', f)
    for code, text in (('$LT$', '<'), ('$GT$', '>'), ('$C$', ','), ('$u20$', ' '),
                       ('$u7b$', '{'), ('$u7d$', '}'), ('..', '::')):
        f = f.replace(code, text)
    f = re.sub(r'_?<impl lssi_core::identifier::Identifier<T,_,_,_>>', 'Identifier', f)
    f = re.sub(r'<T(,_)*>', '', f)
    return f.replace('lssi_core::', '')

def short_line(l):
    if l is None:
        return '?'
    l = re.sub(r'^/rustc/[0-9a-f]+/library/', 'std:', l)
    l = re.sub(r'^.*/crates/lssi-core/src/', 'lssi-core/', l)
    l = re.sub(r'^.*/registry/src/[^/]+/', '', l)
    return l

# Samples pushed: entries of the bench's `sample_mark`, called once before every push.
marks = [f for f in entry if 'sample_mark' in f]
samples = max((count.get(entry[f], 0) for f in marks), default=0)
if samples == 0:
    sys.exit('firmware-profile: no sample was pushed in the trace (a longer LSSI_PROFILE_SECONDS?)')
total = 0
by_line, by_file, by_func = collections.Counter(), collections.Counter(), collections.Counter()
for a, c in count.items():
    f, l = func_of.get(a, '?'), short_line(line_of.get(a))
    in_core = 'lssi_core' in f or ('bench_identifier::stream' in f and 'closure' in f)
    if not (l.startswith('lssi-core/') or in_core):
        continue
    if 'Meter' in f or 'Eq17' in f or 'sample_mark' in f:
        continue
    total += c
    by_line[(short_func(f), l)] += c
    by_func[short_func(f)] += c
    file = l.split(':')[0] if l.startswith('lssi-core/') else 'std, inlined into ' + short_func(f)
    by_file[file] += c
print(f'firmware profile, image {image}: {samples} samples pushed in the trace; '
      f'lssi-core: {total / samples:.0f} instructions a sample (calls into compiler_builtins '
      'and libm are not counted here)')
print()
print('| instructions a sample | source file (lssi-core), or standard library inlined into |')
print('|---:|---|')
for file, c in by_file.most_common(25):
    print(f'| {c / samples:.1f} | {file} |')
print()
print('| instructions a sample | function (with what was inlined into it) |')
print('|---:|---|')
for f, c in by_func.most_common(20):
    print(f'| {c / samples:.1f} | `{f}` |')
print()
print('| instructions a sample | function | line |')
print('|---:|---|---|')
for (f, l), c in by_line.most_common(40):
    print(f'| {c / samples:.1f} | `{f}` | {l} |')
# The soft-float and memory helpers, whoever called them (the trace cannot tell).
helpers = collections.Counter()
for a, c in count.items():
    f = func_of.get(a, '?')
    if re.search(r'compiler_builtins|__aeabi|libm|__(add|sub|mul|div)[sd]f3', f):
        helpers[short_func(f)] += c
print()
print('Helpers (soft f64, mem*, libm), every caller (the signal generator and the meter too):')
print()
print('| instructions a sample | helper |')
print('|---:|---|')
for f, c in helpers.most_common(12):
    print(f'| {c / samples:.1f} | `{f}` |')
# Who calls them, by call site: the soft-f64 time arithmetic and the arrays zeroed by memclr.
sites = collections.Counter()
for a, target in calls.items():
    if not re.search(r'compiler_builtins|__aeabi|libm|__(add|sub|mul|div)[sd]f3', target):
        continue
    f = func_of.get(a, '?')
    if 'Meter' in f or 'Eq17' in f or not ('lssi_core' in f or 'stream' in f):
        continue
    sites[(short_func(target), short_func(f), short_line(line_of.get(a)))] += count.get(a, 0)
print()
print("Calls from lssi-core's code into the helpers (calls a sample, helper, caller, line):")
print()
print('| calls a sample | helper | caller | line |')
print('|---:|---|---|---|')
for (t, f, l), c in sites.most_common(15):
    if c:
        print(f'| {c / samples:.3f} | `{t}` | `{f}` | {l} |')
EOF
