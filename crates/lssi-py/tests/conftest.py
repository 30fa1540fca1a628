import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
LSSI = ROOT / "target" / "release" / "lssi"
DATA = sorted((ROOT / "data").glob("*.csv"))


@pytest.fixture(scope="session")
def cli():
    """The `lssi` command (scripts/setup.sh builds it, with the Rust tests' features)."""
    if not LSSI.exists():
        subprocess.run(["cargo", "test", "--workspace", "--release", "--locked", "--no-run"],
                       cwd=ROOT, check=True)

    def run(*args):
        out = subprocess.run([str(LSSI), *map(str, args)], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        return out.stdout

    return run


def duffing(n=20000, dt=0.002, seed=0, noise=0.0):
    """x'' = -x - 0.1 x' - 0.5 x^3 + 0.8 cos(1.2 t), RK4 on a fine grid, sampled every dt."""
    rng = np.random.default_rng(seed)
    sub = 4
    h = dt / sub
    f = lambda t, x, v: -x - 0.1 * v - 0.5 * x**3 + 0.8 * np.cos(1.2 * t)
    x, v, t = 0.5 + 0.1 * rng.random(), 0.0, 0.0
    xs = np.empty(n)
    for i in range(n):
        xs[i] = x
        for _ in range(sub):
            k1x, k1v = v, f(t, x, v)
            k2x, k2v = v + h / 2 * k1v, f(t + h / 2, x + h / 2 * k1x, v + h / 2 * k1v)
            k3x, k3v = v + h / 2 * k2v, f(t + h / 2, x + h / 2 * k2x, v + h / 2 * k2v)
            k4x, k4v = v + h * k3v, f(t + h, x + h * k3x, v + h * k3v)
            x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            t += h
    ts = np.arange(n) * dt
    return ts, xs + noise * np.std(xs) * rng.standard_normal(n)


DUFFING_TRUTH = {"x": -1.0, "v": -0.1, "x^3": -0.5, "cos(1.2t)": 0.8}
