"""A harvester's system fitted from arrays: `Model().fit(x, t=t, u=u, V=V)` gives the system
`lssi identify` finds in a CSV file with the same columns (issue 26 item 4), with its
equations, coefficients, standard errors, simulation, score per state and pickling; and
every bad argument is an error naming the Python argument (issue 25 item 4)."""
import json
import pickle
import subprocess

import numpy as np
import pandas as pd
import pytest

import lssi
from lssi import _lssi
from conftest import LSSI  # noqa: F401  (the cli fixture builds it when missing)


def columns(path, max_rows=None):
    header = path.read_text().splitlines()[0].split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, max_rows=max_rows)
    return {name: np.ascontiguousarray(data[:, k]) for k, name in enumerate(header)}


def write_csv(path, col):
    """The columns as a CSV file, every value written so that it reads back exactly."""
    names = list(col)
    with open(path, "w") as f:
        f.write(",".join(names) + "\n")
        for row in zip(*(col[name] for name in names)):
            f.write(",".join(repr(float(q)) for q in row) + "\n")


@pytest.fixture(scope="module")
def piezo(tmp_path_factory, cli):
    """A monostable piezo harvester, x, V and the base acceleration u recorded (clean: at
    1 % noise the command's x'' equation loses its V term for a cos(Ωt) on every seed tried,
    which is the identifier's to fix, not the package's)."""
    out = tmp_path_factory.mktemp("piezo-fit") / "piezo.csv"
    cli("gen", "piezo", "--input", out)
    return out, columns(out)


@pytest.fixture(scope="module")
def fitted(piezo):
    _, col = piezo
    return lssi.Model().fit(col["x"], t=col["t"], u=col["u"], V=col["V"])


# -- the same system as from the file -------------------------------------------------------
# Every recording in f64; f32 on two of them (CI's time: each case identifies three times, and
# the electromagnetic bistable record of v and i in f32 took 34 s, the longest Python test;
# the bistable records are 8-10 s, each as the command decides it at 20 s: the electromagnetic
# one withheld, the piezo one identified; its refinement took 45 s a run at 20 s).
@pytest.mark.parametrize(
    "kind, wells, observe, extra, f32",
    [
        ("piezo", "monostable", "x", [], False),
        ("piezo", "monostable", "x", [], True),
        ("piezo", "bistable", "x", ["--delta", "0.01", "--t-end", "10"], False),
        ("piezo", "bistable", "x", ["--delta", "0.01", "--t-end", "10"], True),
        ("piezo", "monostable", "v", [], False),
        ("piezo", "bistable", "xv", ["--delta", "0.05", "--seed", "3"], False),
        ("electromagnetic", "monostable", "x", ["--coil", "inductive"], False),
        ("electromagnetic", "monostable", "x", ["--coil", "negligible", "--delta", "0.01"], False),
        ("electromagnetic", "monostable", "x", ["--electrical", "i"], False),
        ("electromagnetic", "bistable", "v", ["--electrical", "i", "--delta", "0.01", "--seed", "5", "--t-end", "8"], False),
    ],
)
def test_fit_on_arrays_equals_identify_on_the_file(cli, tmp_path, kind, wells, observe, extra, f32):
    """Arrays read from a generated recording, and the same arrays written back as a CSV
    file: Model().fit gives the JSON `lssi.identify` and `lssi identify --json` give."""
    path = tmp_path / f"{kind}.csv"
    if "--t-end" not in extra:
        extra = [*extra, "--t-end", "8"]  # of 20 s by default: the equality is the claim
    cli("gen", kind, "--input", "--wells", wells, "--observe", observe, *extra, path)
    col = columns(path)
    electrical = {name: col[name] for name in ("V", "i") if name in col}
    assert electrical, col.keys()
    again = tmp_path / "again.csv"
    write_csv(again, col)
    command = subprocess.run(
        [str(LSSI), "identify", str(again), "--json", "--f32" if f32 else "--f64"],
        capture_output=True, text=True,
    )
    if command.returncode == 3:
        # The command's gate withholds this model (a coupling the record cannot resolve, or
        # one its selection dropped): the package raises with the command's sentence.
        reason = command.stderr.strip().split(": ", 2)[-1]
        with pytest.raises(ValueError, match="no deterministic dynamics found in array") as e:
            lssi.Model(f32=f32).fit(col.get("x"), t=col["t"], v=col.get("v"), u=col["u"], **electrical)
        assert str(e.value).split(": ", 1)[-1] == reason
        with pytest.raises(ValueError, match="no deterministic dynamics found"):
            lssi.identify(path, f32=f32)
        return
    assert command.returncode == 0, command.stderr
    m = lssi.Model(f32=f32).fit(col.get("x"), t=col["t"], v=col.get("v"), u=col["u"], **electrical)
    assert m.is_system()
    assert m.to_json() == lssi.identify(path, f32=f32).to_json()
    # Written back from the arrays: the command reads the same numbers.
    expected = command.stdout.strip()
    assert m.to_json() == expected
    # A DataFrame with the same columns gives the same system (once: a fourth identification).
    if kind == "piezo" and wells == "monostable" and observe == "x" and not f32:
        assert lssi.Model(f32=f32).fit(pd.DataFrame(col)).to_json() == expected
    if "i" in col:
        assert list(m.equations()) == ["x''", "i'"]
        assert m.states()[2:] == ["i"]


def test_both_electrical_channels_as_the_command(cli, tmp_path):
    """A recording with the load voltage V and the current i (V / R_L, 1 % noise on i): V and
    i are one signal (V = R_L i), so the command's gate withholds the three equations as
    collinear, and the package raises with the command's sentence."""
    path = tmp_path / "em.csv"
    cli("gen", "electromagnetic", "--input", "--wells", "bistable", "--delta", "0.01", "--seed", "31", "--t-end", "8", path)
    col = columns(path)
    rng = np.random.default_rng(11)
    col["i"] = col["V"] / 1000.0 * (1.0 + 0.01 * rng.standard_normal(col["V"].shape))
    both = tmp_path / "both.csv"
    write_csv(both, col)
    command = subprocess.run([str(LSSI), "identify", str(both), "--json", "--f64"], capture_output=True, text=True)
    assert command.returncode == 3, command.stderr
    assert "are collinear on this recording" in command.stderr
    reason = command.stderr.strip().split(": ", 2)[-1]
    with pytest.raises(ValueError, match="no deterministic dynamics found in array") as e:
        lssi.Model().fit(col["x"], t=col["t"], u=col["u"], V=col["V"], i=col["i"])
    assert str(e.value).split(": ", 1)[-1] == reason


def test_load_ohms_and_coupling_order_as_the_command(cli, piezo, tmp_path):
    path, col = piezo
    truth = json.loads(path.with_suffix(".json").read_text())
    ohms = truth.get("load_ohms") or 1.0e5
    # The streaming model (refinement is the same with or without a load: CI's time).
    m = lssi.Model(coupling_order=2, refine=False).fit(col["x"], t=col["t"], u=col["u"], V=col["V"], load_ohms=ohms)
    expected = cli("identify", path, "--json", "--f64", "--no-refine", "--load-ohms", ohms, "--coupling-order", 2)
    assert m.to_json() == expected.strip()
    h = m.harvester()
    assert h["load_ohms"] == ohms
    assert 0.0 < h["coupling_k2"] < 1.0
    assert h["power_measured_w"] > 0.0
    assert lssi.identify(path, load_ohms=ohms, coupling_order=2, refine=False).to_json() == m.to_json()
    assert lssi.Model(refine=False).fit(col["x"], t=col["t"], u=col["u"], V=col["V"]).harvester() is None


# -- what a fitted system gives -------------------------------------------------------------
def test_equations_coefficients_and_print(fitted, piezo, capsys):
    path, _ = piezo
    truth = json.loads(path.with_suffix(".json").read_text())
    m = fitted
    assert m.states() == ["x", "v", "V"]
    equations = m.equations()
    assert list(equations) == ["x''", "V'"]
    # The truth within 1 %, no spurious term.
    for equation in truth["equations"]:
        found = equations[equation["target"]]
        true = {term["term"]: term["coef"] for term in equation["terms"]}
        assert sorted(found) == sorted(true), equation["target"]
        for name, coef in true.items():
            assert found[name] == pytest.approx(coef, rel=0.01), (equation["target"], name)
    # coefficients(): every term of the shared library in each equation, 0 where inactive.
    names = m.feature_names()
    assert "V" in names and "x" in names and "u" in names
    coefficients = m.coefficients()
    assert list(coefficients) == ["x''", "V'"]
    for target, dense in coefficients.items():
        assert list(dense) == names
        for name, coef in dense.items():
            assert coef == equations[target].get(name, 0.0)
    if m.report()["model"] == "refined":
        with pytest.raises(ValueError, match="a refined system keeps no streaming model"):
            m.streaming_coefficients()
    else:
        assert m.streaming_coefficients() == coefficients
    se = m.standard_errors()
    assert list(se) == ["x''", "V'"]
    for target in se:
        assert sorted(se[target]) == sorted(equations[target])
        assert all(s > 0 for s in se[target].values()), (target, se[target])
    m.print()
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("x''") and lines[1].startswith("V'")
    assert m.equation().splitlines() == lines[:2]
    assert "V'" in repr(m)


def test_simulate_and_score_per_state(fitted, piezo):
    _, col = piezo
    m = fitted
    n = 6000
    t, u = col["t"][:n], col["u"][:n]
    x0 = {"x": col["x"][0], "v": (col["x"][1] - col["x"][0]) / (t[1] - t[0]), "V": col["V"][0]}
    out = m.simulate(x0, t, u=u)
    assert list(out) == ["x", "v", "V"]
    assert all(values.shape == t.shape and np.all(np.isfinite(values)) for values in out.values())
    score = m.score(col["x"][:n], t, u=u, V=col["V"][:n])
    assert list(score) == ["x", "V"]
    # Both states followed from the excitation alone (1 − NRMSE²).
    assert score["x"] > 0.9 and score["V"] > 0.9, score
    # A velocity given is scored too.
    v = np.gradient(col["x"][:n], t)
    assert sorted(m.score(col["x"][:n], t, u=u, V=col["V"][:n], v=v)) == ["V", "v", "x"]
    # A recording of something else scores worse.
    other = m.score(col["x"][:n], t, u=-u, V=col["V"][:n])
    assert other["x"] < score["x"] and other["V"] < score["V"]


def test_pickling_a_system_fitted_from_arrays(fitted, piezo):
    _, col = piezo
    back = pickle.loads(pickle.dumps(fitted))
    assert back.is_system()
    assert back.to_json() == fitted.to_json()
    assert back.coefficients() == fitted.coefficients()
    ohms = lssi.Model(refine=False).fit(col["x"], t=col["t"], u=col["u"], V=col["V"], load_ohms=2.0e5)
    assert pickle.loads(pickle.dumps(ohms)).harvester() == ohms.harvester()


def test_pickling_a_system_identified_from_a_file(piezo):
    path, _ = piezo
    m = lssi.identify(path, load_ohms=1.0e5, refine=False)
    back = pickle.loads(pickle.dumps(m))
    assert back.to_json() == m.to_json()
    assert back.harvester()["load_ohms"] == 1.0e5


def test_datetime64_t_for_a_system(fitted, piezo):
    _, col = piezo
    start = np.datetime64("2026-11-26T03:00:00", "ns")
    stamps = start + (col["t"] * 1e9).round().astype("timedelta64[ns]")
    m = lssi.Model().fit(col["x"], t=stamps, u=col["u"], V=col["V"])
    assert m.is_system()
    for target, terms in m.equations().items():
        for name, coef in terms.items():
            assert coef == pytest.approx(fitted.equations()[target][name], rel=1e-6), (target, name)
    # Simulated and scored on dates and times as well, from the fit's origin.
    n = 2000
    out = m.simulate({"x": col["x"][0], "v": 0.0, "V": col["V"][0]}, stamps[:n], u=col["u"][:n])
    assert out["V"].shape == (n,)
    score = m.score(col["x"][:n], stamps[:n], u=col["u"][:n], V=col["V"][:n])
    assert score["V"] > 0.5


# -- errors naming the Python arguments -----------------------------------------------------
def test_bad_electrical_columns_are_named(piezo):
    _, col = piezo
    x, t, u, V = col["x"], col["t"], col["u"], col["V"]
    with pytest.raises(ValueError, match="V has 99 samples but x has"):
        lssi.Model().fit(x, t=t, u=u, V=V[:99])
    with pytest.raises(ValueError, match=r"i has 10 samples but x has"):
        lssi.Model().fit(x, t=t, u=u, V=V, i=V[:10])
    bad = V.copy()
    bad[123] = np.nan
    with pytest.raises(ValueError, match="V has 1 non-finite value.*index 123"):
        lssi.Model().fit(x, t=t, u=u, V=bad)
    with pytest.raises(ValueError, match="V must be a 1-D array"):
        lssi.Model().fit(x, t=t, u=u, V=np.stack([V, V]))
    with pytest.raises(ValueError, match="V must be a 1-D array of numbers"):
        lssi.Model().fit(x, t=t, u=u, V=["a"] * len(x))
    with pytest.raises(ValueError, match="V holds dates or times"):
        lssi.Model().fit(x, t=t, u=u, V=np.array(["2026-01-01"] * len(x), dtype="datetime64[ns]"))
    with pytest.raises(ValueError, match="give the displacement x, or the velocity v"):
        lssi.Model().fit(None, t=t, u=u, V=V)
    with pytest.raises(ValueError, match="give the displacement x"):
        lssi.Model().fit(None, t=t, v=x)
    with pytest.raises(ValueError, match="t has 5 samples but x has"):
        lssi.Model().fit(x, t=t[:5], u=u, V=V)
    with pytest.raises(ValueError, match="t must increase"):
        lssi.Model().fit(x, t=t[::-1].copy(), u=u, V=V)
    with pytest.raises(ValueError, match="x has 10 samples; at least 64"):
        lssi.Model().fit(x[:10], t=t[:10], u=u[:10], V=V[:10])


def test_bad_options_for_systems_are_named(piezo):
    _, col = piezo
    x, t, u, V = col["x"], col["t"], col["u"], col["V"]
    with pytest.raises(TypeError, match="load_ohms must be a positive resistance"):
        lssi.Model().fit(x, t=t, u=u, V=V, load_ohms="1e5")
    with pytest.raises(ValueError, match="load_ohms must be a positive resistance"):
        lssi.Model().fit(x, t=t, u=u, V=V, load_ohms=-3.0)
    with pytest.raises(TypeError, match="load_ohms must be"):
        lssi.Model().fit(x, t=t, u=u, V=V, load_ohms=True)
    with pytest.raises(ValueError, match="load_ohms applies to a system"):
        lssi.Model().fit(x, t=t, u=u, load_ohms=1e5)
    with pytest.raises(TypeError, match="coupling_order must be an integer from 1 to 3"):
        lssi.Model(coupling_order=2.0)
    with pytest.raises(ValueError, match="coupling_order must be an integer from 1 to 3"):
        lssi.Model(coupling_order=4)
    with pytest.raises(ValueError, match="coupling_order=2 applies to a system"):
        lssi.Model(coupling_order=2).fit(x, t=t, u=u)
    for message in (lambda: lssi.Model(omega="21"), lambda: lssi.Model(poly_order=True)):
        with pytest.raises(TypeError):
            message()


def test_single_equation_file_refuses_system_options(cli, tmp_path):
    path = tmp_path / "eveh.csv"
    cli("gen", "eveh", "--t-end", "4", path)
    with pytest.raises(ValueError, match="load_ohms applies to a recording with an electrical column"):
        lssi.identify(path, load_ohms=1e5)
    with pytest.raises(ValueError, match="coupling_order applies to a recording"):
        lssi.identify(path, coupling_order=2)


def test_electrical_channels_a_model_lacks_are_named(fitted, piezo):
    _, col = piezo
    n = 500
    x, t, u, V = col["x"][:n], col["t"][:n], col["u"][:n], col["V"][:n]
    # A single-equation model (fitted without V) given V. The streaming model: x'' alone cannot
    # describe a harvester whose V acts back on x, and refined it leaves a term its standard
    # error does not resolve (withheld); the channel errors below are what this test is about.
    single = lssi.Model(refine=False).fit(col["x"], t=col["t"], u=col["u"])
    assert not single.is_system()
    with pytest.raises(ValueError, match="V: this model was fitted without an electrical channel"):
        single.score(x, t, u=u, V=V)
    with pytest.raises(ValueError, match=r"x0 names \['V'\].*fitted without V"):
        single.simulate({"x": 0.0, "v": 0.0, "V": 0.0}, t, u=u)
    out = single.simulate({"x": x[0], "v": 0.0}, t, u=u)
    assert list(out) == ["x", "v"] and out["x"].shape == (n,)
    # The system fitted with V given i, or scored without V.
    with pytest.raises(ValueError, match="i: this system's states are \\['x', 'v', 'V'\\]; it was fitted without i"):
        fitted.score(x, t, u=u, V=V, i=V)
    with pytest.raises(ValueError, match="V: the system has the electrical state V, so score needs"):
        fitted.score(x, t, u=u)
    with pytest.raises(ValueError, match="u: the model has an excitation term u, so score needs"):
        fitted.score(x, t, V=V)
    with pytest.raises(ValueError, match="u: the model has an excitation term u, so simulate needs"):
        fitted.simulate({"x": 0.0, "v": 0.0, "V": 0.0}, t)
    with pytest.raises(ValueError, match="V has 499 samples but x has 500"):
        fitted.score(x, t, u=u, V=V[:-1])
    with pytest.raises(ValueError, match=r"x0 has no initial value for the state\(s\) \['V'\]"):
        fitted.simulate({"x": 0.0, "v": 0.0}, t, u=u)
    with pytest.raises(TypeError, match=r"x0\['V'\] must be a number"):
        fitted.simulate({"x": 0.0, "v": 0.0, "V": "high"}, t, u=u)
    with pytest.raises(ValueError, match="stream\\(\\) is for a single equation"):
        fitted.stream()
    # A Stream takes no electrical channel, as an argument or a DataFrame's column.
    stream = lssi.Stream(calibrate=64)
    with pytest.raises(ValueError, match="V: a Stream identifies the single equation"):
        stream.push(x, t=t, u=u, V=V)
    with pytest.raises(ValueError, match="i: a Stream identifies the single equation"):
        stream.push(pd.DataFrame({"t": t, "x": x, "u": u, "i": V}))
    with pytest.raises(ValueError, match="like: the model is a system"):
        lssi.Stream(like=fitted)


def test_no_panic_reaches_python_for_odd_system_inputs(piezo):
    """Inputs at the edges (constant channels, a tiny V, a V of zeros, a single-valued u):
    a model or a ValueError, never a PanicException or another exception type."""
    _, col = piezo
    n = 3000
    x, t, u, V = col["x"][:n], col["t"][:n], col["u"][:n], col["V"][:n]
    cases = {
        "V zero": dict(V=np.zeros(n)),
        "V constant": dict(V=np.full(n, 3.0)),
        "x constant": dict(x=np.full(n, 1e-3)),
        "V tiny": dict(V=V * 1e-300),
        "V huge": dict(V=V * 1e300),
        "u zero": dict(u=np.zeros(n)),
        "both V and i": dict(i=V.copy()),
    }
    for name, change in cases.items():
        args = {**dict(x=x, t=t, u=u, V=V), **change}
        try:
            m = lssi.Model().fit(args.pop("x"), **args)
        except BaseException as e:  # a PanicException is a BaseException, not an Exception
            assert isinstance(e, ValueError), f"{name}: {type(e).__module__}.{type(e).__name__}: {e}"
            continue
        assert m.is_system(), name
        json.loads(m.to_json())


# -- the private module, called directly: a ValueError with a sentence, never a panic ------
SYSTEM_OPTIONS = (None, 1, 3, "all", False, True, None)


def system_call(t, x=None, v=None, u=None, V=None, i=None, options=SYSTEM_OPTIONS, **kw):
    # Not refined (these tests are about the errors; refining each full fit took CI's time).
    kw.setdefault("refine", False)
    return _lssi.fit_system(t, x, v, u, V, i, *options, **kw)


@pytest.mark.parametrize(
    "call",
    [
        lambda c: system_call(c["t"][:100], c["x"], None, c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"][:100], None, c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"], c["x"][:100], c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"], None, c["u"][:100], c["V"]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"][:100]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], None, c["V"][:100]),
        lambda c: _lssi.system_start(c["t"], c["x"], None, c["V"][:100], None),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"]).simulate(c["t"], [0.0, 0.0, 0.0], c["u"][:100]),
    ],
)
def test_system_columns_of_other_lengths_are_value_errors(piezo, call):
    _, col = piezo
    with pytest.raises(ValueError, match="^[txvuVi] has (100|40001) samples but [xt] has (40001|100)\\."):
        call(col)


@pytest.mark.parametrize(
    "call",
    [
        lambda c: system_call(c["t"][:0], c["x"][:0], None, None, c["V"][:0]),
        lambda c: system_call(c["t"][:5], c["x"][:5], None, None, c["V"][:5]),
        lambda c: system_call(c["t"], None, None, c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], None, None),
        lambda c: system_call(np.zeros_like(c["t"]), c["x"], None, c["u"], c["V"]),
        lambda c: system_call(c["t"][::-1].copy(), c["x"], None, c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"] * 1e300, None, c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], np.full_like(c["V"], np.nan)),
        lambda c: system_call(c["t"], None, np.full_like(c["x"], np.inf), c["u"], c["V"]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"], load_ohms=-1.0),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"], load_ohms=float("nan")),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"], coupling_order=0),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"], coupling_order=9),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"], options=(1e9, 1, 3, "all", False, True, None)),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"], options=(None, 8, 9, "all", False, True, None)),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"]).simulate(c["t"][:0], [0.0, 0.0, 0.0], c["u"][:0]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"]).simulate(c["t"], [1e300, 1e300, 1e300], c["u"]),
        lambda c: system_call(c["t"], c["x"], None, c["u"], c["V"]).simulate(c["t"], [0.0], c["u"]),
        lambda c: _lssi.system_start(c["t"][:0], c["x"][:0], None, c["V"][:0], None),
        lambda c: _lssi.system_start(c["t"][:1], None, c["x"][:1], c["V"][:1], None),
    ],
)
def test_degenerate_system_inputs_do_not_panic(piezo, call):
    """A ValueError with a sentence, or a result: never a pyo3_runtime.PanicException."""
    _, col = piezo
    try:
        call(col)
    except BaseException as e:  # a PanicException is a BaseException, not an Exception
        assert isinstance(e, ValueError), f"{type(e).__module__}.{type(e).__name__}: {e}"


def test_dask_identify_one_takes_a_system(piezo, fitted):
    """lssi.dask's task on a system's file and on its arrays: its equations, by target."""
    import lssi.dask

    path, col = piezo
    for item in (path, {name: col[name] for name in ("t", "x", "u", "V")}):
        row = lssi.dask.identify_one(item)
        assert row["error"] is None, row["error"]
        assert list(row["terms"]) == ["x''", "V'"]
        assert row["coefficients"] == fitted.equations()
        assert row["report"] == fitted.report()


def test_a_dataframe_with_zoned_timestamps_and_its_pickle(fitted, piezo):
    """Issue 25's Python points for systems: pandas Timestamps with a time zone in a
    DataFrame's t, the model pickled with its origin, options type-checked for a system's
    file too."""
    path, col = piezo
    stamps = pd.Timestamp("2026-11-26 04:00", tz="Europe/Paris") + pd.to_timedelta(col["t"], unit="s")
    frame = pd.DataFrame({"t": stamps, "x": col["x"], "u": col["u"], "V": col["V"]})
    m = lssi.Model().fit(frame)
    assert m.is_system()
    for target, terms in m.equations().items():
        assert sorted(terms) == sorted(fitted.equations()[target])
    back = pickle.loads(pickle.dumps(m))
    assert back.to_json() == m.to_json()
    n = 1000
    a = m.simulate({"x": col["x"][0], "v": 0.0, "V": col["V"][0]}, stamps[:n], u=col["u"][:n])
    b = back.simulate({"x": col["x"][0], "v": 0.0, "V": col["V"][0]}, stamps[:n], u=col["u"][:n])
    assert all(np.array_equal(a[k], b[k]) for k in a)
    with pytest.raises(TypeError, match="^omega must be"):
        lssi.identify(path, omega="21")
    with pytest.raises(TypeError, match="^poly_order must be"):
        lssi.identify(path, poly_order=True)
    with pytest.raises(TypeError, match="^load_ohms must be"):
        lssi.identify(path, load_ohms="1e5")


def test_a_velocity_alone_is_integrated_and_scored(cli, tmp_path):
    """A vibrometer's velocity without a displacement: x is v integrated (the report says
    so, as the command's), and score() scores the measured states v and V, not x."""
    path = tmp_path / "piezo-v.csv"
    cli("gen", "piezo", "--input", "--observe", "v", path)
    col = columns(path)
    assert "x" not in col
    m = lssi.Model().fit(None, t=col["t"], v=col["v"], u=col["u"], V=col["V"])
    assert any(w.startswith("x is v integrated") for w in m.report()["warnings"])
    n = 4000
    score = m.score(None, col["t"][:n], u=col["u"][:n], v=col["v"][:n], V=col["V"][:n])
    assert list(score) == ["v", "V"]
    assert score["v"] > 0.9 and score["V"] > 0.9, score
