"""The package against the `lssi` command, the stream against the fit, and bad input."""
import json

import numpy as np
import pandas as pd
import pytest

import lssi
from conftest import DATA, DUFFING_TRUTH, duffing


@pytest.mark.parametrize("path", DATA, ids=lambda p: p.name)
@pytest.mark.parametrize("f32", [False, True])
@pytest.mark.parametrize("refine", [True, False])
def test_identify_equals_the_command(cli, path, f32, refine):
    """The same object as `lssi identify --json`: refined by default, as the command."""
    precision = "--f32" if f32 else "--f64"
    flags = [] if refine else ["--no-refine"]
    expected = cli("identify", path, "--json", precision, *flags).strip()
    assert lssi.identify(path, f32=f32, refine=refine).to_json() == expected


@pytest.mark.parametrize("path", [p for p in DATA if p.name.startswith("eveh-")], ids=lambda p: p.name)
def test_fit_on_arrays_equals_the_command(cli, path):
    expected = cli("identify", path, "--json", "--f64", "--family", "odd", "--no-refine").strip()
    t, x, v, u = lssi.read_recording(path)
    m = lssi.Model(family="odd", refine=False).fit(x, t=t, v=v, u=u)
    assert m.to_json() == expected
    frame = pd.DataFrame({"t": t, "x": x})
    assert lssi.Model(family="odd", refine=False).fit(frame).to_json() == expected


def test_dt_instead_of_t_and_the_api():
    t, x = duffing()
    m = lssi.Model(omega=1.2, refine=False).fit(x, dt=t[1] - t[0])
    coefficients = m.coefficients()
    assert list(coefficients) == m.feature_names()
    for name, true in DUFFING_TRUTH.items():
        assert coefficients[name] == pytest.approx(true, rel=0.01), name
    spurious = [k for k, c in coefficients.items() if c != 0.0 and k not in DUFFING_TRUTH]
    assert spurious == []
    assert m.equation().startswith("x'' = ")
    assert m.standard_errors() is None
    assert json.loads(m.to_json())["omega"] == 1.2


@pytest.mark.parametrize("f32", [False, True])
def test_stream_like_a_fit_gives_the_fit(f32):
    """A stream gives the streaming model: the fit's with refine=False, and the
    streaming_coefficients() of a refined fit."""
    t, x = duffing(seed=3, noise=0.01)
    m = lssi.Model(omega=1.2, f32=f32, refine=False).fit(x, t=t)
    refined = lssi.Model(omega=1.2, f32=f32).fit(x, t=t)
    assert refined.streaming_coefficients() == m.coefficients()
    for like in (m, refined):
        s = like.stream()
        for i in range(0, len(t), 777):
            s.push(x[i:i + 777], t=t[i:i + 777])
        assert s.model().to_json() == m.to_json()


def test_a_calibrated_stream_identifies_online():
    t, x = duffing(seed=4)
    s = lssi.Stream(omega=1.2, calibrate=4096)
    for i in range(0, len(t), 1000):
        s.push(x[i:i + 1000], t=t[i:i + 1000])
    c = s.model().coefficients()
    for name, true in DUFFING_TRUTH.items():
        assert c[name] == pytest.approx(true, rel=0.02), name
    # The configuration came from the first 4096 samples; fed the same, a stream like the
    # stream's model gives the same model.
    assert s.rejected == 0


def test_simulate_reproduces_the_recording():
    t, x = duffing(n=10000)
    m = lssi.Model(omega=1.2).fit(x, t=t)
    v0 = (x[1] - x[0]) / (t[1] - t[0])
    xs, vs = m.simulate((x[0], 0.0), t)
    assert xs.shape == t.shape and vs.shape == t.shape
    nrmse = np.sqrt(np.mean((xs - x) ** 2)) / np.std(x)
    assert nrmse < 0.05, nrmse
    assert m.score(x, t) > 0.99
    assert v0 == pytest.approx(0.0, abs=0.01)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(x=np.r_[np.ones(10), np.nan, np.ones(100)], dt=0.01), "x has 1 non-finite value(s), the first at index 10"),
        (dict(x=np.ones((100, 3)), dt=0.01), "x must be a 1-D array"),
        (dict(x=np.ones(10), dt=0.01), "x has 10 samples; at least 64"),
        (dict(x=np.ones(100), t=np.arange(99.0)), "t has 99 samples but x has 100"),
        (dict(x=np.ones(100), t=np.r_[np.arange(50.0), np.arange(50.0)]), "t must increase"),
        (dict(x=np.ones(100)), "give the sample times t, or the sample period dt"),
        (dict(x=np.ones(100), dt=-1.0), "dt must be a positive number"),
    ],
)
def test_bad_input_is_a_value_error(kwargs, message):
    with pytest.raises(ValueError, match=None) as e:
        lssi.Model().fit(**kwargs)
    assert message in str(e.value)


def test_bad_options_and_files_are_value_errors(tmp_path):
    with pytest.raises(ValueError, match="poly_order"):
        lssi.Model(poly_order=0)
    with pytest.raises(ValueError, match="family"):
        lssi.Model(family="even")
    with pytest.raises(ValueError, match="not fitted"):
        lssi.Model().equation()
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x\n0,1\n0.1,oops\n")
    with pytest.raises(ValueError, match="bad.csv"):
        lssi.identify(bad)
    # Too little signal for a model: the identifier's own sentence.
    with pytest.raises(ValueError, match="x is constant"):
        lssi.Model().fit(np.zeros(200), dt=0.01)
    with pytest.raises(ValueError, match="only 70 samples, too few to estimate the excitation"):
        lssi.Model().fit(np.sin(np.arange(70) * 0.3), dt=0.01)
    with pytest.raises(ValueError, match="array: no model: 70 samples were accepted"):
        lssi.Model(omega=1.0).fit(np.sin(np.arange(70) * 0.3), dt=0.01)
    with pytest.raises(ValueError, match="x is constant"):
        lssi.Model(omega=1.0).fit(np.zeros(200), dt=0.01)


def test_white_noise_gets_no_model_as_the_command_refuses_it():
    """The quality gate of `lssi identify` (exit 3) is a ValueError here, same sentence."""
    rng = np.random.default_rng(7)
    t = np.arange(20000) * 5e-4
    x = 1e-3 * rng.standard_normal(t.size)
    with pytest.raises(ValueError, match="no deterministic dynamics found"):
        lssi.Model().fit(x, t=t)
