#!/usr/bin/env python3
"""lssi against PySINDy on the same recordings: one Markdown table.

Cases: the paper's eq. 17 (dt = 0.001 s, t <= 100 s, eq. 16 noise, x and x' observed) at
delta = 0.001, 0.01, 0.1, written by `lssi gen paper`, and the eveh recordings data/eveh-*.csv
when they exist (scored against the truth JSON beside each, when there is one).

Library (eq. 18): constant, monomials of (x, v) to order 3, sin/cos(k t) for k = 1..3
(lssi: --omega 1 --harmonics 3 --poly-order 3; the eveh cases take Omega from their truth).

PySINDy, two ways:
  default  SmoothedFiniteDifference() (Savitzky-Golay, window 11, order 3), STLSQ with the
           library's documented defaults (threshold 0.1, alpha 0.05) and normalize_columns=True.
  cv       the best of a small grid -- smoothing window {11, 51, 201} x threshold
           tau * ||x''|| with tau in {1e-3, 1e-2, 3e-2, 1e-1} (normalised columns) -- chosen
           by 5-fold cross-validation on contiguous time blocks: fit on four blocks, predict
           x'' on the fifth, and score against a common target that no candidate chooses
           (the central difference of the measured v, or a fixed Savitzky-Golay second
           derivative of x when v is not measured). The true coefficients are never used.

Scores (as `lssi bench accuracy`): per true term |error| / |true| in %, 100 for a missed term;
mean and max over the true terms; spurious = active terms not in the truth.
Wall time: one command on one recording, start-up included, median of 3 (PySINDy: a fresh
Python process that imports pysindy, reads the CSV and fits; lssi: `lssi identify --json
--no-refine`, the streaming identifier's model, as a device computes it);
the CPU time of that process beside it (a shared machine inflates wall times, not CPU times).
Throughput without start-up on 10^6 samples: PySINDy's default `fit` call alone; lssi's
streaming identifier as `lssi bench accuracy --quick` reports it.

Usage: bench/pysindy/run.sh  (makes the venv, builds lssi, runs this file).
"""

import argparse
import glob
import json
import os
import resource
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
CASES = os.path.join(HERE, ".cases")

EQ17_TRUTH = {"x": -1.0, "v": 1.0, "x^2": 2.0, "x^3": -4.0, "x^2*v": -2.0, "cos(2t)": 5.0}
WINDOWS = [11, 51, 201]
TAUS = [1e-3, 1e-2, 3e-2, 1e-1]
FOLDS = 5


# --------------------------------------------------------------------------------------
# Names, as lssi writes them.

def frequency_text(w):
    if w == 1.0:
        return ""
    magnitude = 0
    scaled = w
    while scaled >= 10.0:
        scaled /= 10.0
        magnitude += 1
    while scaled < 1.0:
        scaled *= 10.0
        magnitude -= 1
    decimals = min(max(5 - magnitude, 0), 12)
    text = f"{w:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text


def harmonic_names(omega, harmonics):
    names = []
    for k in range(1, harmonics + 1):
        f = frequency_text(k * omega)
        names += [f"sin({f}t)", f"cos({f}t)"]
    return names


def lssi_name(feature, harmonic_map):
    if feature in harmonic_map:
        return harmonic_map[feature]
    return "*".join(feature.split(" "))


# --------------------------------------------------------------------------------------
# PySINDy (runs in the venv).

def read_csv(path):
    import numpy as np

    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    cols = {name: data[:, i] for i, name in enumerate(header)}
    return cols["t"], cols["x"], cols.get("v")


def forcing(t, omega, harmonics):
    import numpy as np

    cols = []
    for k in range(1, harmonics + 1):
        cols += [np.sin(k * omega * t), np.cos(k * omega * t)]
    return np.column_stack(cols) if cols else None


def make_model(window, threshold, poly_order, harmonics):
    import pysindy as ps

    poly = ps.PolynomialLibrary(degree=poly_order, include_bias=True)
    if harmonics > 0:
        library = ps.GeneralizedLibrary(
            [poly, ps.IdentityLibrary()],
            inputs_per_library=[[0, 1], list(range(2, 2 + 2 * harmonics))],
        )
    else:
        library = poly
    return ps.SINDy(
        feature_library=library,
        optimizer=ps.STLSQ(threshold=threshold, alpha=0.05, normalize_columns=True),
        differentiation_method=ps.SmoothedFiniteDifference(
            smoother_kws={"window_length": window, "polyorder": 3}
        ),
    )


def states(x, v, t, window):
    """(x, v): v measured, or the smoothed derivative of x."""
    import numpy as np
    import pysindy as ps

    if v is None:
        v = ps.SmoothedFiniteDifference(
            smoother_kws={"window_length": window, "polyorder": 3}
        )._differentiate(x, t)
        v = np.asarray(v).reshape(-1)
    return np.column_stack([x, v])


def fit_once(x, v, t, omega, harmonics, poly_order, window, threshold, blocks=None):
    dt = float(t[1] - t[0])
    X = states(x, v, t, window)
    U = forcing(t, omega, harmonics)
    model = make_model(window, threshold, poly_order, harmonics)
    names = ["x", "v"] + [f"h{j}" for j in range(2 * harmonics)]
    if blocks is None:
        model.fit(X, t=dt, u=U, feature_names=names)
    else:
        model.fit(
            [X[b] for b in blocks],
            t=[dt] * len(blocks),
            u=[U[b] for b in blocks] if U is not None else None,
            feature_names=names,
        )
    return model, X, U


def report(model, omega, harmonics):
    hm = {f"h{j}": n for j, n in enumerate(harmonic_names(omega, harmonics))}
    coefs = model.coefficients()[1]
    return {
        lssi_name(f, hm): float(c)
        for f, c in zip(model.get_feature_names(), coefs)
        if c != 0.0
    }


def cv_target(x, v, t):
    import numpy as np
    from scipy.signal import savgol_filter

    dt = float(t[1] - t[0])
    if v is not None:
        return np.gradient(v, dt)
    return savgol_filter(x, 51, 3, deriv=2, delta=dt)


def fit_cv(x, v, t, omega, harmonics, poly_order):
    import warnings

    import numpy as np

    # A threshold that removes every term is a candidate like any other: no warning.
    warnings.filterwarnings("ignore", message="Sparsity parameter is too big")
    n = len(t)
    edges = np.linspace(0, n, FOLDS + 1).astype(int)
    target = cv_target(x, v, t)
    scale = float(np.linalg.norm(target))
    margin = max(WINDOWS)
    results = []
    for window in WINDOWS:
        for tau in TAUS:
            threshold = tau * scale
            errors = []
            for k in range(FOLDS):
                lo, hi = edges[k], edges[k + 1]
                train = [b for b in (slice(0, lo), slice(hi, n)) if b.stop - b.start > 4 * margin]
                model, X, U = fit_once(
                    x, v, t, omega, harmonics, poly_order, window, threshold, blocks=train
                )
                held = slice(lo + margin, hi - margin)
                pred = model.predict(X[held], u=U[held] if U is not None else None)[:, 1]
                errors.append(float(np.mean((pred - target[held]) ** 2)))
            results.append((float(np.mean(errors)), window, tau))
    best = min(results)
    model, _, _ = fit_once(x, v, t, omega, harmonics, poly_order, best[1], best[2] * scale)
    return model, {"window": best[1], "tau": best[2], "cv_error": best[0]}


def fit_command(args):
    t, x, v = read_csv(args.file)
    if args.recipe == "default":
        model, _, _ = fit_once(x, v, t, args.omega, args.harmonics, args.poly_order, 11, 0.1)
        chosen = {"window": 11, "threshold": 0.1}
    else:
        model, chosen = fit_cv(x, v, t, args.omega, args.harmonics, args.poly_order)
    print(json.dumps({"terms": report(model, args.omega, args.harmonics), "chosen": chosen}))


def throughput_command(args):
    t, x, v = read_csv(args.file)
    dt = float(t[1] - t[0])
    X = states(x, v, t, 11)
    U = forcing(t, args.omega, args.harmonics)
    model = make_model(11, 0.1, args.poly_order, args.harmonics)
    start = time.perf_counter()
    model.fit(X, t=dt, u=U, feature_names=["x", "v"] + [f"h{j}" for j in range(2 * args.harmonics)])
    elapsed = time.perf_counter() - start
    print(json.dumps({"samples": len(t), "seconds": elapsed}))


# --------------------------------------------------------------------------------------
# The comparison (any Python 3).

def run(cmd):
    """(wall seconds, CPU seconds of the child, stdout)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, out.stdout


def timed(cmd, repeats):
    """Median wall and CPU seconds over `repeats` runs, and the last stdout."""
    walls, cpus, out = [], [], ""
    for _ in range(repeats):
        wall, cpu, out = run(cmd)
        walls.append(wall)
        cpus.append(cpu)
    return statistics.median(walls), statistics.median(cpus), out


def score(terms, truth):
    errors = [
        abs((terms[name] - c) / c) * 100.0 if name in terms else 100.0
        for name, c in truth.items()
    ]
    spurious = sum(1 for name in terms if name not in truth)
    return sum(errors) / len(errors), max(errors), spurious


def lssi_binary():
    if os.environ.get("LSSI"):
        return os.environ["LSSI"]
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    return os.path.join(target, "release", "lssi")


def cases(lssi):
    os.makedirs(CASES, exist_ok=True)
    out = []
    for delta in ["0.001", "0.01", "0.1"]:
        path = os.path.join(CASES, f"eq17-delta{delta}.csv")
        if not os.path.exists(path):
            subprocess.run(
                [lssi, "gen", "paper", "--delta", delta, "--seed", "1", path],
                check=True,
                capture_output=True,
            )
        out.append((f"eq. 17, δ = {delta}", path, 1.0, 3, 3, EQ17_TRUTH))
    notes = []
    eveh = sorted(glob.glob(os.path.join(ROOT, "data", "eveh-*.csv")))
    if not eveh:
        notes.append("eveh recordings: data/eveh-*.csv not found, skipped.")
    for path in eveh:
        truth_path = path[:-4] + ".json"
        truth, omega, order = None, None, 3
        if os.path.exists(truth_path):
            with open(truth_path) as f:
                doc = json.load(f)
            truth = {t["term"]: t["coef"] for t in doc.get("terms", []) if t["term"].startswith(("x", "v", "1"))}
            forcing_terms = [t for t in doc.get("terms", []) if t["term"].startswith(("sin", "cos"))]
            omega = doc.get("omega")
            truth.update({t["term"]: t["coef"] for t in forcing_terms})
            for name in truth:
                order = max(order, sum(int(p.split("^")[1]) if "^" in p else 1 for p in name.split("*") if p in ("x", "v") or p.startswith(("x^", "v^"))))
        if omega is None:
            notes.append(f"{os.path.basename(path)}: no Ω in a truth file, skipped.")
            continue
        out.append((os.path.basename(path)[:-4], path, float(omega), 1, order, truth))
    return out, notes


def lssi_throughput(lssi):
    _, _, out = run([lssi, "bench", "accuracy", "--quick"])
    for line in out.splitlines():
        if line.startswith("throughput"):
            value = line.split("streaming identifier")[1].split("M samples/s")[0]
            return float(value) * 1e6
    raise RuntimeError("lssi bench accuracy printed no throughput line")


def compare(args):
    lssi = lssi_binary()
    python = sys.executable
    me = os.path.abspath(__file__)
    rows = []
    all_cases, notes = cases(lssi)
    for label, path, omega, harmonics, order, truth in all_cases:
        lib = ["--omega", str(omega), "--harmonics", str(harmonics), "--poly-order", str(order)]
        results = {}
        for name, cmd in [
            ("PySINDy default", [python, me, "_fit", "default", path] + lib),
            ("PySINDy CV", [python, me, "_fit", "cv", path] + lib),
            ("lssi f32", [lssi, "identify", path, "--json", "--no-refine"] + lib),
            ("lssi f64", [lssi, "identify", path, "--json", "--f64", "--no-refine"] + lib),
        ]:
            repeats = 1 if name == "PySINDy CV" else args.repeats
            wall, cpu, out = timed(cmd, repeats)
            doc = json.loads(out)
            terms = doc["terms"]
            if isinstance(terms, list):
                terms = {t["term"]: t["coef"] for t in terms}
            results[name] = (terms, wall, cpu, doc.get("chosen"))
            print(f"  {label}: {name} {wall:.2f} s wall, {cpu:.2f} s CPU", file=sys.stderr)
        rows.append((label, truth, results))

    print("| case | method | mean error % | max error % | spurious | wall time s | CPU time s |")
    print("|---|---|---|---|---|---|---|")
    for label, truth, results in rows:
        for name, (terms, wall, cpu, chosen) in results.items():
            if truth:
                mean, worst, spurious = score(terms, truth)
                cells = f"{mean:.3f} | {worst:.3f} | {spurious}"
            else:
                cells = "— | — | —"
            extra = ""
            if chosen and name == "PySINDy CV":
                extra = f" (window {chosen['window']}, τ {chosen['tau']:g})"
            print(f"| {label} | {name}{extra} | {cells} | {wall:.3f} | {cpu:.3f} |")

    big = os.path.join(CASES, "eq17-1e6.csv")
    if not os.path.exists(big):
        subprocess.run(
            [lssi, "gen", "paper", "--delta", "0.01", "--t-end", "999.999", "--seed", "1", big],
            check=True,
            capture_output=True,
        )
    _, _, out = run([python, me, "_throughput", big, "--omega", "1", "--harmonics", "3", "--poly-order", "3"])
    py = json.loads(out)
    py_rate = py["samples"] / py["seconds"]
    rs_rate = lssi_throughput(lssi)
    wall_big, _, _ = timed([lssi, "identify", big, "--json", "--no-refine", "--omega", "1", "--harmonics", "3", "--poly-order", "3"], 1)
    print()
    print(
        f"Fit throughput on 10^6 samples of eq. 17 (δ = 0.01), without start-up, one core: "
        f"PySINDy default fit {py_rate / 1e6:.2f} M samples/s; lssi f32 streaming identifier "
        f"{rs_rate / 1e6:.2f} M samples/s ({rs_rate / py_rate:.1f}×). "
        f"`lssi identify` on that file, start-up and window choice included: {wall_big:.2f} s."
    )
    for n in notes:
        print(f"\nNote: {n}")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command")
    f = sub.add_parser("_fit", help="(internal) one PySINDy fit, JSON out")
    f.add_argument("recipe", choices=["default", "cv"])
    f.add_argument("file")
    g = sub.add_parser("_throughput", help="(internal) time one PySINDy fit")
    g.add_argument("file")
    for q in (f, g):
        q.add_argument("--omega", type=float, required=True)
        q.add_argument("--harmonics", type=int, required=True)
        q.add_argument("--poly-order", type=int, required=True)
    p.add_argument("--repeats", type=int, default=3, help="runs per wall time (median)")
    args = p.parse_args()
    if args.command == "_fit":
        fit_command(args)
    elif args.command == "_throughput":
        throughput_command(args)
    else:
        compare(args)


if __name__ == "__main__":
    main()
