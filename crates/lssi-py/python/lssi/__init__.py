"""lssi: streaming sparse identification of a vibration energy harvester's equation of motion.

The same identifier as the ``lssi`` command and the firmware (Rust, in f32 or f64), behind
a PySINDy-like API::

    import numpy as np, lssi
    m = lssi.Model(poly_order=3, harmonics=1)
    m.fit(x, t=t)                  # x'' = f(x, x', t) from the displacement alone
    m.print()                      # x'' = 336.68 x - 0.40135 v - 7.9552e8 x^3 + ...
    m.coefficients()               # {"1": 0.0, "x": 336.68, ...}
    x_sim, v_sim = m.simulate((x[0], 0.0), t)

``Model.to_json()`` is the object ``lssi identify --no-refine --json`` prints for the same data and
options. ``Stream`` identifies online, block by block. ``lssi.dask.identify_many`` maps the
identification over a Dask cluster.
"""

from __future__ import annotations

import json
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _lssi

__all__ = ["Model", "Stream", "identify", "read_recording", "Fit"]

Fit = _lssi.Fit

#: The fewest samples a fit accepts (a library of 16 terms needs about 2·16 rows in each
#: held-out half once the derivative window is full).
MIN_SAMPLES = 64


def _column(name: str, a: Any, n: Optional[int] = None) -> np.ndarray:
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


def _columns(x, t=None, v=None, u=None, dt=None, minimum: int = MIN_SAMPLES):
    """Checks and converts (x, t, v, u); a pandas DataFrame in x supplies its t/x/v/u columns."""
    if hasattr(x, "columns") and hasattr(x, "__getitem__"):
        frame = x
        if "x" not in frame.columns:
            raise ValueError(f"the DataFrame has no column 'x' (it has {list(frame.columns)}).")
        x = frame["x"].to_numpy()
        if t is None and "t" in frame.columns:
            t = frame["t"].to_numpy()
        if v is None and "v" in frame.columns:
            v = frame["v"].to_numpy()
        if u is None and "u" in frame.columns:
            u = frame["u"].to_numpy()
    x = _column("x", x)
    n = x.shape[0]
    if n < minimum:
        raise ValueError(f"x has {n} samples; at least {minimum} are needed.")
    if t is None:
        if dt is None:
            raise ValueError("give the sample times t, or the sample period dt.")
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, not {dt}.")
        t = np.arange(n, dtype=np.float64) * float(dt)
    elif dt is not None:
        raise ValueError("give either t or dt, not both.")
    t = _column("t", t, n)
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise ValueError(
            f"t must increase: t[{i + 1}] = {t[i + 1]} does not come after t[{i}] = {t[i]}."
        )
    v = None if v is None else _column("v", v, n)
    u = None if u is None else _column("u", u, n)
    return t, x, v, u


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


class Model:
    """The equation of motion x'' = f(x, x', t) of a recording, as ``lssi identify`` finds it.

    Parameters mirror the command's flags: ``poly_order`` (``--poly-order``), ``harmonics``
    (``--harmonics``: sin/cos(kΩt) for k = 1..H), ``omega`` (``--omega``, rad/s; None:
    estimated from the data), ``family`` (None or "all", "families", "odd"), ``f32``
    (compute in f32 as a device does; the default here is f64, ``--f64``), ``smoothing``
    (False: ``--no-smoothing``), ``memory`` (``--memory``, seconds).
    """

    def __init__(
        self,
        poly_order: int = 3,
        harmonics: int = 1,
        omega: Optional[float] = None,
        family: Optional[str] = None,
        f32: bool = False,
        smoothing: bool = True,
        memory: Optional[float] = None,
    ) -> None:
        if not (isinstance(poly_order, (int, np.integer)) and 1 <= poly_order <= 9):
            raise ValueError(f"poly_order must be an integer from 1 to 9, not {poly_order!r}.")
        if not (isinstance(harmonics, (int, np.integer)) and 0 <= harmonics <= 8):
            raise ValueError(f"harmonics must be an integer from 0 to 8, not {harmonics!r}.")
        if omega is not None and not (np.isfinite(omega) and omega > 0):
            raise ValueError(f"omega must be a positive angular frequency in rad/s, not {omega!r}.")
        if memory is not None and not (np.isfinite(memory) and memory > 0):
            raise ValueError(f"memory must be a positive time in seconds, not {memory!r}.")
        if family is not None and family not in ("all", "families", "odd"):
            raise ValueError(f"family must be 'all', 'families' or 'odd', not {family!r}.")
        self.poly_order = int(poly_order)
        self.harmonics = int(harmonics)
        self.omega = None if omega is None else float(omega)
        self.family = family or "all"
        self.f32 = bool(f32)
        self.smoothing = bool(smoothing)
        self.memory = None if memory is None else float(memory)
        self._fit: Optional[Fit] = None

    # -- fitting -------------------------------------------------------------------------
    def fit(self, x, t=None, v=None, u=None, dt=None) -> "Model":
        """Identifies the equation from displacement ``x`` (and a measured velocity ``v``,
        excitation ``u`` when there are), sampled at times ``t`` or every ``dt`` seconds.
        ``x`` may be a pandas DataFrame with columns t, x and optionally v, u.
        Raises ValueError for bad input or when no model comes out."""
        t, x, v, u = _columns(x, t, v, u, dt)
        self._fit = _lssi.fit(t, x, v, u, *_options(self))
        return self

    def _fitted(self) -> Fit:
        if self._fit is None:
            raise ValueError("the model is not fitted yet: call fit() first.")
        return self._fit

    # -- results -------------------------------------------------------------------------
    def equation(self) -> str:
        """The selected equation as one line, e.g. ``x'' = 336.68 x - 0.40135 v + ...``."""
        return self._fitted().equation()

    def print(self) -> None:
        """Prints the report ``lssi identify --no-refine`` prints (equation, configuration, sweep)."""
        print(self._fitted().text(), end="")

    def feature_names(self) -> List[str]:
        """The library's term names, in order (``1``, ``x``, ``v``, ``x^2``, …, ``cos(21.4t)``)."""
        return self._fitted().feature_names()

    def coefficients(self) -> Dict[str, float]:
        """Every library term's coefficient in physical units (0 for inactive terms)."""
        fit = self._fitted()
        active = dict(fit.terms())
        return {name: active.get(name, 0.0) for name in fit.feature_names()}

    def standard_errors(self) -> Optional[Dict[str, float]]:
        """Standard errors of the coefficients: not available yet (the identifier does not
        compute them), so None."""
        self._fitted()
        return None

    def to_json(self) -> str:
        """The object ``lssi identify --no-refine --json`` prints for the same data and options
        (the streaming model; the command refines it on simulation error by default)."""
        return self._fitted().json()

    def report(self) -> Dict[str, Any]:
        """``to_json()`` as a dict."""
        return json.loads(self.to_json())

    # -- using the model -----------------------------------------------------------------
    def simulate(self, x0, t, u=None) -> Tuple[np.ndarray, np.ndarray]:
        """Free run from ``x0`` (x, or (x, v)) on the times ``t``; ``u`` the excitation on
        the same grid when the model has a ``u`` term. Returns (x, v); NaN after a
        divergence."""
        fit = self._fitted()
        if np.ndim(x0) == 0:
            x_init, v_init = float(x0), 0.0
        else:
            if len(x0) != 2:
                raise ValueError(f"x0 must be x or (x, v), not {x0!r}.")
            x_init, v_init = float(x0[0]), float(x0[1])
        t = _column("t", t)
        u = None if u is None else _column("u", u, t.shape[0])
        return fit.simulate(t, x_init, v_init, u)

    def score(self, x, t, u=None) -> float:
        """Free-run fit of the measured ``x``: 1 − NRMSE² (1 is perfect, 0 no better than the
        mean, negative worse), simulated from x[0] with v[0] from a first difference."""
        t, x, _, u = _columns(x, t, None, u, minimum=3)
        v0 = (x[1] - x[0]) / (t[1] - t[0])
        xs, _ = self.simulate((x[0], v0), t, u)
        if not np.all(np.isfinite(xs)):
            return float("-inf")
        var = float(np.var(x))
        if var == 0.0:
            raise ValueError("x is constant: a score needs a signal that varies.")
        return 1.0 - float(np.mean((xs - x) ** 2)) / var

    def stream(self) -> "Stream":
        """A ``Stream`` with this fit's configuration: fed the same samples, it gives the same
        model as the fit."""
        return Stream(like=self)

    def __repr__(self) -> str:
        state = self.equation() if self._fit is not None else "not fitted"
        return f"lssi.Model({state})"


class Stream:
    """Online identification: ``push`` blocks of samples, ask for the ``model()`` any time.

    ``Stream(like=model)`` takes a fitted model's configuration (then the same samples give
    the same model as the fit). Otherwise the configuration is chosen, as ``lssi identify``
    chooses it, from the first ``calibrate`` samples pushed (they are then fed in too); the
    options are those of ``Model``.
    """

    def __init__(
        self,
        poly_order: int = 3,
        harmonics: int = 1,
        omega: Optional[float] = None,
        family: Optional[str] = None,
        f32: bool = False,
        smoothing: bool = True,
        memory: Optional[float] = None,
        calibrate: int = 8192,
        like: Optional[Model] = None,
    ) -> None:
        self._options = Model(poly_order, harmonics, omega, family, f32, smoothing, memory)
        self._calibrate = int(calibrate)
        if self._calibrate < MIN_SAMPLES:
            raise ValueError(f"calibrate must be at least {MIN_SAMPLES} samples.")
        self._raw = None if like is None else _lssi.RawStream.like(like._fitted())
        self._pending: List[Tuple] = []
        self._count = 0
        self._last_t: Optional[float] = None
        self.rejected = 0

    def push(self, x, t=None, v=None, u=None) -> "Stream":
        """Feeds a block: arrays (or a DataFrame with columns t, x[, v, u]) of one length.
        The block is checked before anything is fed in (ValueError names the problem)."""
        t, x, v, u = _columns(x, t, v, u, minimum=1)
        if self._last_t is not None and t[0] <= self._last_t:
            raise ValueError(f"t must increase: the block starts at {t[0]}, after {self._last_t}.")
        self._last_t = float(t[-1])
        if self._raw is None:
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
        self._raw = _lssi.RawStream.calibrated(t, x, v, u, *_options(self._options))
        self._pending = []
        self.rejected += self._raw.push(t, x, v, u)

    def model(self) -> Model:
        """The model from everything pushed so far (it changes nothing that follows)."""
        if self._raw is None:
            if not self._pending:
                raise ValueError("nothing was pushed yet.")
            self._start()
        m = Model.__new__(Model)
        m.__dict__.update(self._options.__dict__)
        m._fit = self._raw.model()
        return m


def read_recording(path: str):
    """Reads a recording file as ``lssi identify`` does: (t, x, v or None, u or None)."""
    return _lssi.read_recording(str(path))


def identify(path, **options) -> Model:
    """``lssi identify FILE`` with the options of ``Model`` (f32=False by default, as
    ``--f64``). Returns the fitted Model; ValueError says why a file cannot be used."""
    m = Model(**options)
    m._fit = _lssi.identify_file(str(path), *_options(m))
    return m
