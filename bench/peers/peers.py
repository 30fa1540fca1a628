#!/usr/bin/env python3
"""PySINDy and the lssi Python package side by side, in one process, on the same recordings.

Cases (all generated, seed 1):
  eq. 17 (the paper's test ODE, x and x' observed, eq. 16 noise) at δ = 0.001, 0.01, 0.1
  (`lssi gen paper --delta D`); the harvester of eq. 19 from x alone with 1 % Gaussian sensor
  noise (`lssi gen eveh --observe x --delta 0.01`); a Van der Pol oscillator
  x'' = -x + μ(1 - x²)x' with μ = 1, 0.5 % noise, from x alone (made here by RK4).
Both get the same library: constant and monomials of (x, v) to order 3, plus sin/cos(kΩt)
for the forced cases with Ω given (eq. 17: k = 1..3; harvester: k = 1; Van der Pol: none).

PySINDy 2.0.0: SmoothedFiniteDifference + STLSQ(normalize_columns=True), given its BEST
setting from a small grid -- smoothing window {11, 51, 201} × threshold τ·||x''|| with τ in
{1e-3, 1e-2, 3e-2, 1e-1} -- picked with the true coefficients (an oracle no user has: the
most favourable reading of PySINDy). x' for PySINDy is the measured v when there is one,
else its own smoothed derivative of x.
lssi: `lssi.Model(...).fit(x, t=t, v=v)` with no tuning at all, f64 (and f32, as on a device).

Scores: per true term |error|/|true| in %, 100 for a missed term; mean over the true terms;
spurious = active terms not in the truth. Wall time: the fit call alone, median of 3
(PySINDy: the fit at its best setting, not the grid search).
"""

import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "pysindy"))
import compare  # noqa: E402  (bench/pysindy: PySINDy's library, names as lssi writes them)

import lssi  # noqa: E402

CASES = os.path.join(HERE, ".cases")
EQ17_TRUTH = compare.EQ17_TRUTH


def gen(*args):
    os.makedirs(CASES, exist_ok=True)
    path = os.path.join(CASES, "-".join(a.lstrip("-") for a in args) + ".csv")
    if not os.path.exists(path):
        subprocess.run([os.environ["LSSI"], "gen", *args, "--seed", "1", path], check=True,
                       capture_output=True)
    return path


def truth_of(path):
    with open(path[:-4] + ".json") as f:
        doc = json.load(f)
    return {t["term"]: t["coef"] for t in doc["terms"]}, doc.get("omega")


def van_der_pol(mu=1.0, dt=0.01, n=20000, noise=0.005, seed=1):
    f = lambda x, v: -x + mu * (1 - x * x) * v
    x, v, h = 2.0, 0.0, dt / 4
    xs = np.empty(n)
    for i in range(n):
        xs[i] = x
        for _ in range(4):
            k1 = (v, f(x, v))
            k2 = (v + h / 2 * k1[1], f(x + h / 2 * k1[0], v + h / 2 * k1[1]))
            k3 = (v + h / 2 * k2[1], f(x + h / 2 * k2[0], v + h / 2 * k2[1]))
            k4 = (v + h * k3[1], f(x + h * k3[0], v + h * k3[1]))
            x += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            v += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    return t, xs + noise * np.std(xs) * rng.standard_normal(n), {"x": -1.0, "v": mu, "x^2*v": -mu}


def cases():
    out = []
    for delta in ["0.001", "0.01", "0.1"]:
        path = gen("paper", "--delta", delta)
        t, x, v = compare.read_csv(path)
        out.append((f"eq. 17, δ = {delta}, x and x'", t, x, v, 1.0, 3, EQ17_TRUTH))
    path = gen("eveh", "--observe", "x", "--delta", "0.01")
    t, x, v = compare.read_csv(path)
    truth, omega = truth_of(path)
    out.append(("harvester (eq. 19), 1 % noise, x only", t, x, None, float(omega), 1, truth))
    t, x, truth = van_der_pol()
    out.append(("Van der Pol μ = 1, 0.5 % noise, x only", t, x, None, None, 0, truth))
    return out


def timed(f, repeats=3):
    walls, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = f()
        walls.append(time.perf_counter() - start)
    return statistics.median(walls), result


def pysindy_best(t, x, v, omega, harmonics, truth):
    import warnings

    warnings.filterwarnings("ignore")
    target = compare.cv_target(x, v, t)
    scale = float(np.linalg.norm(target))
    best = None
    for window in compare.WINDOWS:
        for tau in compare.TAUS:
            model, _, _ = compare.fit_once(x, v, t, omega or 1.0, harmonics, 3, window, tau * scale)
            terms = compare.report(model, omega or 1.0, harmonics)
            s = compare.score(terms, truth)
            if best is None or s[0] < best[0][0]:
                best = (s, window, tau)
    (mean, _, spurious), window, tau = best
    wall, _ = timed(lambda: compare.fit_once(x, v, t, omega or 1.0, harmonics, 3, window, tau * scale))
    return mean, spurious, wall, f"window {window}, τ {tau:g}"


def lssi_fit(t, x, v, omega, harmonics, truth, f32):
    options = dict(poly_order=3, harmonics=harmonics, omega=omega, f32=f32)
    wall, model = timed(lambda: lssi.Model(**options).fit(x, t=t, v=v))
    terms = {k: c for k, c in model.coefficients().items() if c != 0.0}
    mean, _, spurious = compare.score(terms, truth)
    return mean, spurious, wall


def main():
    rows = []
    for label, t, x, v, omega, harmonics, truth in cases():
        p = pysindy_best(t, x, v, omega, harmonics, truth)
        a = lssi_fit(t, x, v, omega, harmonics, truth, f32=False)
        b = lssi_fit(t, x, v, omega, harmonics, truth, f32=True)
        rows.append((label, len(t), p, a, b))
        print(f"done: {label}", file=sys.stderr)
    import pysindy

    print(f"PySINDy {pysindy.__version__} (best of its grid, picked with the truth) against "
          f"the lssi package (no tuning); mean coefficient error %, spurious terms, fit wall time.\n")
    print("| case | samples | PySINDy best of grid | its setting | lssi f64 | lssi f32 | PySINDy time | lssi f64 time |")
    print("|---|---:|---|---|---|---|---:|---:|")
    for label, n, p, a, b in rows:
        print(f"| {label} | {n} | {p[0]:.3g} %, {p[1]} | {p[3]} | {a[0]:.3g} %, {a[1]} | "
              f"{b[0]:.3g} %, {b[1]} | {p[2] * 1e3:.0f} ms | {a[2] * 1e3:.0f} ms |")


if __name__ == "__main__":
    main()
