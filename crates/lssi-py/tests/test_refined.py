"""One answer everywhere: `lssi.identify` and `Model.fit` give the model `lssi identify --f64`
prints by default (refined on simulation error when that predicts better), and refine=False
the streaming one (`--no-refine`); to_json, print, standard errors and simulate follow."""
import json

import numpy as np
import pytest

import lssi
from conftest import ROOT

BISTABLE = ROOT / "data" / "eveh-bistable.csv"
FLAGS = {True: [], False: ["--no-refine"]}


@pytest.fixture(scope="module", params=[True, False], ids=["refined", "no-refine"])
def both(request, cli):
    """(refine, the package's model, the command's --json text, the command's text)."""
    refine = request.param
    command = ["identify", BISTABLE, "--family", "odd", "--f64", *FLAGS[refine]]
    model = lssi.identify(BISTABLE, family="odd", refine=refine)
    return refine, model, cli(*command, "--json").strip(), cli(*command)


def terms(report, key="terms"):
    return [(t["term"], t["coef"]) for t in report[key]]


def test_the_package_reports_the_commands_model(both):
    refine, m, expected_json, _ = both
    expected = json.loads(expected_json)
    report = m.report()
    assert expected["model"] == ("refined" if refine else "streaming")
    assert report["model"] == expected["model"]
    assert terms(report) == terms(expected)
    nonzero = {k: c for k, c in m.coefficients().items() if c != 0.0}
    assert nonzero == dict(terms(expected))
    assert m.to_json() == expected_json


def test_fit_on_arrays_reports_the_commands_model(both):
    refine, _, expected_json, _ = both
    t, x, v, u = lssi.read_recording(BISTABLE)
    m = lssi.Model(family="odd", refine=refine).fit(x, t=t, v=v, u=u)
    assert m.to_json() == expected_json


def test_print_is_the_commands_text(both, capsys):
    _, m, _, expected_text = both
    m.print()
    assert capsys.readouterr().out == expected_text
    assert m.equation() == expected_text.splitlines()[0]


def test_standard_errors_and_the_streaming_model(both):
    refine, m, expected_json, _ = both
    expected = json.loads(expected_json)
    if refine:
        assert m.standard_errors() == {t["term"]: t["se"] for t in expected["terms"]}
        assert all(se > 0 for se in m.standard_errors().values())
    else:
        assert m.standard_errors() is None
    streaming = {k: c for k, c in m.streaming_coefficients().items() if c != 0.0}
    assert streaming == dict(terms(expected, "streaming_terms"))
    assert lssi.identify(BISTABLE, family="odd", refine=False).coefficients() == \
        m.streaming_coefficients()


def _rk4(report, t, x0, v0, substeps=4):
    """The reported model of a `--json` object, integrated in Python (RK4, as the package)."""
    omega, (ox, ov) = report["omega"], report["offsets"]

    def theta(name, s, x, v):
        if name == "1":
            return 1.0
        if name.startswith(("sin(", "cos(")):
            inner = name[4:-2]
            k = round((float(inner) if inner else 1.0) / omega)
            return (np.sin if name.startswith("sin") else np.cos)(k * omega * s)
        value = 1.0
        for factor in name.split("*"):
            symbol, _, power = factor.partition("^")
            value *= (x if symbol == "x" else v) ** int(power or 1)
        return value

    model = terms(report)
    f = lambda s, x, v: sum(c * theta(name, s, x, v) for name, c in model)
    x, v = x0 - ox, v0 - ov
    out = [x0]
    for i in range(1, len(t)):
        h = (t[i] - t[i - 1]) / substeps
        for k in range(substeps):
            s = t[i - 1] + k * h
            k1x, k1v = v, f(s, x, v)
            k2x, k2v = v + h / 2 * k1v, f(s + h / 2, x + h / 2 * k1x, v + h / 2 * k1v)
            k3x, k3v = v + h / 2 * k2v, f(s + h / 2, x + h / 2 * k2x, v + h / 2 * k2v)
            k4x, k4v = v + h * k3v, f(s + h, x + h * k3x, v + h * k3v)
            x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        out.append(x + ox)
    return np.array(out)


def test_simulate_runs_the_reported_model(both):
    refine, m, _, _ = both
    t, x, _, _ = lssi.read_recording(BISTABLE)
    t, x0 = t[:1500], (x[0], 0.0)
    xs, _ = m.simulate(x0, t)
    expected = _rk4(m.report(), t, *x0)
    assert np.max(np.abs(xs - expected)) <= 1e-9 * np.max(np.abs(expected))
    if refine:
        # ... not the streaming model's, which Report.model holds.
        streaming = lssi.identify(BISTABLE, family="odd", refine=False)
        xs_streaming, _ = streaming.simulate(x0, t)
        assert np.max(np.abs(xs - xs_streaming)) > 1e3 * np.max(np.abs(xs - expected))
