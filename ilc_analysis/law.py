r"""The learning law of eq (11): gains and forgetting factors, shared by every stage.

The open-closed-loop PD-ILC law with forgetting (eq 11) is

.. math::

    u_{i+1}(t) = a(i,t)\,u_0(t) + (1-a(i,t))\,u_i(t)
        + \Phi_1\dot e_i(t) + \Psi_1 e_i(t) + \Phi_2\dot e_{i+1}(t) + \Psi_2 e_{i+1}(t),

with :math:`e_i = y_d - y_i`. The variable forgetting factor (eq 12) is

.. math::

    a(i,t) = \frac{1-\delta}{5^{\max_j[\Lambda e_{i,j}^2(t)]}},

the max taken over the output channels j at each t (the toolkit's documented reading).

Sampled-data convention (used identically by lifting, simulation, analysis and synthesis)
-------------------------------------------------------------------------------------------
With sample time :math:`T_s`, trial length N and the sampled relative degree (shift) s >= 1:

* lifted input :math:`u = [u(0); \dots; u(N-1)]`, lifted output and error
  :math:`y = [y(s); \dots; y(N-1+s)]`, :math:`e = y_d - y` on the same window;
* derivative: backward difference :math:`\dot e(j) \approx (e(j) - e(j-1))/T_s`; the error just
  before the window is taken as zero (Assumption 2: :math:`x_i(0) = x_d(0)`);
* previous-trial (open-loop) term at sample k uses :math:`e_i(k+s+\ell)` and its difference,
  :math:`\ell` = ``lead`` >= 0 extra samples of anticipation; indices past the trial are zero;
* current-trial (closed-loop) term at sample k uses the error *measured* at sample k,
  :math:`e_{i+1}(k)` (lifted index k - s), and its difference; errors before the window
  (k < s) are zero. It is causal: u(k) depends on y(j) only for j <= k;
* forgetting: :math:`a(i,k)` is evaluated from :math:`e_i(k+s)` (the aligned error).

In lifted form, with :math:`A_i = \mathrm{diag}(a(i,k)) \otimes I`,

.. math::

    u_{i+1} = (I + L_2 G)^{-1}\left[(I - A_i - L_1 G)u_i + A_i u_0 + (L_1 + L_2)(y_d - d)\right].
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np
import tomli_w

from ._validation import (
    as_finite_array,
    in_interval,
    nonnegative,
    positive,
    positive_int,
    read_toml_file,
    table,
)
from .exceptions import ParameterError, ShapeError

__all__ = ["PDGains", "FixedForgetting", "VariableForgetting", "Forgetting", "NO_FORGETTING",
           "load_gains", "save_gains", "GainsFile"]

_GAIN_NAMES = ("Phi1", "Phi2", "Psi1", "Psi2")
#: exp(-x) is exactly 0.0 in double precision for x above about 745.13
_EXP_UNDERFLOW = 746.0


@dataclass(frozen=True)
class PDGains:
    r"""Learning gains :math:`\Phi_1, \Phi_2, \Psi_1, \Psi_2` of eq (11).

    Each is an ``(n_u, n_y)`` matrix (time-invariant) or an ``(N, n_u, n_y)`` array
    (time-varying, one matrix per sample). All four must share one shape. ``Phi*`` multiply
    the error derivative, ``Psi*`` the error; ``*1`` act on the previous trial (open loop),
    ``*2`` on the current trial (closed loop, feedback inside the trial).
    """

    Phi1: np.ndarray
    """open-loop derivative gain (previous trial)"""
    Phi2: np.ndarray
    """closed-loop derivative gain (current trial)"""
    Psi1: np.ndarray
    """open-loop proportional gain (previous trial)"""
    Psi2: np.ndarray
    """closed-loop proportional gain (current trial)"""
    lead: int = 0
    """extra samples of anticipation of the open-loop term (>= 0)"""

    def __post_init__(self) -> None:
        first = as_finite_array(self.Phi1, "Phi1")
        if first.ndim not in (2, 3):
            raise ShapeError(f"Phi1 must have shape (n_u, n_y) or (N, n_u, n_y); "
                             f"found shape {first.shape}")
        for name in _GAIN_NAMES:
            arr = as_finite_array(getattr(self, name), name, shape=first.shape)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "lead", positive_int(self.lead, "lead", minimum=0))

    # shape facts -----------------------------------------------------------------------------
    @property
    def time_varying(self) -> bool:
        """True when the gains are given per sample."""
        return self.Phi1.ndim == 3

    @property
    def n_u(self) -> int:
        return self.Phi1.shape[-2]

    @property
    def n_y(self) -> int:
        return self.Phi1.shape[-1]

    @property
    def horizon(self) -> int | None:
        """N for time-varying gains, else None."""
        return self.Phi1.shape[0] if self.time_varying else None

    def check_dimensions(self, n_u: int, n_y: int, N: int | None = None) -> None:
        """Raise :class:`ShapeError` unless the gains fit a plant with n_u inputs, n_y outputs
        (and, for time-varying gains, a trial of N samples).

        Parameters
        ----------
        n_u, n_y : int
            Number of plant inputs and outputs.
        N : int, optional
            Samples per trial (needed for time-varying gains).
        """
        want = (n_u, n_y) if not self.time_varying else (N if N is not None else
                                                         self.horizon, n_u, n_y)
        for name in _GAIN_NAMES:
            found = getattr(self, name).shape
            if found != tuple(want):
                raise ShapeError(f"{name} must have shape {tuple(want)} (inputs x outputs"
                                 f"{', per sample' if self.time_varying else ''}); "
                                 f"found shape {found}")

    def per_sample(self, N: int) -> dict[str, np.ndarray]:
        """Each gain as an ``(N, n_u, n_y)`` array (time-invariant gains are repeated).

        Parameters
        ----------
        N : int
            Samples per trial (for time-varying gains: their number of samples).
        """
        if self.time_varying and self.horizon != N:
            raise ShapeError(f"time-varying gains have {self.horizon} samples; the trial has {N}")
        return {name: (getattr(self, name) if self.time_varying
                       else np.broadcast_to(getattr(self, name), (N, self.n_u, self.n_y)))
                for name in _GAIN_NAMES}

    def sup_norms(self) -> dict[str, float]:
        r""":math:`b_{\Phi_1}, \dots` of eq (25): the sup over the trial of the induced 2-norm."""
        out = {}
        for name in _GAIN_NAMES:
            g = getattr(self, name)
            g3 = g if g.ndim == 3 else g[None]
            out[name] = float(np.max(np.linalg.norm(g3, ord=2, axis=(1, 2))))
        return out

    # constructors ------------------------------------------------------------------------------
    @classmethod
    def zeros(cls, n_u: int, n_y: int) -> PDGains:
        """All gains zero (no learning, no feedback).

        Parameters
        ----------
        n_u, n_y : int
            Number of plant inputs and outputs: each gain is ``(n_u, n_y)``.
        """
        z = np.zeros((n_u, n_y))
        return cls(z, z, z, z)

    def replace(self, **changes) -> PDGains:
        """A copy with some gains (or ``lead``) replaced."""
        unknown = sorted(set(changes) - {*_GAIN_NAMES, "lead"})
        if unknown:
            raise ParameterError(f"unknown gain name(s) {unknown}; known: {_GAIN_NAMES} and lead")
        kw = {name: getattr(self, name) for name in (*_GAIN_NAMES, "lead")}
        kw.update(changes)
        return PDGains(**kw)

    def as_dict(self) -> dict:
        return {**{n: getattr(self, n).tolist() for n in _GAIN_NAMES}, "lead": self.lead}


@dataclass(frozen=True)
class FixedForgetting:
    """A constant forgetting factor ``a`` in [0, 1) (the traditional law)."""

    a: float = 0.0
    """the forgetting factor a(i, t) = a for all i, t"""

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", in_interval(self.a, "a (fixed forgetting factor)", 0, 1))

    @property
    def bounds(self) -> tuple[float, float]:
        """The range (a_min, a_max) the factor can take."""
        return (self.a, self.a)

    def factor(self, e) -> np.ndarray:
        """a(k) for an error array of shape (N, n_y): constant.

        Parameters
        ----------
        e : array_like, shape (N, n_y)
            The aligned error of one trial (only its length matters).
        """
        e = np.asarray(e, dtype=float)
        return np.full(e.shape[0], self.a)

    def casadi_factor(self, e):
        """The factor as a CasADi expression of one error sample.

        Parameters
        ----------
        e : casadi.SX or casadi.MX, shape (n_y, 1)
            One aligned error sample.
        """
        return ca.DM(self.a) + 0 * ca.sum1(e)

    def as_dict(self) -> dict:
        return {"a": self.a}


def check_delta(value, name: str = "delta") -> float:
    r"""δ of eq (12): a finite real number in the open interval (0, 1).

    The factor :math:`a = (1-\delta)\,5^{-\Lambda e^2}` then lies in :math:`(0, 1-\delta]`
    with :math:`1 - \delta \in (0, 1)`: δ = 0 would allow a = 1 (a law that throws the whole
    previous input away), and δ = 1 makes a ≡ 0 — no forgetting at all, which is
    ``FixedForgetting(0)``, not a variable factor (and the error floor a/(1 + ||E||) of the
    scenario report would be 0, its reciprocal undefined).
    """
    v = in_interval(value, name, -math.inf, math.inf)       # a finite real number
    if not 0.0 < v < 1.0:
        raise ParameterError(f"{name} must lie in (0, 1) (the largest forgetting factor "
                             f"1 - {name} must lie in (0, 1); for no forgetting use a fixed "
                             f"factor a = 0); got {value!r}")
    return v


def check_Lambda(value, name: str = "Lambda", base: float = 5.0) -> float:
    r"""Λ of eq (12): a finite real number >= 0 whose rate :math:`\Lambda \ln(\mathrm{base})`
    is a finite double.

    The factor is evaluated as :math:`(1-\delta)\exp(-(\sqrt r\,\min(|e|, c))^2)` with
    :math:`r = \Lambda\ln(\mathrm{base})` and :math:`c` where the exponential underflows
    (:func:`_rate_root_and_cap`), so any finite rate and finite error are safe; a Λ whose
    rate overflows to infinity (Λ above about 1.1e308 for base 5) would turn the factor into
    NaN and is refused here.
    """
    v = nonnegative(value, name)
    if not math.isfinite(v * math.log(base)):
        raise ParameterError(f"{name} is too large: {name} * ln({base:g}) overflows a double "
                             f"(the power {base:g}^({name} e^2) of eq (12)); {name} must be at "
                             f"most {sys.float_info.max / math.log(base):.3g}; got "
                             f"{value!r}")
    return v


def _rate_root_and_cap(rate: float) -> tuple[float, float]:
    r"""For the exponent :math:`r e^2` of eq (12) (:math:`r = \Lambda\ln(\mathrm{base}) > 0`):
    :math:`\sqrt r` and the error magnitude :math:`\sqrt{746}/\sqrt r` beyond which
    :math:`e^{-r e^2}` is exactly 0.0 in double precision. The factor is evaluated as
    :math:`\exp(-(\sqrt r\,\min(|e|, \mathrm{cap}))^2)`: the product is at most
    :math:`\sqrt{746}`, so nothing overflows for any finite rate and error (squaring
    :math:`|e|` first overflowed for a tiny Λ and an error above 1e154)."""
    root = math.sqrt(rate)
    return root, math.sqrt(_EXP_UNDERFLOW) / root


@dataclass(frozen=True)
class VariableForgetting:
    r"""The variable forgetting factor of eq (12).

    .. math::

        a(i,t) = (1-\delta)\, \mathrm{base}^{-\Lambda \max_j e_{i,j}^2(t)}

    evaluated as :math:`(1-\delta)\exp(-\Lambda \ln(\mathrm{base}) \max_j e_j^2)`, which cannot
    overflow (the printed :math:`5^{(\cdot)}` overflows a float for errors above about 7.7 with
    :math:`\Lambda = 6`). Values lie in :math:`(0, 1-\delta]`: largest, 1 - δ, when the error
    is zero, so the law pulls u back towards u0 when tracking is good and learns freely when
    the error is large. Pass ``base`` to change the printed 5.
    """

    delta: float = 0.85
    """δ in (0, 1): the maximal factor is 1 - δ, in (0, 1) (δ = 0 would allow a = 1, a law
    that forgets the whole previous input; δ = 1 is no forgetting: use FixedForgetting(0))"""
    Lambda: float = 6.0
    """Λ >= 0, finite with Λ ln(base) finite (:func:`check_Lambda`): how fast the factor falls
    with the squared error"""
    base: float = 5.0
    """the base of the power in eq (12) (5 in the paper), > 1"""

    def __post_init__(self) -> None:
        delta = check_delta(self.delta)
        object.__setattr__(self, "delta", delta)
        base = positive(self.base, "base")
        if base <= 1:
            raise ParameterError(f"base must be > 1; got {self.base!r}")
        object.__setattr__(self, "base", base)
        object.__setattr__(self, "Lambda", check_Lambda(self.Lambda, "Lambda", base))

    @property
    def bounds(self) -> tuple[float, float]:
        """(0, 1 - δ): the infimum (large errors) and the maximum (zero error)."""
        return (0.0, 1.0 - self.delta)

    def factor(self, e) -> np.ndarray:
        """a(k) for an error array of shape (N, n_y) (max over channels at each k).

        Parameters
        ----------
        e : array_like, shape (N, n_y) or (N,)
            The aligned error :math:`e_i(k + s)` of one trial.
        """
        e = np.asarray(e, dtype=float)
        if e.ndim == 1:
            e = e[:, None]
        rate = self.Lambda * math.log(self.base)
        if rate == 0.0:
            return np.full(e.shape[0], 1.0 - self.delta)
        root, cap = _rate_root_and_cap(rate)
        magnitude = np.minimum(np.max(np.abs(e), axis=1), cap)
        return (1.0 - self.delta) * np.exp(-((root * magnitude) ** 2))

    def casadi_factor(self, e):
        """The factor as a CasADi expression of one error sample.

        Parameters
        ----------
        e : casadi.SX or casadi.MX, shape (n_y, 1)
            One aligned error sample.
        """
        rate = self.Lambda * math.log(self.base)
        if rate == 0.0:
            return ca.DM(1.0 - self.delta) + 0 * ca.sum1(e)
        root, cap = _rate_root_and_cap(rate)
        magnitude = ca.fmin(ca.mmax(ca.fabs(e)), cap)
        return (1.0 - self.delta) * ca.exp(-((root * magnitude) ** 2))

    def as_dict(self) -> dict:
        return {"delta": self.delta, "Lambda": self.Lambda, "base": self.base}


Forgetting = FixedForgetting | VariableForgetting
NO_FORGETTING = FixedForgetting(0.0)


# -------------------------------------------------------------------------------------------
# The gains file (TOML), shared by check, synthesis and simulation
# -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GainsFile:
    """Contents of a gains file: gains, forgetting, sample time and optional certificate."""

    gains: PDGains
    """the learning gains of eq (11)"""
    forgetting: Forgetting = NO_FORGETTING
    """the forgetting factor of eq (12) (fixed or variable)"""
    ts: float | None = None
    """sample time [s] the gains were designed for (None: not recorded)"""
    certificate: dict = field(default_factory=dict)
    """the numbers that certified the gains (``[certificate]`` table)"""
    meta: dict = field(default_factory=dict)
    """free-form provenance (``[meta]`` table)"""


_TOP_KEYS = {*_GAIN_NAMES, "lead", "ts", "forgetting", "certificate", "meta"}


def _forgetting_from(value, source: str) -> Forgetting:
    forgetting = table(value, "forgetting", source)
    keys = set(forgetting)
    if keys <= {"a"} and keys:
        return FixedForgetting(forgetting["a"])
    if keys and keys <= {"delta", "Lambda", "base"} and {"delta", "Lambda"} <= keys:
        return VariableForgetting(**forgetting)
    raise ParameterError(f"{source}: [forgetting] must hold either 'a' (fixed) or 'delta' and "
                         f"'Lambda' (variable, optional 'base'); found keys {sorted(keys)}")


def load_gains(path: str | Path) -> GainsFile:
    """Read a gains TOML file.

    Format: matrices ``Phi1``, ``Phi2``, ``Psi1``, ``Psi2`` as nested arrays of numbers
    (inputs x outputs, or samples x inputs x outputs), optional ``lead`` (samples, an integer)
    and ``ts`` (s), a ``[forgetting]`` table with ``a`` or ``delta`` and ``Lambda``, optional
    ``[certificate]`` and ``[meta]`` tables. Unknown keys are errors; booleans, strings and
    non-finite numbers where numbers are expected are errors.

    Parameters
    ----------
    path : str or pathlib.Path
        The gains file.

    Returns
    -------
    GainsFile
        Its gains, forgetting factor, sample time, certificate and metadata.

    Raises
    ------
    ParameterError
        The file is missing, not a regular file (a directory, a FIFO: refused before it is
        opened), too large, not UTF-8, not TOML, nested too deeply
        (:func:`~ilc_analysis._validation.read_toml_file`), or a key is unknown, missing or of
        the wrong form; the message names the file and the key.
    ShapeError
        Gain matrices of different or wrong shapes (ragged nested arrays included).
    """
    source = f"gains file {str(path)!r}"
    data = read_toml_file(path, "gains file")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise ParameterError(f"{source}: unknown key(s) {unknown}; "
                             f"allowed: {sorted(_TOP_KEYS)}")
    missing = [n for n in _GAIN_NAMES if n not in data]
    if missing:
        raise ParameterError(f"{source}: missing gain matrix/matrices {missing}")
    try:
        gains = PDGains(data["Phi1"], data["Phi2"], data["Psi1"], data["Psi2"],
                        lead=data.get("lead", 0))
        forgetting = _forgetting_from(data["forgetting"], source) if "forgetting" in data \
            else NO_FORGETTING
        ts = positive(data["ts"], "ts") if "ts" in data else None
    except (ParameterError, ShapeError) as exc:
        message = str(exc)
        raise type(exc)(message if message.startswith(source) else f"{source}: {message}") \
            from exc
    certificate = dict(table(data.get("certificate", {}), "certificate", source))
    meta = dict(table(data.get("meta", {}), "meta", source))
    return GainsFile(gains=gains, forgetting=forgetting, ts=ts, certificate=certificate,
                     meta=meta)


def save_gains(path: str | Path, gains: PDGains, forgetting: Forgetting = NO_FORGETTING, *,
               ts: float | None = None, certificate: dict | None = None,
               meta: dict | None = None) -> Path:
    """Write a gains TOML file readable by :func:`load_gains`.

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write.
    gains : PDGains
        The learning gains.
    forgetting : FixedForgetting or VariableForgetting, optional
        The forgetting factor (default: none, a = 1).
    ts : float, optional
        Sample time [s] the gains were designed for.
    certificate : dict, optional
        The numbers that certified the gains (written as ``[certificate]``).
    meta : dict, optional
        Free-form provenance (written as ``[meta]``).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    doc: dict = gains.as_dict()
    if ts is not None:
        doc["ts"] = positive(ts, "ts")
    doc["forgetting"] = forgetting.as_dict()
    if certificate:
        doc["certificate"] = _plain(certificate)
    if meta:
        doc["meta"] = _plain(meta)
    path = Path(path)
    path.write_text(tomli_w.dumps(doc))
    return path


def _plain(obj):
    """Convert numpy scalars/arrays in nested dicts to TOML-serialisable Python values."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
