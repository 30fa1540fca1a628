"""Never a confident wrong model from Python: dates and times as t, streams fed channels
they were not configured for, a simulation without the u its model needs, options of the
wrong type, sentences naming the Python arguments (not the command's flags), pickling, and
no panic of the Rust code reaching Python."""
import datetime
import os
import pickle

import numpy as np
import pandas as pd
import pytest

import lssi
from lssi import _lssi
from conftest import DATA, duffing

N, STEP_NS = 6000, 5_000_000  # 6000 samples every 5 ms


def recording(seed=1):
    """Duffing samples on a grid of whole nanoseconds (t in seconds is then exactly what a
    datetime64[ns] grid gives), and that grid as dates and times."""
    _, x = duffing(n=N, dt=STEP_NS * 1e-9, seed=seed)
    ns = np.arange(N, dtype=np.int64) * STEP_NS
    start = np.datetime64("2024-03-31T00:59:58", "ns")  # 2 s before Paris's DST change
    return ns / 1e9, x, start + ns.astype("timedelta64[ns]")


def forced_by_u(n=N, dt=0.005):
    """x'' = -x - 0.1 x' - 0.5 x^3 + 0.8 u with a measured u (RK4 on a finer grid)."""
    u_of = lambda s: np.cos(1.2 * s) + 0.5 * np.sin(0.37 * s)
    f = lambda s, x, v: -x - 0.1 * v - 0.5 * x**3 + 0.8 * u_of(s)
    x, v, s, h = 0.5, 0.0, 0.0, dt / 4
    xs = np.empty(n)
    for i in range(n):
        xs[i] = x
        for _ in range(4):
            k1x, k1v = v, f(s, x, v)
            k2x, k2v = v + h / 2 * k1v, f(s + h / 2, x + h / 2 * k1x, v + h / 2 * k1v)
            k3x, k3v = v + h / 2 * k2v, f(s + h / 2, x + h / 2 * k2x, v + h / 2 * k2v)
            k4x, k4v = v + h * k3v, f(s + h, x + h * k3x, v + h * k3v)
            x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            s += h
    t = np.arange(n) * dt
    return t, xs, u_of(t)


# -- dates and times as t -------------------------------------------------------------------
def test_datetimes_are_seconds_from_the_first_sample():
    seconds, x, stamps = recording()
    expected = lssi.Model(omega=1.2, refine=False).fit(x, t=seconds).to_json()
    fit = lambda *a, **k: lssi.Model(omega=1.2, refine=False).fit(*a, **k).to_json()
    assert fit(x, t=stamps) == expected                                     # datetime64[ns]
    assert fit(x, t=stamps.astype("datetime64[us]")) == expected            # another unit
    assert fit(x, t=stamps - stamps[0]) == expected                         # timedelta64
    frame = pd.DataFrame({"t": pd.to_datetime(stamps), "x": x})
    assert fit(frame) == expected                                           # pandas Timestamps
    # With a time zone, across a daylight-saving change: the seconds that passed.
    frame["t"] = frame["t"].dt.tz_localize("UTC").dt.tz_convert("Europe/Paris")
    assert fit(frame) == expected
    assert fit(x, t=list(frame["t"])) == expected                           # a list of Timestamps
    wall = [datetime.datetime(2024, 1, 1) + datetime.timedelta(seconds=s) for s in seconds]
    assert np.allclose(lssi._times(wall)[0], seconds, rtol=0, atol=1e-6)  # microseconds


def test_datetimes_in_streams_simulations_and_pickles():
    seconds, x, stamps = recording()
    m = lssi.Model(omega=1.2, refine=False).fit(x, t=stamps)
    s = lssi.Stream(omega=1.2, calibrate=2000)
    for i in range(0, N, 1000):
        s.push(x[i:i + 1000], t=stamps[i:i + 1000])
    reference = lssi.Stream(omega=1.2, calibrate=2000)
    for i in range(0, N, 1000):
        reference.push(x[i:i + 1000], t=seconds[i:i + 1000])
    assert s.model().to_json() == reference.model().to_json()
    with pytest.raises(ValueError, match="^t: this stream's times were dates and times"):
        s.push(x[:10], t=seconds[:10] + 1e3)
    # A simulation on dates and times starts where the fit's t = 0 is.
    later = stamps[1000:2000]
    assert np.array_equal(m.simulate((x[1000], 0.0), later)[0],
                          m.simulate((x[1000], 0.0), seconds[1000:2000])[0])
    assert pickle.loads(pickle.dumps(m)).simulate((x[1000], 0.0), later)[0].tolist() == \
        m.simulate((x[1000], 0.0), later)[0].tolist()


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda s, x: dict(x=x, t=np.r_[s[:10], np.datetime64("NaT"), s[11:]]),
         "t has 1 missing time(s) (NaT), the first at index 10"),
        (lambda s, x: dict(x=s, t=s), "x holds dates or times"),
        (lambda s, x: dict(x=x, t=s, v=s), "v holds dates or times"),
        (lambda s, x: dict(x=x, t=[datetime.datetime(2024, 1, 1, tzinfo=datetime.timezone.utc)]
                           + [datetime.datetime(2024, 1, 1) + datetime.timedelta(seconds=k) for k in range(1, N)]),
         "t mixes times with a time zone and times without one"),
    ],
)
def test_bad_dates_and_times_are_value_errors(make, message):
    _, x, stamps = recording()
    with pytest.raises(ValueError) as e:
        lssi.Model(omega=1.2).fit(**make(stamps, x))
    assert message in str(e.value)


# -- streams and their channels -------------------------------------------------------------
def test_stream_blocks_carry_the_channels_the_stream_was_configured_with():
    seconds, x, _ = recording()
    v, u = np.gradient(x, seconds), np.cos(1.2 * seconds)
    block = lambda a, b, **k: dict(x=x[a:b], t=seconds[a:b], **{n: c[a:b] for n, c in k.items()})
    m = lssi.Model(omega=1.2, refine=False).fit(x, t=seconds)
    s = m.stream()
    with pytest.raises(ValueError, match="^v: this stream was configured without a measured velocity v"):
        s.push(**block(0, 100, v=v))
    with pytest.raises(ValueError, match="^u: this stream was configured without an excitation u"):
        s.push(**block(0, 100, u=u))
    s.push(**block(0, 100))  # nothing of the refused blocks went in
    assert s.rejected == 0
    # Calibrating: the first block decides; lacked then gained, before and after calibrating.
    s = lssi.Stream(omega=1.2, calibrate=1000)
    s.push(**block(0, 500))
    with pytest.raises(ValueError, match="^v: this stream's first block came without a measured velocity v"):
        s.push(**block(500, 1000, v=v))
    s.push(**block(500, 1500))
    with pytest.raises(ValueError, match="^v: this stream was configured without a measured velocity v"):
        s.push(**block(1500, 2000, v=v))
    # Had, then lost.
    s = lssi.Model(omega=1.2, refine=False).fit(x, t=seconds, v=v).stream()
    with pytest.raises(ValueError, match="^v: this stream was configured with a measured velocity v, so every block needs v"):
        s.push(**block(0, 100))
    # The compiled stream refuses them too, rather than rejecting every sample quietly.
    raw = _lssi.RawStream.like(m._fit)
    with pytest.raises(ValueError, match="^v: "):
        raw.push(seconds[:100], x[:100], v[:100], None)
    with pytest.raises(ValueError, match="^u: "):
        raw.push(seconds[:100], x[:100], None, u[:100])


# -- simulate and score need the u of a model with a u term ---------------------------------
def test_simulate_and_score_without_the_u_the_model_needs():
    t, x, u = forced_by_u()
    m = lssi.Model(harmonics=0, refine=False).fit(x, t=t, u=u)
    assert m.coefficients()["u"] == pytest.approx(0.8, rel=0.01)
    with pytest.raises(ValueError, match="^u: the model has an excitation term u .* simulate needs"):
        m.simulate((x[0], 0.0), t)
    with pytest.raises(ValueError, match="^u: the model has an excitation term u .* score needs"):
        m.score(x, t)
    with pytest.raises(ValueError, match="u has 10 samples but x has"):
        m.simulate((x[0], 0.0), t, u=u[:10])
    assert m.score(x, t, u=u) > 0.99


# -- options are type-checked, by their Python names ----------------------------------------
@pytest.mark.parametrize(
    "options, error, name",
    [
        (dict(omega="21"), TypeError, "omega"),
        (dict(poly_order=True), TypeError, "poly_order"),
        (dict(poly_order=3.0), TypeError, "poly_order"),
        (dict(harmonics=1.5), TypeError, "harmonics"),
        (dict(f32="yes"), TypeError, "f32"),
        (dict(memory="2"), TypeError, "memory"),
        (dict(smoothing=1), TypeError, "smoothing"),
        (dict(refine="no"), TypeError, "refine"),
        (dict(family=3), TypeError, "family"),
        (dict(omega=-1.0), ValueError, "omega"),
        (dict(memory=float("nan")), ValueError, "memory"),
        (dict(harmonics=9), ValueError, "harmonics"),
    ],
)
def test_options_are_type_checked(options, error, name):
    makers = [lambda: lssi.Model(**options), lambda: lssi.identify(DATA[0], **options)]
    if "refine" not in options:  # a stream's model is the streaming one: no refine option
        makers.append(lambda: lssi.Stream(**options))
    for make in makers:
        with pytest.raises(error) as e:
            make()
        assert str(e.value).startswith(f"{name} must be"), str(e.value)


def test_other_arguments_are_type_checked():
    seconds, x, _ = recording()
    with pytest.raises(TypeError, match="^calibrate must be an integer"):
        lssi.Stream(calibrate=1e4)
    with pytest.raises(TypeError, match="^like must be a fitted lssi.Model"):
        lssi.Stream(like="model")
    with pytest.raises(TypeError, match="^dt must be a positive number of seconds"):
        lssi.Model().fit(x, dt="0.005")
    m = lssi.Model(omega=1.2, refine=False).fit(x, dt=datetime.timedelta(milliseconds=5))
    assert m.to_json() == lssi.Model(omega=1.2, refine=False).fit(x, dt=0.005).to_json()
    with pytest.raises(TypeError, match="^x0 must be a number or a pair"):
        m.simulate(("a", 0.0), seconds)
    with pytest.raises(ValueError, match="^x0 must be finite"):
        m.simulate((np.nan, 0.0), seconds)
    with pytest.raises(ValueError, match="^t must increase"):
        m.simulate(x[0], seconds[::-1])


# -- sentences name Python arguments, not the command's flags --------------------------------
def test_errors_name_python_arguments_not_flags():
    with pytest.raises(ValueError) as e:
        lssi.Model().fit(np.exp(-np.arange(2000) * 0.01), dt=0.01)
    assert "give omega=… (rad/s)." in str(e.value) and "--" not in str(e.value)
    seconds, x, _ = recording()
    with pytest.raises(ValueError) as e:
        lssi.Model(omega=1e4).fit(x, t=seconds)
    assert str(e.value).startswith("array: omega=10000 rad/s is at or above the Nyquist frequency")
    assert "--" not in str(e.value)



def test_a_header_with_units_is_renamed_not_given_flags(tmp_path):
    # BistableX's header as its recordings come: the command's hint names --t-col, which
    # Python has not got.
    path = tmp_path / "raw.csv"
    path.write_text("t_s,base_acc_g,piezo_voltage_V_raw,vibrometer_velocity_V_raw\n"
                    + "".join(f"{i / 100},0,0,0\n" for i in range(300)))
    for call in (lssi.identify, lssi.read_recording):
        with pytest.raises(ValueError) as e:
            call(path)
        message = str(e.value)
        assert "no column named 't'" in message and "rename the file's columns" in message
        assert "--" not in message, message

# -- pickling ----------------------------------------------------------------------------
@pytest.mark.parametrize("refine", [True, False])
def test_a_fitted_model_pickles(refine):
    seconds, x, _ = recording(seed=2)
    m = lssi.Model(omega=1.2, refine=refine).fit(x, t=seconds)
    back = pickle.loads(pickle.dumps(m))
    assert back.to_json() == m.to_json()
    assert back.coefficients() == m.coefficients()
    assert back.standard_errors() == m.standard_errors()
    assert np.array_equal(back.simulate(x[0], seconds)[0], m.simulate(x[0], seconds)[0])
    assert back.refine == refine
    # A model read from a file keeps its name (the file's, in its sentences).
    path = [p for p in DATA if p.name == "paper-eq17.csv"][0]
    f = lssi.identify(path, refine=False)
    assert pickle.loads(pickle.dumps(f)).to_json() == f.to_json()
    # Unfitted, it pickles its options.
    assert pickle.loads(pickle.dumps(lssi.Model(poly_order=5))).poly_order == 5


def test_a_pickle_that_no_longer_gives_its_model_is_refused():
    seconds, x, _ = recording()
    state = lssi.Model(omega=1.2, refine=False).fit(x, t=seconds).__getstate__()
    state["fit"]["json"] = state["fit"]["json"].replace('"x^3"', '"x^5"')
    m = lssi.Model.__new__(lssi.Model)
    with pytest.raises(ValueError, match="identifies another model"):
        m.__setstate__(state)


def test_a_streams_model_does_not_pickle():
    seconds, x, _ = recording()
    s = lssi.Model(omega=1.2, refine=False).fit(x, t=seconds).stream()
    s.push(x, t=seconds)
    with pytest.raises(TypeError, match="keeps none of the samples"):
        pickle.dumps(s.model())


# -- no panic reaches Python -----------------------------------------------------------------
def test_a_panic_is_a_runtime_error_with_a_sentence():
    with pytest.raises(RuntimeError) as e:
        _lssi._panic_for_tests()
    assert "lssi failed while testing the guard: an internal error (a panic on purpose at" in str(e.value)
    assert "this is a bug" in str(e.value)


OPTIONS = (1.2, 1, 3, "all", False, True, None)
fitted = lambda t, x: _lssi.fit(t, x, None, None, *OPTIONS, refine=False)


@pytest.mark.parametrize(
    "call",
    [
        lambda t, x: _lssi.fit(t[:100], x, None, None, *OPTIONS),
        lambda t, x: _lssi.fit(t, x[:100], None, None, *OPTIONS),
        lambda t, x: _lssi.fit(t, x, x[:100], None, *OPTIONS),
        lambda t, x: _lssi.fit(t, x, None, x[:100], *OPTIONS),
        lambda t, x: _lssi.RawStream.calibrated(t, x[:100], None, None, *OPTIONS),
        lambda t, x: _lssi.RawStream.calibrated(t, x, None, x[:100], *OPTIONS),
        lambda t, x: _lssi.RawStream.like(fitted(t, x)).push(t, x[:100]),
        lambda t, x: fitted(t, x).simulate(t, 0.0, 0.0, x[:100]),
        lambda t, x: lssi.Model().fit(x, t=t, u=x[:100]),
    ],
)
def test_columns_of_other_lengths_are_value_errors_not_panics(call):
    """These indexed out of bounds in the Rust code: a pyo3_runtime.PanicException."""
    seconds, x, _ = recording()
    with pytest.raises(ValueError, match="^[txvu] has (100|6000) samples but [xt] has (6000|100)\\."):
        call(seconds, x)


@pytest.mark.parametrize(
    "call",
    [
        lambda t, x: _lssi.fit(t[:0], x[:0], None, None, *OPTIONS),
        lambda t, x: _lssi.fit(t[:5], x[:5], None, None, *OPTIONS),
        lambda t, x: _lssi.fit(np.zeros_like(t), x, None, None, *OPTIONS),
        lambda t, x: _lssi.fit(t, x * 1e300, None, None, *OPTIONS),
        lambda t, x: _lssi.fit(t, x * 1e300, None, None, None, 1, 3, "all", False, True, None),
        lambda t, x: _lssi.fit(t, x * 1e300, None, None, *OPTIONS[:4], True, True, None),
        lambda t, x: _lssi.fit(t, np.ones_like(x), None, None, None, 1, 3, "all", False, True, None),
        lambda t, x: _lssi.RawStream.like(fitted(t, x)).push(t, x * 1e300),
        lambda t, x: _lssi.RawStream.like(fitted(t, x)).model(),
        lambda t, x: fitted(t, x).simulate(t[:0], 0.0, 0.0),
        lambda t, x: fitted(t, x).simulate(t, 1e300, 1e300),
        lambda t, x: lssi.Model().fit(x[:5], t=t[:5]),
        lambda t, x: lssi.Model().fit(x[:0], t=t[:0]),
        lambda t, x: lssi.Model().fit(np.ones_like(x), t=t),
        lambda t, x: lssi.Model().fit(x * 1e300, t=t),
        lambda t, x: lssi.Model(omega=1.2).fit(x * 1e300, t=t),
        lambda t, x: lssi.Model().fit(x, t=np.full_like(t, 3.0)),
    ],
)
def test_degenerate_inputs_do_not_panic(call):
    """A ValueError with a sentence, or a result: never a pyo3_runtime.PanicException."""
    seconds, x, _ = recording()
    try:
        call(seconds, x)
    except BaseException as e:  # a PanicException is a BaseException, not an Exception
        assert isinstance(e, ValueError), f"{type(e).__module__}.{type(e).__name__}: {e}"


def test_a_forcing_not_recorded_names_the_u_argument():
    # A linear well swept through its resonance (10 -> 40 rad/s over 20 s, 1 kHz) without
    # its u: the command's sentence ends "give the excitation's column as u (--u-col)" or
    # "give the excitation as a u column (--u-col)"; Python names its argument.
    n, dt = 20000, 0.001
    t = np.arange(n) * dt
    w0, w1 = 10.0, 40.0
    h = dt / 4
    f = lambda x, v, s: -631.65 * x - 0.4 * v + np.cos(w0 * s + 0.5 * (w1 - w0) / t[-1] * s * s)
    x = v = 0.0
    xs = np.empty(n)
    for i in range(n):
        xs[i] = x
        for j in range(4):
            s = t[i] + j * h
            k1x, k1v = v, f(x, v, s)
            k2x, k2v = v + h / 2 * k1v, f(x + h / 2 * k1x, v + h / 2 * k1v, s + h / 2)
            k3x, k3v = v + h / 2 * k2v, f(x + h / 2 * k2x, v + h / 2 * k2v, s + h / 2)
            k4x, k4v = v + h * k3v, f(x + h * k3x, v + h * k3v, s + h)
            x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    with pytest.raises(ValueError) as e:
        lssi.Model().fit(xs, t=t)
    message = str(e.value)
    assert message.startswith("no deterministic dynamics found in array:"), message
    assert "(u=…)" in message and "--" not in message, message


def test_an_upper_case_header_is_renamed_not_given_flags(tmp_path):
    # `T,X`: the command's hint is `give --t-col T --x-col X`, which Python has not got.
    path = tmp_path / "upper.csv"
    path.write_text("T,X\n" + "".join(f"{i / 100},{np.sin(i / 10)}\n" for i in range(300)))
    for call in (lssi.identify, lssi.read_recording):
        with pytest.raises(ValueError) as e:
            call(path)
        message = str(e.value)
        assert "differs only in case" in message and "rename the file's columns" in message
        assert "--" not in message, message


def test_a_path_is_read_as_bytes_or_pathlike_and_none_is_a_type_error(tmp_path):
    # `str(b"a.csv")` is "b'a.csv'": a bytes path was reported missing; None was a file
    # named "None".
    path = [p for p in DATA if p.name == "paper-eq17.csv"][0]
    t, x, _, _ = lssi.read_recording(os.fsencode(path))
    assert len(t) == len(x) > 1000
    for call in (lssi.identify, lssi.read_recording):
        with pytest.raises(TypeError) as e:
            call(None)
        assert "path must be a file path" in str(e.value)
        # A DataFrame is named in a sentence, not printed whole, and Model().fit named.
        with pytest.raises(TypeError) as e:
            call(pd.DataFrame({"t": np.arange(300.0), "x": np.zeros(300)}))
        message = str(e.value)
        assert "not a DataFrame" in message and "lssi.Model().fit" in message, message
        assert "\n" not in message, message


def test_a_frame_indexed_by_time_gives_its_times():
    """Issue 25: a DataFrame whose times are its index (a DatetimeIndex, as read_csv(...,
    index_col=0, parse_dates=True) makes, a TimedeltaIndex, or an index named t) fits as the
    same recording with a column t; a plain index is not taken for times."""
    pd = pytest.importorskip("pandas")
    t, x = duffing(n=8000, dt=0.01)
    reference = lssi.Model(refine=False).fit(pd.DataFrame({"t": t, "x": x})).coefficients()
    stamps = pd.Timestamp("2026-11-27 05:00") + pd.to_timedelta(t, unit="s")
    frames = [
        pd.DataFrame({"x": x}, index=pd.DatetimeIndex(stamps)),
        pd.DataFrame({"x": x}, index=pd.DatetimeIndex(stamps).tz_localize("Europe/Paris")),
        pd.DataFrame({"x": x}, index=pd.to_timedelta(t, unit="s")),
        pd.DataFrame({"t": t, "x": x}).set_index("t"),
    ]
    for frame in frames:
        got = lssi.Model(refine=False).fit(frame).coefficients()
        assert got.keys() == reference.keys()
        for name, value in reference.items():
            assert got[name] == pytest.approx(value, rel=1e-6, abs=1e-9), name
    with pytest.raises(ValueError, match="give the sample times t"):
        lssi.Model().fit(pd.DataFrame({"x": x}))
