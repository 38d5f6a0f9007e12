r"""The forgetting factor of eq (11)-(12): fixed or variable, one type for every stage.

A forgetting factor :math:`a(i,k) \in [0, 1)` pulls the next trial's input towards
:math:`u_0`: :math:`a\,u_0 + (1-a)\,u_i` (:func:`apply_forgetting`, the one implementation
every law uses). :class:`FixedForgetting` is a constant a (the traditional law);
:class:`VariableForgetting` is eq (12),

.. math::

    a(i,t) = \frac{1-\delta}{5^{\max_j[\Lambda e_{i,j}^2(t)]}}.

Analysis and synthesis read a forgetting factor through :meth:`FixedForgetting.values` /
:meth:`VariableForgetting.values`: the distinct values a sup over the factor is taken at (the
norms of the lifted operator are convex in a, so on an interval the sup is attained at an end).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .._validation import in_interval, nonnegative, positive
from ..exceptions import ParameterError

__all__ = ["FixedForgetting", "VariableForgetting", "Forgetting", "NO_FORGETTING",
           "check_delta", "check_Lambda", "apply_forgetting"]

#: exp(-x) is exactly 0.0 in double precision for x above about 745.13
_EXP_UNDERFLOW = 746.0


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

    def values(self) -> tuple[float, ...]:
        """The distinct values the factor takes: ``(a,)`` (what analysis and synthesis take a
        sup over)."""
        return (self.a,)

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

    Parameters
    ----------
    value : float
        The δ to check.
    name : str
        Its name in the error message.

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        Not a finite real number in (0, 1).
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

    Parameters
    ----------
    value : float
        The Λ to check.
    name : str
        Its name in the error message.
    base : float
        The base of the power in eq (12) (5 in the paper).

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        Negative, not finite, or with an overflowing rate.
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

    def values(self) -> tuple[float, ...]:
        """The distinct ends of the factor's range ``(0, 1 - δ)`` (:attr:`bounds`): the values
        analysis and synthesis take a sup over (convex in a: attained at an end)."""
        lo, hi = self.bounds
        return (lo,) if lo == hi else (lo, hi)

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


def apply_forgetting(forgetting: Forgetting, e, u, u0) -> tuple[np.ndarray, np.ndarray]:
    r"""The forgetting part of a between-trial update, :math:`a\,u_0 + (1-a)\,u`.

    .. math::

        w(k) = a(i,k)\,u_0(k) + (1 - a(i,k))\,u_i(k),

    with :math:`a(i,k)` the factor evaluated from the aligned error :math:`e_i(k+s)`.

    Parameters
    ----------
    forgetting : FixedForgetting or VariableForgetting
        The forgetting factor.
    e : array_like, shape (N, n_y)
        The aligned (lifted) error of trial i.
    u : ndarray, shape (N, n_u)
        The input applied in trial i.
    u0 : ndarray, shape (N, n_u), or None
        The input the forgetting pulls towards; None only for a factor that is zero
        (:class:`FixedForgetting` with a = 0: then ``u0`` is not read).

    Returns
    -------
    w : ndarray, shape (N, n_u)
        The forgotten input.
    a : ndarray, shape (N,)
        The factor :math:`a(i, k)` used.
    """
    a = forgetting.factor(e)
    if isinstance(forgetting, FixedForgetting) and forgetting.a == 0.0:
        return u, a                     # no forgetting: w = u
    if u0 is None:
        raise ParameterError("u0 is required unless the forgetting factor is zero")
    return a[:, None] * u0 + (1.0 - a[:, None]) * u, a
