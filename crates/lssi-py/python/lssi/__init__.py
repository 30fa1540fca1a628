"""lssi: streaming sparse identification of a vibration energy harvester's equation of motion.

The same identifier and pipeline as the ``lssi`` command (Rust, in f64 or f32), behind a
PySINDy-like API::

    import numpy as np, lssi
    m = lssi.Model(family="odd")
    m.fit(x, t=t)                  # x'' = f(x, x', t) from the displacement alone
    m.print()                      # what `lssi identify --f64` prints
    m.coefficients()               # {"1": 0.0, "x": 336.64, ...}
    x_sim, v_sim = m.simulate((x[0], 0.0), t)

By default the model is the one ``lssi identify --f64`` reports: the streaming identifier's
model refined on simulation error, taken when it predicts the held-out half better (with
standard errors, ``Model.standard_errors()``). ``Model(refine=False)`` gives the streaming
model a device computes (``lssi identify --f64 --no-refine``), in a fraction of the time;
it is always in ``Model.streaming_coefficients()``. ``Model.to_json()`` is the object the
command prints with ``--json`` for the same data and options. ``Stream`` identifies online,
block by block (the streaming model). ``lssi.dask.identify_many`` maps the identification
over a Dask cluster.

Times may be seconds, or dates and times (NumPy ``datetime64``, pandas Timestamps,
``datetime``): those become seconds from the first sample. Errors are ``ValueError`` (bad
data) or ``TypeError`` (an argument of the wrong type), each naming the Python argument; an
internal error of the Rust code is a ``RuntimeError``, never a crash.
"""

from __future__ import annotations

import datetime as _dt
import json
import numbers
import os
from collections.abc import Mapping
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from . import _lssi

__all__ = ["Model", "Stream", "identify", "read_recording", "Fit"]

Fit = _lssi.Fit

#: The fewest samples a fit accepts (a library of 16 terms needs about 2·16 rows in each
#: held-out half once the derivative window is full).
MIN_SAMPLES = 64

#: The version of the state ``Model`` pickles.
_PICKLE_VERSION = 1


# -- checking arguments ---------------------------------------------------------------------
def _is_bool(value) -> bool:
    return isinstance(value, (bool, np.bool_))


def _integer(name: str, value, lo: int, hi: int) -> int:
    if _is_bool(value) or not isinstance(value, (numbers.Integral, np.integer)):
        raise TypeError(f"{name} must be an integer from {lo} to {hi}, not {value!r}.")
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer from {lo} to {hi}, not {value!r}.")
    return int(value)


def _positive(name: str, value, what: str) -> Optional[float]:
    if value is None:
        return None
    if _is_bool(value) or not isinstance(value, (numbers.Real, np.integer, np.floating)):
        raise TypeError(f"{name} must be {what}, not {value!r}.")
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be {what}, not {value!r}.")
    return value


def _flag(name: str, value) -> bool:
    if not _is_bool(value):
        raise TypeError(f"{name} must be True or False, not {value!r}.")
    return bool(value)


def _seconds(name: str, value, what: str) -> float:
    """A duration: a number of seconds, or a ``timedelta``/``timedelta64``."""
    if isinstance(value, _dt.timedelta):
        value = value.total_seconds()
    elif isinstance(value, np.timedelta64):
        value = value / np.timedelta64(1, "s")
    return _positive(name, value, what)


# -- checking and converting columns ------------------------------------------------------
def _datetimes(name: str, a) -> Optional[np.ndarray]:
    """``a`` as datetime64[ns] when it holds dates and times (NumPy datetime64, pandas
    Timestamps or a datetime column, with a time zone or not, ``datetime`` objects), else
    None. Times with a time zone are taken in UTC."""
    module = type(a).__module__ or ""
    if module.startswith("pandas"):
        import pandas as pd

        if isinstance(a, (pd.Series, pd.Index)) and pd.api.types.is_datetime64_any_dtype(a.dtype):
            s = pd.Series(a)
            if s.dt.tz is not None:
                s = s.dt.tz_convert("UTC").dt.tz_localize(None)
            return s.to_numpy(dtype="datetime64[ns]")
    if isinstance(a, np.ndarray) and a.dtype.kind == "M":
        return a.astype("datetime64[ns]")
    if isinstance(a, np.ndarray) and a.dtype.kind != "O":
        return None
    if not isinstance(a, np.ndarray):
        try:
            arr = np.asarray(a)
        except (TypeError, ValueError):
            return None
        if arr.dtype.kind == "M":
            return arr.astype("datetime64[ns]")
        if arr.dtype.kind != "O":
            return None
    else:
        arr = a
    items = arr.ravel()
    if not items.size or not all(isinstance(e, (_dt.datetime, np.datetime64)) for e in items):
        return None
    aware = [isinstance(e, _dt.datetime) and e.tzinfo is not None for e in items]
    if any(aware) and not all(aware):
        raise ValueError(f"{name} mixes times with a time zone and times without one.")
    out = np.empty(items.size, dtype="datetime64[ns]")
    for i, e in enumerate(items):
        if isinstance(e, _dt.datetime):
            if e.tzinfo is not None:
                e = e.astimezone(_dt.timezone.utc).replace(tzinfo=None)
            value = getattr(e, "value", None)  # a pandas Timestamp: nanoseconds since 1970
            if isinstance(value, (int, np.integer)) and hasattr(e, "tz_localize"):
                out[i] = np.datetime64(int(value), "ns")
                continue
        out[i] = np.datetime64(e, "ns")
    return out.reshape(arr.shape)


def _times(a, n: Optional[int] = None, origin: Optional[np.datetime64] = None, name: str = "t"):
    """Times as seconds, and the origin of dates and times (None for seconds): datetime64,
    Timestamps and datetimes become seconds from ``origin`` (default: the first sample);
    timedelta64 and timedeltas, seconds."""
    stamps = _datetimes(name, a)
    if stamps is None:
        arr = a if isinstance(a, np.ndarray) else None
        if arr is None:
            try:
                arr = np.asarray(a)
            except (TypeError, ValueError):
                arr = None
        if arr is not None and arr.dtype.kind == "m":
            return _column(name, arr / np.timedelta64(1, "s"), n), None
        if arr is not None and arr.dtype.kind == "O" and arr.size and all(
            isinstance(e, _dt.timedelta) for e in arr.ravel()
        ):
            seconds = np.array([e.total_seconds() for e in arr.ravel()]).reshape(arr.shape)
            return _column(name, seconds, n), None
        return _column(name, a, n), None
    stamps = stamps.reshape(-1) if stamps.ndim == 2 and 1 in stamps.shape else stamps
    if stamps.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, not one of shape {stamps.shape}.")
    missing = np.flatnonzero(np.isnat(stamps))
    if missing.size:
        raise ValueError(
            f"{name} has {missing.size} missing time(s) (NaT), the first at index {missing[0]}; "
            "remove or fill them first."
        )
    if not stamps.size:
        return _column(name, np.empty(0), n), None
    origin = stamps[0] if origin is None else origin
    seconds = (stamps - origin).astype(np.int64) / 1e9
    return _column(name, seconds, n), origin


def _column(name: str, a: Any, n: Optional[int] = None) -> np.ndarray:
    kind = getattr(getattr(a, "dtype", None), "kind", None)
    if kind in ("M", "m") or _datetimes(name, a) is not None:
        raise ValueError(
            f"{name} holds dates or times; only t may (as seconds from the first sample), "
            f"{name} must be numbers."
        )
    if kind == "c":
        raise ValueError(f"{name} must be real numbers, not complex ones.")
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} must be a 1-D array of numbers ({e}).") from None
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, not one of shape {arr.shape}.")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} has {arr.shape[0]} samples but x has {n}.")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(
            f"{name} has {bad.size} non-finite value(s), the first at index {bad[0]} "
            f"({arr[bad[0]]}); remove or fill them first."
        )
    return np.ascontiguousarray(arr)


def _increasing(t: np.ndarray, name: str = "t") -> None:
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise ValueError(
            f"{name} must increase: {name}[{i + 1}] = {t[i + 1]} does not come after "
            f"{name}[{i}] = {t[i]}."
        )


#: The electrical channels a system's recording may carry, in the library's order: the
#: voltage across the load and the current.
ELECTRICAL = ("V", "i")


def _is_frame(x) -> bool:
    return hasattr(x, "columns") and hasattr(x, "__getitem__")


def _index_times(frame):
    """A DataFrame's index as its times when it has no column t: an index named t (seconds, as
    after ``set_index("t")``), or one of dates and times or of durations (``DatetimeIndex``,
    ``TimedeltaIndex``, as ``read_csv(..., index_col=0, parse_dates=True)`` makes); else None."""
    index = getattr(frame, "index", None)
    if index is None or not hasattr(index, "dtype"):
        return None
    if getattr(index, "name", None) == "t" or getattr(index.dtype, "kind", None) in ("M", "m"):
        return index
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - a frame with an index is pandas'
        return None
    if pd.api.types.is_datetime64_any_dtype(index.dtype):  # a DatetimeIndex with a time zone
        return index
    return None


def _frame(frame, t, v, u, electrical: Optional[Dict[str, Any]] = None):
    """A DataFrame's columns t, x, v, u (and V, i into ``electrical`` when given) where the
    arguments do not give them."""
    columns = list(frame.columns)
    x = frame["x"].to_numpy() if "x" in columns else None
    if x is None and "x1" in columns and "x2" in columns:
        raise ValueError(
            "the DataFrame has two displacements (x1, x2): a two-degree-of-freedom harvester is "
            "identified from its CSV file, lssi.identify(path); Model().fit takes one "
            "displacement x."
        )
    if x is None and (electrical is None or "v" not in columns
                      or not any(name in columns for name in ELECTRICAL)):
        raise ValueError(f"the DataFrame has no column 'x' (it has {columns}).")
    if t is None and "t" in columns:
        t = frame["t"]
    elif t is None:
        t = _index_times(frame)
    if v is None and "v" in columns:
        v = frame["v"].to_numpy()
    if u is None and "u" in columns:
        u = frame["u"].to_numpy()
    if electrical is not None:
        for name in ELECTRICAL:
            if electrical.get(name) is None and name in columns:
                electrical[name] = frame[name].to_numpy()
    return x, t, v, u


def _columns(x, t=None, v=None, u=None, dt=None, minimum: int = MIN_SAMPLES,
             origin: Optional[np.datetime64] = None):
    """Checks and converts (x, t, v, u); a pandas DataFrame in x supplies its t/x/v/u
    columns. Returns (t, x, v, u, origin), origin the datetime t = 0 stands for (or None)."""
    if _is_frame(x):
        x, t, v, u = _frame(x, t, v, u)
    x = _column("x", x)
    n = x.shape[0]
    if n < minimum:
        raise ValueError(f"x has {n} samples; at least {minimum} are needed.")
    if t is None:
        if dt is None:
            raise ValueError("give the sample times t, or the sample period dt.")
        step = _seconds("dt", dt, "a positive number of seconds")
        t = np.arange(n, dtype=np.float64) * step
    elif dt is not None:
        raise ValueError("give either t or dt, not both.")
    t, origin = _times(t, n, origin)
    _increasing(t)
    v = None if v is None else _column("v", v, n)
    u = None if u is None else _column("u", u, n)
    return t, x, v, u, origin


def _system_columns(x, t, v, u, dt, electrical: Dict[str, Any], minimum: int = MIN_SAMPLES,
                    origin: Optional[np.datetime64] = None):
    """Checks and converts a system's columns: x (or v alone), v, u and the electrical ones
    (``electrical``: V, i), all of one length. Returns (t, columns, origin), columns a dict
    with keys x, v, u, V, i (None where absent)."""
    if x is None and v is None:
        raise ValueError(
            "give the displacement x, or the velocity v (then integrated), beside the "
            "electrical channel."
        )
    first = "x" if x is not None else "v"
    lead = _column(first, x if x is not None else v)
    n = lead.shape[0]
    if n < minimum:
        raise ValueError(f"{first} has {n} samples; at least {minimum} are needed.")

    def check(name, a):
        if a is None:
            return None
        out = _column(name, a)
        if out.shape[0] != n:
            raise ValueError(f"{name} has {out.shape[0]} samples but {first} has {n}.")
        return out

    columns = {"x": check("x", x), "v": check("v", v), "u": check("u", u)}
    for name in ELECTRICAL:
        columns[name] = check(name, electrical.get(name))
    if t is None:
        if dt is None:
            raise ValueError("give the sample times t, or the sample period dt.")
        step = _seconds("dt", dt, "a positive number of seconds")
        t = np.arange(n, dtype=np.float64) * step
    elif dt is not None:
        raise ValueError("give either t or dt, not both.")
    t, origin = _times(t, n, origin)
    if t.shape[0] != n:
        raise ValueError(f"t has {t.shape[0]} samples but {first} has {n}.")
    _increasing(t)
    return t, columns, origin


def _score(name: str, simulated: np.ndarray, measured: np.ndarray) -> float:
    """1 − NRMSE² of a free run against the measured state; -inf when it diverged."""
    if not np.all(np.isfinite(simulated)):
        return float("-inf")
    var = float(np.var(measured))
    if var == 0.0:
        raise ValueError(f"{name} is constant: a score needs a signal that varies.")
    return 1.0 - float(np.mean((simulated - measured) ** 2)) / var


class Model:
    """The equation of motion x'' = f(x, x', t) of a recording, as ``lssi identify`` finds it.

    Parameters mirror the command's flags: ``poly_order`` (``--poly-order``), ``harmonics``
    (``--harmonics``: sin/cos(kΩt) for k = 1..H; None, the default: 1, or 0 when the fit has
    a measured excitation ``u``, which is the forcing), ``omega`` (``--omega``, rad/s; None:
    estimated from the data), ``family`` (None or "all", "families", "odd"), ``f32``
    (compute in f32 as a device does; the default here is f64, ``--f64``), ``smoothing``
    (False: ``--no-smoothing``), ``memory`` (``--memory``, seconds), ``refine`` (False:
    ``--no-refine``, the streaming model a device computes; True, the default: refined on
    simulation error and reported when it predicts better, as the command does).

    A fitted model pickles: it keeps its samples, and unpickling fits them again (seconds
    for 10⁵ samples), checking that the model is the one pickled (a ValueError if this
    version of lssi identifies another). A ``Stream``'s model keeps no samples and does not
    pickle.
    """

    def __init__(
        self,
        poly_order: int = 3,
        harmonics: Optional[int] = None,
        omega: Optional[float] = None,
        family: Optional[str] = None,
        f32: bool = False,
        smoothing: bool = True,
        memory: Optional[float] = None,
        refine: bool = True,
        coupling_order: int = 1,
    ) -> None:
        self.poly_order = _integer("poly_order", poly_order, 1, 9)
        self.coupling_order = _integer("coupling_order", coupling_order, 1, 3)
        self.harmonics = None if harmonics is None else _integer("harmonics", harmonics, 0, 8)
        self.omega = _positive("omega", omega, "a positive angular frequency in rad/s (or None)")
        self.memory = _positive("memory", memory, "a positive time in seconds (or None)")
        if family is not None and not isinstance(family, str):
            raise TypeError(f"family must be None, 'all', 'families' or 'odd', not {family!r}.")
        if family is not None and family not in ("all", "families", "odd"):
            raise ValueError(f"family must be 'all', 'families' or 'odd', not {family!r}.")
        self.family = family or "all"
        self.f32 = _flag("f32", f32)
        self.smoothing = _flag("smoothing", smoothing)
        self.refine = _flag("refine", refine)
        self._fit: Optional[Fit] = None
        # (name, t, x, v, u) of the fit, for pickling; None for a Stream's model.
        self._data: Optional[Tuple] = None
        # The date and time t = 0 stands for, when the fit's t held dates and times.
        self._t_origin: Optional[np.datetime64] = None
        # The file of a system's model (a recording with an electrical column), else None.
        self._system_path: Optional[str] = None
        # A system fitted from arrays: its columns and load, for pickling.
        self._system_data: Optional[Dict[str, Any]] = None
        # The load resistance a system's report is for (load_ohms), else None.
        self._load_ohms: Optional[float] = None

    def _options(self) -> Tuple:
        return (
            self.omega,
            self.harmonics,
            self.poly_order,
            self.family,
            self.f32,
            self.smoothing,
            self.memory,
        )

    def _option_dict(self) -> Dict[str, Any]:
        return dict(poly_order=self.poly_order, harmonics=self.harmonics, omega=self.omega,
                    family=self.family, f32=self.f32, smoothing=self.smoothing,
                    memory=self.memory, refine=self.refine,
                    coupling_order=self.coupling_order)

    # -- fitting -------------------------------------------------------------------------
    def fit(self, x=None, t=None, v=None, u=None, dt=None, *, V=None, i=None,
            load_ohms=None) -> "Model":
        """Identifies the equation from displacement ``x`` (and a measured velocity ``v``,
        excitation ``u`` when there are), sampled at times ``t`` (seconds, or dates and
        times: then seconds from the first sample) or every ``dt`` seconds. ``x`` may be a
        pandas DataFrame with columns t, x and optionally v, u (and V, i); without a column
        t, its index gives the times when it is one of dates and times (a ``DatetimeIndex``),
        of durations, or is named t.

        With an electrical channel, ``V`` (the voltage across the load) or ``i`` (the
        current), the model is the harvester's system, as ``lssi identify`` finds it for a
        file with these columns: ``x'' = …`` and ``V' = …`` (``i' = …``), each sparse over
        one shared library of the states (``equations()``, ``coefficients()``). ``x`` may
        then be None with ``v`` given: x is v integrated, its drift removed, as the command
        does. ``load_ohms``, the load the voltage was recorded across, adds the harvester in
        physical terms (``harvester()``: coupling factor, time constant, power against load).
        Raises ValueError for bad input or when no model comes out."""
        electrical: Dict[str, Any] = {"V": V, "i": i}
        frame = _is_frame(x)
        if frame:
            x, t, v, u = _frame(x, t, v, u, electrical)
        load = _positive("load_ohms", load_ohms, "a positive resistance in ohms (or None)")
        if all(e is None for e in electrical.values()):
            if load is not None:
                raise ValueError(
                    "load_ohms applies to a system: give the voltage V across that load "
                    "(or the current i) beside x."
                )
            if self.coupling_order != 1:
                raise ValueError(
                    f"coupling_order={self.coupling_order} applies to a system: give the "
                    "voltage V across the load (or the current i) beside x."
                )
            if x is None:
                raise ValueError(
                    "give the displacement x (a velocity v alone is enough only for a system, "
                    "with V or i)."
                )
            t, x, v, u, origin = _columns(x, t, v, u, dt)
            self._run("array", t, x, v, u)
            self._t_origin = origin
            return self
        t, columns, origin = _system_columns(x, t, v, u, dt, electrical)
        self._fit = _lssi.fit_system(
            t, columns["x"], columns["v"], columns["u"], columns["V"], columns["i"],
            *self._options(), coupling_order=self.coupling_order, load_ohms=load,
            refine=self.refine,
        )
        self._data = None
        self._system_path = None
        self._system_data = dict(t=t, load_ohms=load, **columns)
        self._load_ohms = load
        self._t_origin = origin
        return self

    def _run(self, name: str, t, x, v, u) -> None:
        self._fit = _lssi.fit(t, x, v, u, *self._options(), refine=self.refine, name=name)
        self._system_path = None
        self._system_data = None
        self._load_ohms = None
        self._data = (name, t, x, v, u)

    def _is_system(self) -> bool:
        return isinstance(self._fit, _lssi.SystemFit)

    def _fitted(self) -> Fit:
        if self._fit is None:
            raise ValueError("the model is not fitted yet: call fit() first.")
        return self._fit

    def _single(self, method: str) -> Fit:
        """The single-equation fit; ValueError naming ``method`` for a system's model."""
        fit = self._fitted()
        if self._is_system():
            raise ValueError(
                f"{method}() is for a single equation; this model is a system "
                f"({', '.join(self.equations())}): use equations() and to_json()."
            )
        return fit

    def is_system(self) -> bool:
        """Whether the model is a system of equations (a recording with an electrical
        column, ``V`` or ``i``)."""
        self._fitted()
        return self._is_system()

    def states(self) -> List[str]:
        """The states: ``["x", "v"]``, and for a system its electrical ones (``V``, ``i``)."""
        fit = self._fitted()
        return list(fit.states()) if self._is_system() else ["x", "v"]

    def equations(self) -> Dict[str, Dict[str, float]]:
        """Each equation's active terms and coefficients, by target: ``{"x''": {"x": …},
        "V'": {"V": …, "v": …}}`` (a single equation: ``{"x''": …}``, its active terms). An
        electrical channel proportional to v has the algebraic ``{"V": {"v": c}}`` instead of
        ``V'``, and the v coefficient of x'' then holds the beam's and the electrical damping."""
        fit = self._fitted()
        if self._is_system():
            return {target: dict(terms) for target, terms in fit.equations()}
        return {"x''": dict(fit.terms())}

    # -- results -------------------------------------------------------------------------
    def equation(self) -> str:
        """The reported equation as one line, ``lssi identify``'s first (with ± a standard
        error on each coefficient when refined)."""
        if self._is_system():
            return "\n".join(self._fitted().text().splitlines()[: len(self.equations())])
        return self._fitted().equation()

    def print(self, unit: str = "[x]") -> None:
        """Prints the report ``lssi identify`` prints (``--no-refine``'s when refine=False),
        x in ``unit`` (its ``--unit``)."""
        if not isinstance(unit, str):
            raise TypeError(f"unit must be a string, not {unit!r}.")
        if self._is_system():
            print(self._fitted().text(), end="")
            return
        print(self._fitted().text(unit), end="")

    def feature_names(self) -> List[str]:
        """The library's term names, in order (``1``, ``x``, ``v``, ``x^2``, …, ``cos(21.4t)``;
        for a system the shared library of every equation, with ``V``, ``x*V``, …)."""
        return self._fitted().feature_names()

    def _dense(self, terms) -> Dict[str, float]:
        active = dict(terms)
        return {name: active.get(name, 0.0) for name in self._fitted().feature_names()}

    def coefficients(self):
        """Every library term's coefficient in physical units (0 for inactive terms), of the
        reported model: the refined one when it was taken (``report()["model"]`` says).

        For a system, a dict per equation: ``{"x''": {term: coef, …}, "V'": {…}}``, every
        term of the shared library in each (of the reported system: refined unless
        ``refine=False``)."""
        if self._is_system():
            return {target: self._dense(terms) for target, terms in self._fitted().equations()}
        return self._dense(self._single("coefficients").terms())

    def streaming_coefficients(self):
        """As ``coefficients()``, of the streaming identifier's model (what a device computes
        for the same samples; the JSON's ``streaming_terms``). For a system, its
        ``coefficients()`` when the reported system is the streaming one (``refine=False``, or
        refinement not taken); a refined system keeps no streaming model: ValueError."""
        if self._is_system():
            if self.report().get("model") == "refined":
                raise ValueError(
                    "streaming_coefficients(): this system was refined, and a refined system "
                    "keeps no streaming model: fit with refine=False for the device's model."
                )
            return self.coefficients()
        return self._dense(self._single("streaming_coefficients").streaming_terms())

    def standard_errors(self):
        """The standard error of each active term's coefficient (NaN where it could not be
        computed): the refined model's, or, when refinement kept the streaming model, the
        larger of its support's refined standard error and the distance between the two
        estimates; None with refine=False (the device's model has none). For a system, a dict per equation of the active terms' standard
        errors (the report's least-squares ones; NaN where there is none)."""
        if self._is_system():
            return {
                e["target"]: {
                    term["term"]: float("nan") if term.get("se") is None else term["se"]
                    for term in e["terms"]
                }
                for e in self.report()["equations"]
            }
        se = self._single("standard_errors").standard_errors()
        return None if se is None else dict(se)

    def harvester(self) -> Optional[Dict[str, Any]]:
        """A system's harvester in physical terms for the load ``load_ohms`` given to
        ``fit``/``identify`` (the report's ``harvester``: coupling factor ``coupling_k2``,
        time constant, mean power measured and predicted, power against load and forcing
        frequency); None without ``load_ohms``. ValueError for a single equation."""
        if not self._is_system():
            self._single("harvester")
        return self.report().get("harvester")

    def to_json(self) -> str:
        """The object ``lssi identify --json`` prints for the same data and options
        (``--f64`` unless f32, ``--no-refine`` when refine=False)."""
        return self._fitted().json()

    def report(self) -> Dict[str, Any]:
        """``to_json()`` as a dict."""
        return json.loads(self.to_json())

    # -- using the model -----------------------------------------------------------------
    def simulate(self, x0, t, u=None):
        """Free run of the reported model from ``x0`` (x, or (x, v)) on the times ``t``
        (seconds, or dates and times as for ``fit``); ``u`` the excitation on the same grid,
        needed when the model has a ``u`` term. Returns (x, v); NaN after a divergence.

        ``x0`` may also be a mapping of every state name to its initial value
        (``{"x": …, "v": …}``; a system's: ``{"x": …, "v": …, "V": …}``, ``states()``): the
        result is then a dict of state names to arrays, in the recording's units (for a
        system, ``lssi simulate``'s free run). A system's model takes only a mapping. An
        algebraic electrical equation (``equations()`` key ``V`` or ``i``, no prime: a channel
        proportional to v, as across a coil of negligible inductance) is computed from the
        simulated v at every time; its value in ``x0`` is not used."""
        fit = self._fitted()
        if self._is_system():
            return self._simulate_system(x0, t, u)
        mapping = isinstance(x0, Mapping)
        if mapping:
            x_init, v_init = self._start(x0)
        elif np.ndim(x0) == 0:
            x_init, v_init = x0, 0.0
        else:
            if len(x0) != 2:
                raise ValueError(f"x0 must be x or (x, v), not {x0!r}.")
            x_init, v_init = x0[0], x0[1]
        try:
            x_init, v_init = float(x_init), float(v_init)
        except (TypeError, ValueError):
            raise TypeError(f"x0 must be a number or a pair of numbers (x, v), not {x0!r}.") from None
        if not (np.isfinite(x_init) and np.isfinite(v_init)):
            raise ValueError(f"x0 must be finite, not {x0!r}.")
        t, _ = _times(t, origin=self._t_origin)
        _increasing(t)
        u = self._input(u, t.shape[0], "simulate")
        xs, vs = fit.simulate(t, x_init, v_init, u)
        return {"x": xs, "v": vs} if mapping else (xs, vs)

    def _start(self, x0) -> List[float]:
        """The initial state from a mapping of every state name to its value, in
        ``states()`` order."""
        states = self.states()
        kind = "system's " if self._is_system() else "model's "
        missing = [name for name in states if name not in x0]
        if missing:
            raise ValueError(
                f"x0 has no initial value for the state(s) {missing}; the {kind}states are {states}."
            )
        unknown = [name for name in x0 if name not in states]
        if unknown:
            fitted_without = [name for name in unknown if name in ELECTRICAL]
            why = (
                f"; it was fitted without {' or '.join(fitted_without)}" if fitted_without else ""
            )
            raise ValueError(
                f"x0 names {unknown}, which are not states of this "
                f"{'system' if self._is_system() else 'model'} (its states are {states}{why})."
            )
        start = []
        for name in states:
            try:
                value = float(x0[name])
            except (TypeError, ValueError):
                raise TypeError(f"x0[{name!r}] must be a number, not {x0[name]!r}.") from None
            if not np.isfinite(value):
                raise ValueError(f"x0[{name!r}] must be finite, not {value!r}.")
            start.append(value)
        return start

    def _simulate_system(self, x0, t, u) -> Dict[str, np.ndarray]:
        fit = self._fitted()
        states = self.states()
        if not isinstance(x0, Mapping):
            raise TypeError(
                f"x0 must be a mapping of the system's states {states} to initial values "
                f"(e.g. {{'x': 0.0, 'v': 0.0, ...}}), not {x0!r}."
            )
        start = self._start(x0)
        t, _ = _times(t, origin=self._t_origin)
        _increasing(t)
        if u is None:
            if fit.uses_input():
                raise ValueError(
                    "u: the model has an excitation term u, so simulate needs the excitation u "
                    "on the same grid as t."
                )
        else:
            u = _column("u", u)
            if u.shape[0] != t.shape[0]:
                raise ValueError(f"u has {u.shape[0]} samples but t has {t.shape[0]}.")
        columns = fit.simulate(t, start, u)
        return dict(zip(states, columns))

    def _input(self, u, n: int, method: str) -> Optional[np.ndarray]:
        if u is None:
            if self._fitted().uses_input():
                coefficient = (
                    "" if self._is_system()
                    else f" (coefficient {dict(self._fitted().terms()).get('u')})"
                )
                raise ValueError(
                    f"u: the model has an excitation term u{coefficient}, so {method} needs "
                    "the excitation u on the same grid as t."
                )
            return None
        return _column("u", u, n)

    def score(self, x=None, t=None, u=None, v=None, V=None, i=None):
        """Free-run fit of the measured ``x``: 1 − NRMSE² (1 is perfect, 0 no better than the
        mean, negative worse, -inf when the free run diverges), simulated from x[0] with
        v[0] from a first difference (or the measured ``v[0]``).

        For a system, a dict of scores per measured state (``{"x": …, "V": …}``, and ``v``
        when given): the free run from the first sample's state (as ``lssi simulate``
        starts it: v measured, or x's slope over its first samples; x integrated from v when
        x is None), driven by ``u``. Every electrical state of the model (``V``, ``i``) must
        be given: its first value starts the run. A chaotic record (a bistable harvester
        hopping between its wells) departs from any free run after a few periods, however
        right the model: score short spans, or compare statistics (``harvester()``'s mean
        power)."""
        fit = self._fitted()
        if self._is_system():
            return self._score_system(x, t, u, v, {"V": V, "i": i})
        for name, value in (("V", V), ("i", i)):
            if value is not None:
                raise ValueError(
                    f"{name}: this model was fitted without an electrical channel (a single "
                    f"equation, states {self.states()}), so it cannot score {name}; fit a "
                    f"system with Model().fit(x, t=t, {name}={name})."
                )
        if x is None:
            raise ValueError("give the measured displacement x to score.")
        if t is None:
            raise ValueError("give the sample times t.")
        t, x, v, u, _ = _columns(x, t, v, u, minimum=3, origin=self._t_origin)
        u = self._input(u, t.shape[0], "score")
        v0 = v[0] if v is not None else (x[1] - x[0]) / (t[1] - t[0])
        xs, _ = fit.simulate(t, float(x[0]), float(v0), u)
        return _score("x", xs, x)

    def _score_system(self, x, t, u, v, electrical: Dict[str, Any]) -> Dict[str, float]:
        states = self.states()
        if "x2" in states:
            raise ValueError(
                f"score takes one displacement x, and this system has two ({states}): "
                "simulate it with simulate(x0, t, u=u) from a mapping of its states and "
                "compare the arrays with the measured ones."
            )
        for name, value in electrical.items():
            if value is not None and name not in states:
                raise ValueError(
                    f"{name}: this system's states are {states}; it was fitted without {name}, "
                    f"so it cannot score {name}."
                )
        missing = [name for name in states[2:] if electrical[name] is None]
        if missing:
            raise ValueError(
                f"{missing[0]}: the system has the electrical state {missing[0]}, so score needs "
                f"the measured {missing[0]} (its first value starts the free run)."
            )
        if t is None:
            raise ValueError("give the sample times t.")
        t, columns, _ = _system_columns(x, t, v, u, None, electrical, minimum=3,
                                        origin=self._t_origin)
        u = self._input(columns["u"], t.shape[0], "score")
        start, x_run = _lssi.system_start(t, columns["x"], columns["v"], columns["V"],
                                          columns["i"])
        sim = self._fitted().simulate(t, list(start), u)
        sim = dict(zip(states, sim))
        return {
            name: _score(name, sim[name], columns[name])
            for name in states
            if columns.get(name) is not None
        }
    def stream(self) -> "Stream":
        """A ``Stream`` with this fit's configuration: fed the same samples, it gives the same
        streaming model as the fit (``streaming_coefficients()``)."""
        self._single("stream")
        return Stream(like=self)

    # -- pickling ------------------------------------------------------------------------
    def __getstate__(self) -> Dict[str, Any]:
        state: Dict[str, Any] = {"version": _PICKLE_VERSION, "options": self._option_dict(),
                                 "fit": None, "t_origin": self._t_origin}
        if self._system_path is not None:
            state["system"] = dict(path=self._system_path, load_ohms=self._load_ohms,
                                   json=self.to_json())
        elif self._system_data is not None:
            state["system_data"] = dict(self._system_data, json=self.to_json())
        elif self._fit is not None:
            if self._data is None:
                raise TypeError(
                    "a Stream's model keeps none of the samples it came from, so it cannot be "
                    "pickled; pickle the Stream's report() (a dict), or a Model fitted on the samples."
                )
            name, t, x, v, u = self._data
            state["fit"] = dict(name=name, t=t, x=x, v=v, u=u, json=self.to_json())
        return state

    def __setstate__(self, state: Dict[str, Any]) -> None:
        if state.get("version") != _PICKLE_VERSION:
            raise ValueError(
                f"this pickled lssi.Model has state version {state.get('version')!r}; "
                f"this lssi reads version {_PICKLE_VERSION}."
            )
        self.__init__(**state["options"])
        self._t_origin = state.get("t_origin")
        system = state.get("system")
        if system is not None:
            fitted = identify(system["path"], load_ohms=system.get("load_ohms"),
                              **state["options"])
            self._fit, self._system_path = fitted._fit, fitted._system_path
            self._load_ohms = fitted._load_ohms
            if self._system_path is None or self.to_json() != system["json"]:
                raise ValueError(
                    f"this lssi identifies another model from {system['path']} than the one "
                    "pickled (the file changed, or another version?): identify it again."
                )
            return
        data = state.get("system_data")
        if data is not None:
            origin = self._t_origin
            self.fit(data["x"], t=data["t"], v=data["v"], u=data["u"], V=data["V"],
                     i=data["i"], load_ohms=data["load_ohms"])
            self._t_origin = origin
            if self.to_json() != data["json"]:
                raise ValueError(
                    "this lssi identifies another system from the pickled model's samples than "
                    "the one pickled (a different version?): refit them instead of unpickling."
                )
            return
        fit = state["fit"]
        if fit is not None:
            self._run(fit["name"], fit["t"], fit["x"], fit["v"], fit["u"])
            if self.to_json() != fit["json"]:
                raise ValueError(
                    "this lssi identifies another model from the pickled model's samples than "
                    "the one pickled (a different version?): refit them instead of unpickling."
                )

    def __repr__(self) -> str:
        state = self.equation() if self._fit is not None else "not fitted"
        return f"lssi.Model({state})"


class Stream:
    """Online identification: ``push`` blocks of samples, ask for the ``model()`` any time
    (the streaming identifier's model, as a device computes it: not refined).

    ``Stream(like=model)`` takes a fitted model's configuration (then the same samples give
    the model's ``streaming_coefficients()``). Otherwise the configuration is chosen, as
    ``lssi identify`` chooses it, from the first ``calibrate`` samples pushed (they are then
    fed in too); the options are those of ``Model``. Every block must carry the channels
    (v, u) the stream was configured with, no more and no fewer: ValueError otherwise.
    """

    def __init__(
        self,
        poly_order: int = 3,
        harmonics: Optional[int] = None,
        omega: Optional[float] = None,
        family: Optional[str] = None,
        f32: bool = False,
        smoothing: bool = True,
        memory: Optional[float] = None,
        calibrate: int = 8192,
        like: Optional[Model] = None,
    ) -> None:
        self._options = Model(poly_order, harmonics, omega, family, f32, smoothing, memory,
                              refine=False)
        self._calibrate = _integer("calibrate", calibrate, MIN_SAMPLES, 2**62)
        if like is not None and not isinstance(like, Model):
            raise TypeError(f"like must be a fitted lssi.Model, not {like!r}.")
        if like is not None and like._is_system():
            raise ValueError(
                f"like: the model is a system ({', '.join(like.equations())}); a Stream "
                "identifies the single equation x'' from x (and v, u): fit the system whole "
                "with Model().fit(x, t=t, u=u, V=V)."
            )
        self._raw = None if like is None else _lssi.RawStream.like(like._fitted())
        self._t_origin = None if like is None else like._t_origin
        if like is not None:
            self._options = Model(**{**like._option_dict(), "refine": False})
        self._pending: List[Tuple] = []
        # (v, u) given in the blocks so far, before the stream is configured.
        self._channels: Optional[Tuple[bool, bool]] = None
        self._count = 0
        self._last_t: Optional[float] = None
        self._t_dates: Optional[bool] = None if like is None else like._t_origin is not None
        self.rejected = 0

    def _check_channels(self, v, u) -> None:
        given = (v is not None, u is not None)
        if self._raw is not None:
            expected, source = tuple(self._raw.channels()), "this stream was configured"
        elif self._channels is not None:
            expected, source = self._channels, "this stream's first block came"
        else:
            return
        for i, (name, what) in enumerate((("v", "a measured velocity"), ("u", "an excitation"))):
            if given[i] and not expected[i]:
                raise ValueError(
                    f"{name}: {source} without {what} {name}, so a block with {name} cannot be "
                    f"fed in (the identifier would reject every sample); push it without "
                    f"{name}, or start a stream whose calibration (or model) has {name}."
                )
            if expected[i] and not given[i]:
                raise ValueError(
                    f"{name}: {source} with {what} {name}, so every block needs {name}; "
                    "this one has none."
                )

    def push(self, x, t=None, v=None, u=None, V=None, i=None) -> "Stream":
        """Feeds a block: arrays (or a DataFrame with columns t, x[, v, u]) of one length.
        The block is checked before anything is fed in (ValueError names the problem).
        A Stream identifies the single equation: an electrical channel (``V``, ``i``, as an
        argument or a DataFrame column) is a ValueError naming it (fit a system whole with
        ``Model().fit(..., V=V)``)."""
        electrical = {"V": V, "i": i}
        if _is_frame(x):
            for name in ELECTRICAL:
                if electrical[name] is None and name in x.columns:
                    electrical[name] = x[name]
        for name, value in electrical.items():
            if value is not None:
                raise ValueError(
                    f"{name}: a Stream identifies the single equation x'' from x (and v, u), "
                    f"so a block with an electrical channel {name} cannot be fed in; fit the "
                    f"system whole with Model().fit(x, t=t, u=u, {name}={name})."
                )
        t, x, v, u, origin = _columns(x, t, v, u, minimum=1, origin=self._t_origin)
        dates = origin is not None
        if self._t_dates is not None and dates != self._t_dates:
            raise ValueError(
                "t: this stream's times were "
                + ("dates and times" if self._t_dates else "seconds")
                + "; every block's t must be too."
            )
        self._check_channels(v, u)
        if self._last_t is not None and t[0] <= self._last_t:
            raise ValueError(f"t must increase: the block starts at {t[0]}, after {self._last_t}.")
        self._t_dates = dates
        self._t_origin = origin
        self._last_t = float(t[-1])
        if self._raw is None:
            self._channels = (v is not None, u is not None)
            self._pending.append((t, x, v, u))
            self._count += t.shape[0]
            if self._count >= self._calibrate:
                self._start()
            return self
        self.rejected += self._raw.push(t, x, v, u)
        return self

    def _start(self) -> None:
        cat = lambda i: None if self._pending[0][i] is None else np.concatenate([p[i] for p in self._pending])
        t, x, v, u = cat(0), cat(1), cat(2), cat(3)
        self._raw = _lssi.RawStream.calibrated(t, x, v, u, *self._options._options())
        self._pending = []
        self.rejected += self._raw.push(t, x, v, u)

    def model(self) -> Model:
        """The streaming model from everything pushed so far (it changes nothing that
        follows); its ``to_json()`` is what ``lssi identify --no-refine --json`` prints."""
        if self._raw is None:
            if not self._pending:
                raise ValueError("nothing was pushed yet.")
            self._start()
        m = Model(**self._options._option_dict())
        m._fit = self._raw.model()
        m._t_origin = self._t_origin
        return m


def _path(path) -> str:
    """A file path given as str, bytes or os.PathLike, as text (``str(b"a.csv")`` would be
    the name ``b'a.csv'``); TypeError for anything else (None, a number)."""
    try:
        return os.fsdecode(os.fspath(path))
    except TypeError:
        if _is_frame(path) or isinstance(path, (dict, np.ndarray, list, tuple)):
            kind = "a DataFrame" if _is_frame(path) else f"a {type(path).__name__}"
            raise TypeError(
                f"path must be a file path (str, bytes or os.PathLike), not {kind}: fit "
                "columns in memory with lssi.Model().fit(...)."
            ) from None
        shown = repr(path)
        if len(shown) > 60:
            shown = f"a {type(path).__name__}"
        raise TypeError(
            f"path must be a file path (str, bytes or os.PathLike), not {shown}."
        ) from None


def read_recording(path: str):
    """Reads a recording file as ``lssi identify`` does: (t, x, v or None, u or None)."""
    return _lssi.read_recording(_path(path))


def identify(path, load_ohms=None, **options) -> Model:
    """``lssi identify FILE --f64`` with the options of ``Model`` (``refine=False``:
    ``--no-refine``; ``f32=True``: ``--f32``). Returns the fitted Model; ValueError says why
    a file cannot be used.

    A file with an electrical column (``V``, the voltage across the load, or ``i``, the
    current) is a harvester's system, as for the command: the Model holds its equations
    (``equations()``: ``{"x''": {...}, "V'": {...}}``, ``states()``: ``["x", "v", "V"]``),
    ``to_json()`` is the command's ``--json`` object, and ``simulate`` takes and returns
    mappings of state names; a system is refined on simulation error as the command refines
    it (``refine=False``: the streaming system identifier's, ``--no-refine``).
    ``load_ohms`` (the command's ``--load-ohms``) adds the harvester in physical terms
    (``Model.harvester()``); ``coupling_order`` is its ``--coupling-order``."""
    m = Model(**options)
    path = _path(path)
    load = _positive("load_ohms", load_ohms, "a positive resistance in ohms (or None)")
    system = _lssi.identify_system(str(path), *m._options(), coupling_order=m.coupling_order,
                                   load_ohms=load, refine=m.refine)
    if system is not None:
        m._fit = system
        m._system_path = str(path)
        m._load_ohms = load
        return m
    for name, value, default in (("load_ohms", load, None), ("coupling_order", m.coupling_order, 1)):
        if value != default:
            raise ValueError(
                f"{path}: {name} applies to a recording with an electrical column (V or i), "
                "and this one has none."
            )
    t, x, v, u = read_recording(path)
    m._run(str(path), t, x, v, u)
    return m
