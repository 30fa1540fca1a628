"""A measured excitation u means no sin/cos(Ωt) by default, as for the command (issue 25):
u is the forcing, and cos(Ωt) beside it split the forcing between them. An explicit
``harmonics`` still puts them in."""
import json

import numpy as np
import pytest

import lssi
from conftest import LSSI  # noqa: F401  (the cli fixture builds it when missing)


def harmonic(term):
    return term.startswith("sin(") or term.startswith("cos(")


def library(model_json, equation=None):
    d = json.loads(model_json)
    if equation is not None:
        d = next(e for e in d["equations"] if e["target"] == equation)
    return d["solutions"][0]["terms"], [t["term"] for t in d["terms"]]


@pytest.mark.parametrize("seed", [5, 6])
def test_fit_with_u_has_no_harmonics_and_equals_the_command(cli, tmp_path, seed):
    path = tmp_path / "e.csv"
    cli("gen", "eveh", "--input", "--t-end", "6", "--seed", seed, path)
    expected = cli("identify", path, "--json", "--f64").strip()
    terms, selected = library(expected)
    assert not any(harmonic(t) for t in terms), terms
    assert "u" in selected, selected
    assert lssi.identify(path).to_json() == expected
    t, x, v, u = lssi.read_recording(path)
    assert u is not None
    assert lssi.Model().fit(x, t=t, u=u).to_json() == expected
    # Asked for, the harmonics are in the library, as with --harmonics 1.
    asked = cli("identify", path, "--json", "--f64", "--harmonics", "1").strip()
    assert any(harmonic(t) for t in library(asked)[0])
    assert lssi.Model(harmonics=1).fit(x, t=t, u=u).to_json() == asked
    # Without u the default is one harmonic, as before.
    m = lssi.Model(refine=False).fit(x, t=t)
    assert any(harmonic(t) for t in library(m.to_json())[0])


def test_a_system_with_u_has_no_harmonics(cli, tmp_path):
    path = tmp_path / "p.csv"
    cli("gen", "piezo", "--input", "--observe", "xv", "--delta", "0.02", "--seed", "8084",
        "--t-end", "6", path)
    expected = cli("identify", path, "--json", "--f64").strip()
    terms, selected = library(expected, "x''")
    assert not any(harmonic(t) for t in terms), terms
    assert "u" in selected, selected
    assert lssi.identify(path).to_json() == expected
