#!/usr/bin/env bash
# A hostile test set for the single-equation harvester (issue 25): `lssi gen eveh` with
# parameters drawn per seed (wells mono-/bistable, forcing amplitude 0.3-5 m/s^2 log-uniform,
# rate 150 Hz-20 kHz log-uniform, length 3-40 s, noise 0-5 %, a DC offset of 0-1000
# amplitudes on x), each run as a user would (`lssi identify --json FILE`, f32, refined by
# default) and classified:
#   true model  the truth's terms and no others, coefficients within 10 %, damping v within 25 %
#   withheld    exit 3 (the reason's sentence shown)
#   refused     exit 2 (the reason's sentence shown)
#   WRONG       exit 0 with any other model
# Prints a markdown table (one row a seed) and the counts.
#
#   scripts/hostile-eveh.sh                      # seeds 9101-9130 (9001-9030 were used to tune)
#   SEEDS="$(seq 9001 9030)" JOBS=2 scripts/hostile-eveh.sh
#
# Records are capped at 400,000 samples (the length is shortened at the highest rates).
# Needs target/release/lssi (cargo build --release -p lssi-host) and python3.
set -euo pipefail
cd "$(dirname "$0")/.."
L=${LSSI:-target/release/lssi}
SEEDS=${SEEDS:-$(seq 9101 9130)}
JOBS=${JOBS:-2}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

python3 - "$L" "$work" "$JOBS" $SEEDS <<'PY'
import concurrent.futures as cf, json, math, os, random, subprocess, sys
L, work, jobs, seeds = sys.argv[1], sys.argv[2], int(sys.argv[3]), [int(s) for s in sys.argv[4:]]

def variant(seed):
    r = random.Random(seed)
    rate = math.exp(r.uniform(math.log(150), math.log(20000)))
    rate = float(f'{rate:.3g}')
    t_end = math.exp(r.uniform(math.log(3), math.log(40)))
    t_end = float(f'{min(t_end, 400000 / rate):.3g}')
    return dict(
        wells=r.choice(['monostable', 'bistable']),
        amplitude=float(f'{math.exp(r.uniform(math.log(0.3), math.log(5))):.3g}'),
        rate=rate, t_end=t_end,
        delta=r.choice([0.0, 0.005, 0.01, 0.02, 0.03, 0.05]),
        offset=r.choice([0, 0, 0, 10, 1000]),
    )

def key(name):
    return 'cos' if name.startswith('cos(') else 'sin' if name.startswith('sin(') else name

def run(seed):
    p = variant(seed)
    path = os.path.join(work, f'h{seed}.csv')
    subprocess.run([L, 'gen', 'eveh', '--wells', p['wells'], '--amplitude', str(p['amplitude']),
                    '--rate', str(p['rate']), '--t-end', str(p['t_end']), '--delta', str(p['delta']),
                    '--seed', str(seed), path], check=True, capture_output=True)
    truth = json.load(open(path[:-4] + '.json'))
    if p['offset']:
        lines = open(path).read().split('\n')
        head = lines[0].split(',')
        ix = head.index('x')
        rows = [l.split(',') for l in lines[1:] if l]
        xs = [float(r[ix]) for r in rows]
        amp = max(abs(x) for x in xs)
        with open(path, 'w') as f:
            f.write(lines[0] + '\n')
            for r in rows:
                r[ix] = repr(float(r[ix]) + p['offset'] * amp)
                f.write(','.join(r) + '\n')
    out = subprocess.run([L, 'identify', '--json', path], capture_output=True, text=True)
    os.remove(path)
    want = {key(t['term']): t['coef'] for t in truth['terms']}
    if out.returncode == 0:
        got = {key(t['term']): t['coef'] for t in json.loads(out.stdout)['terms']}
        ok = set(got) == set(want) and all(
            abs(got[k] / w - 1) <= (0.25 if k == 'v' else 0.10) for k, w in want.items())
        if ok:
            worst = max(abs(got[k] / w - 1) for k, w in want.items())
            return p, 'true model', f'worst coefficient {100 * worst:.2g} %'
        eq = ' '.join(f'{v:+.4g} {k}' for k, v in got.items())
        return p, 'WRONG', eq
    reason = out.stderr.strip().split('\n')[-1] if out.stderr.strip() else ''
    reason = reason.split(': ', 1)[-1][:110].replace('|', '/')
    return p, 'withheld' if out.returncode == 3 else 'refused' if out.returncode == 2 else f'exit {out.returncode}', reason

with cf.ThreadPoolExecutor(jobs) as pool:
    results = list(pool.map(run, seeds))
print('| seed | wells | F (m/s²) | rate (Hz) | length (s) | noise | offset (amplitudes) | outcome | detail |')
print('|---:|---|---:|---:|---:|---:|---:|---|---|')
counts = {}
for seed, (p, outcome, detail) in zip(seeds, results):
    counts[outcome] = counts.get(outcome, 0) + 1
    print(f"| {seed} | {p['wells']} | {p['amplitude']:g} | {p['rate']:g} | {p['t_end']:g} | "
          f"{100 * p['delta']:g} % | {p['offset']:g} | {outcome} | {detail} |")
print()
print(' · '.join(f'{k}: {counts.get(k, 0)}' for k in ['true model', 'withheld', 'refused', 'WRONG'])
      + f' (of {len(seeds)})')
PY
