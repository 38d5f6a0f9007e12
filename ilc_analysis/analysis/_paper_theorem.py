r"""The convergence theorem of the paper (Section 4, eqs 25–35), done right.

The law (11) gives, after eq (24),

.. math::

    [I + \Phi_2 H]\,\Delta u_{i+1} = [(1-a)I - \Phi_1 H]\,\Delta u_i + (\text{state and
    disturbance terms}),

with :math:`H = C B` in the paper (:math:`H = C A^{r-1} B` in the relative-degree-aware form,
see :mod:`.relative_degree_form`). Taking norms (eq 25),

.. math::

    \gamma_1 = \sup_t \|(1-a)I - \Phi_1(t) H(t)\|_2, \qquad
    \gamma_2 = \sup_t \|[I + \Phi_2(t) H(t)]^{-1}\|_2 ,

and the tight version of the product, :math:`\sup_t \|X^{-1} Y\|_2 \le \gamma_1\gamma_2` with
:math:`X = I + \Phi_2 H`, :math:`Y = (1-a)I - \Phi_1 H`.

The :math:`\lambda`-norm step (eqs 27–35) is carried out with the Lipschitz constant
:math:`k_f` kept (the paper silently uses :math:`k_f = 1` in eq 29 and drops it in eq 31). The
Gronwall bound gives

.. math::

    \|\Delta x_i\|_\lambda \le b_\omega T + \rho(\lambda)\|\Delta u_i\|_\lambda,\qquad
    \rho(\lambda) = b_B\,\frac{1 - e^{-(\lambda - k_f)T}}{\lambda - k_f},\quad \lambda > k_f,

and then (eq 35) :math:`b\|\Delta u_{i+1}\|_\lambda \le a\|\Delta u_i\|_\lambda + c` with

.. math::

    a(\lambda) = \gamma_1\gamma_2 + \gamma_2\xi_1\rho(\lambda),\quad
    b(\lambda) = 1 - \gamma_2\xi_2\rho(\lambda),\quad
    c = \gamma_2(\xi_1 + \xi_2) b_\omega T + \mu_0 .

It converges to the ball :math:`\|\Delta u\|_\lambda \le c/(b-a)` iff :math:`b > 0` and
:math:`a/b < 1`, i.e. iff :math:`\gamma_1\gamma_2 + \gamma_2(\xi_1+\xi_2)\rho(\lambda) < 1`.

Corrections to the printed constants (eq 27): the Lipschitz term enters through :math:`\Phi C
\Delta f`, so :math:`\xi_1 = b_{\Phi_1}(b_{dC} + b_C k_f) + b_{\Psi_1} b_C` (printed without
:math:`b_C`; the two agree when :math:`\|C\| = 1`, as for the robots' selection matrices).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.special

from .._validation import as_finite_array, nonnegative, positive
from ..exceptions import ParameterError, ShapeError
from ..laws._forgetting import FixedForgetting, VariableForgetting
from ._verdicts import threshold_verdict, verdict_tolerance

__all__ = [
    "gamma_factors",
    "tight_contraction",
    "forgetting_values",
    "DisturbanceBounds",
    "Couplings",
    "xi_mu0",
    "lambda_rho",
    "LambdaCondition",
    "lambda_condition",
]

#: Relative tolerance of the root searches for the smallest and the bound-minimising λ.
LAMBDA_RTOL = 1e-12


# ---------------------------------------------------------------------------------------------
# shapes
# ---------------------------------------------------------------------------------------------
def _stack(value, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """A finite (n, rows, cols) array from a (rows, cols) matrix or a per-sample stack."""
    arr = as_finite_array(value, name)
    if arr.ndim == 2:
        arr = arr[None]
    elif arr.ndim != 3:
        raise ShapeError(f"{name} must have shape (rows, cols) or (N, rows, cols); "
                         f"found shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0 or arr.shape[2] == 0:
        raise ShapeError(f"{name} must not be empty; found shape {arr.shape}")
    if (rows is not None and arr.shape[1] != rows) or (cols is not None and arr.shape[2] != cols):
        want = f"({rows if rows is not None else 'any'}, {cols if cols is not None else 'any'})"
        raise ShapeError(f"{name} must have shape {want} (or a per-sample stack of those); "
                         f"found shape {np.shape(value)}")
    return arr


def forgetting_values(a) -> np.ndarray:
    """The forgetting-factor values a sup is taken over, as a 1-D array in [0, 1).

    ``a`` is a number, a sequence of numbers, or a
    :class:`~ilc_analysis.laws.FixedForgetting` / :class:`~ilc_analysis.laws.VariableForgetting`
    (its ``values()``: the factor, or the two ends of its range; the norms below are convex in
    ``a``, so on an interval their sup is attained at an end).

    Parameters
    ----------
    a : float, sequence of float, or forgetting object
        The factor(s), or a :class:`~ilc_analysis.laws.FixedForgetting` /
        :class:`~ilc_analysis.laws.VariableForgetting` (its ``values()``).
    """
    if isinstance(a, FixedForgetting | VariableForgetting):
        a = np.asarray(a.values(), dtype=float)
    arr = as_finite_array(a, "a (forgetting factor)")
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1 or arr.size == 0:
        raise ShapeError(f"a (forgetting factor) must be a number or a 1-D sequence of numbers; "
                         f"found shape {np.shape(a)}")
    if np.any(arr < 0) or np.any(arr >= 1):
        raise ParameterError(f"a (forgetting factor) must lie in [0, 1); got {arr.tolist()}")
    return arr


def _broadcast_triple(H, Phi1, Phi2):
    """Validate H (n_y, n_u) and Phi1, Phi2 (n_u, n_y), each optionally per sample (N, ...)."""
    H3 = _stack(H, "H")
    n_y, n_u = H3.shape[1:]
    P1 = _stack(Phi1, "Phi1", n_u, n_y)
    P2 = _stack(Phi2, "Phi2", n_u, n_y)
    lengths = {len(s) for s in (H3, P1, P2)} - {1}
    if len(lengths) > 1:
        raise ShapeError(f"per-sample H, Phi1, Phi2 must share one number of samples; found "
                         f"{len(H3)}, {len(P1)}, {len(P2)}")
    n = lengths.pop() if lengths else 1
    return (np.broadcast_to(H3, (n, n_y, n_u)), np.broadcast_to(P1, (n, n_u, n_y)),
            np.broadcast_to(P2, (n, n_u, n_y)))


# ---------------------------------------------------------------------------------------------
# eq (25): gamma factors and the tight contraction
# ---------------------------------------------------------------------------------------------
def gamma_factors(H, Phi1, Phi2, a) -> tuple[float, float]:
    r"""The paper's :math:`\gamma_1, \gamma_2` (eq 25).

    .. math::

        \gamma_1 = \sup_{t,\,a} \|(1-a)I - \Phi_1(t) H(t)\|_2,\qquad
        \gamma_2 = \sup_t \|[I + \Phi_2(t) H(t)]^{-1}\|_2
                 = \sup_t 1/\sigma_{\min}(I + \Phi_2(t) H(t)).

    Parameters
    ----------
    H : array_like, shape (n_y, n_u) or (N, n_y, n_u)
        Input–output coupling: :math:`CB` in the paper, :math:`CA^{r-1}B` in the
        relative-degree-aware form; per sample if time-varying.
    Phi1, Phi2 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
        Open- and closed-loop derivative gains; per sample if time-varying.
    a : float, sequence of float, or forgetting object
        Forgetting factor value(s) in [0, 1); the sup is taken over every value and sample
        (see :func:`forgetting_values`).

    Returns
    -------
    gamma1, gamma2 : float
        ``gamma2`` is ``inf`` when :math:`I + \Phi_2 H` is singular at some sample.

    Examples
    --------
    >>> gamma_factors([[2.0]], [[0.25]], [[0.5]], 0.1)
    (0.4, 0.5)
    """
    H3, P1, P2 = _broadcast_triple(H, Phi1, Phi2)
    avals = forgetting_values(a)
    n_u = H3.shape[2]
    eye = np.eye(n_u)
    P1H = P1 @ H3
    Y = (1.0 - avals)[:, None, None, None] * eye - P1H[None]
    gamma1 = float(np.max(np.linalg.norm(Y, ord=2, axis=(-2, -1))))
    smin = np.linalg.svd(eye + P2 @ H3, compute_uv=False)[:, -1]
    gamma2 = float(np.inf) if np.any(smin == 0.0) else float(np.max(1.0 / smin))
    return gamma1, gamma2


def tight_contraction(H, Phi1, Phi2, a) -> float:
    r"""The tight contraction :math:`\sup_{t,a}\|X^{-1}Y\|_2 \le \gamma_1\gamma_2`.

    .. math::

        X = I + \Phi_2 H,\qquad Y = (1-a)I - \Phi_1 H .

    Arguments as in :func:`gamma_factors`. Returns ``inf`` if :math:`X` is singular.

    Parameters
    ----------
    H : array_like, shape (n_y, n_u) or (N, n_y, n_u)
        Input-output coupling: :math:`CB` in the paper, :math:`CA^{r-1}B` in the
        relative-degree-aware form; per sample if time-varying.
    Phi1, Phi2 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
        Open- and closed-loop derivative gains; per sample if time-varying.
    a : float, sequence of float, or forgetting object
        Forgetting factor value(s) in [0, 1) (see :func:`forgetting_values`).

    Examples
    --------
    >>> round(tight_contraction([[2.0]], [[0.25]], [[0.5]], 0.1), 12)
    0.2
    """
    H3, P1, P2 = _broadcast_triple(H, Phi1, Phi2)
    avals = forgetting_values(a)
    n_u = H3.shape[2]
    eye = np.eye(n_u)
    X = eye + P2 @ H3
    if np.any(np.linalg.svd(X, compute_uv=False)[:, -1] == 0.0):
        return float(np.inf)
    Xinv = np.linalg.inv(X)
    Y = (1.0 - avals)[:, None, None, None] * eye - (P1 @ H3)[None]
    return float(np.max(np.linalg.norm(Xinv[None] @ Y, ord=2, axis=(-2, -1))))


# ---------------------------------------------------------------------------------------------
# eq (27): xi1, xi2, mu0
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DisturbanceBounds:
    r"""Sup-norm bounds of the disturbances and their derivatives (Assumption 4, eq 16).

    ``omega[k]`` bounds :math:`\sup_t\|\omega^{(k)}(t)\|` (state disturbance), ``nu[k]`` bounds
    :math:`\sup_t\|\nu^{(k)}(t)\|` (output disturbance). The paper's form needs
    :math:`b_\omega` = ``omega[0]``, :math:`b_\nu` = ``nu[0]``, :math:`b_{d\nu}` = ``nu[1]``; the
    relative-degree-aware form of order r needs ``omega[:r]`` and ``nu[:r+1]``. All-zero bounds
    (the default) mean no disturbance: every derivative bound is then zero.
    """

    omega: tuple[float, ...] = (0.0,)
    """bounds of the state disturbance and its derivatives, order 0, 1, ..."""
    nu: tuple[float, ...] = (0.0, 0.0)
    """bounds of the output disturbance and its derivatives, order 0, 1, ..."""

    def __post_init__(self) -> None:
        for name in ("omega", "nu"):
            vals = tuple(nonnegative(float(v), f"{name}[{k}]")
                         for k, v in enumerate(np.atleast_1d(getattr(self, name)).tolist()))
            if not vals:
                raise ParameterError(f"{name} must hold at least the order-0 bound")
            object.__setattr__(self, name, vals)

    @classmethod
    def sinusoid(cls, amplitude: float, angular_frequency: float, n_state: int, n_output: int,
                 order: int = 2) -> DisturbanceBounds:
        r"""Bounds for :math:`A\sin(\omega t)` on every channel (the paper's Section 5 uses
        :math:`0.01\sin(40\pi t)`): :math:`\|\cdot^{(k)}\| \le A\,\omega^k\sqrt{n}`.

        Parameters
        ----------
        amplitude : float
            A (>= 0).
        angular_frequency : float
            ω [rad/s] (>= 0).
        n_state, n_output : int
            Number of state and output channels (the √n factor).
        order : int, optional
            Highest derivative order bounded for ω (ν gets one more).
        """
        amplitude = nonnegative(amplitude, "amplitude")
        w = nonnegative(angular_frequency, "angular_frequency")
        return cls(omega=tuple(amplitude * w**k * math.sqrt(n_state) for k in range(order + 1)),
                   nu=tuple(amplitude * w**k * math.sqrt(n_output) for k in range(order + 2)))

    def omega_bound(self, order: int) -> float:
        """:math:`\\sup\\|\\omega^{(k)}\\|` for k = ``order``; a clear error if not given.

        Parameters
        ----------
        order : int
            Derivative order k.
        """
        return self._get("omega", order)

    def nu_bound(self, order: int) -> float:
        """:math:`\\sup\\|\\nu^{(k)}\\|` for k = ``order``; a clear error if not given.

        Parameters
        ----------
        order : int
            Derivative order k.
        """
        return self._get("nu", order)

    def _get(self, name: str, order: int) -> float:
        vals = getattr(self, name)
        if order >= len(vals) and not any(vals):
            return 0.0  # no disturbance at all: every derivative is zero too
        if order >= len(vals):
            raise ParameterError(f"DisturbanceBounds.{name} gives derivative orders "
                                 f"0..{len(vals) - 1}; order {order} is needed (pass "
                                 f"{name}=(b0, b1, ..., b{order}))")
        return vals[order]

    def as_dict(self) -> dict:
        return {"omega": list(self.omega), "nu": list(self.nu)}


@dataclass(frozen=True)
class Couplings:
    r"""How the state error and the disturbances enter the learning terms (eq 27).

    In the paper's form, :math:`\Phi\dot e = \Phi(\dot C\Delta x + C\Delta\dot x - \dot\nu)`
    with :math:`\|\Delta f\| \le k_f\|\Delta x\|`, and :math:`\Psi e = \Psi(C\Delta x - \nu)`:

    .. math::

        \phi_x = b_{dC} + b_C k_f,\quad \psi_x = b_C,\quad
        \phi_d = b_C b_\omega + b_{d\nu},\quad \psi_d = b_\nu .
    """

    phi_state: float
    """bound of the derivative term's dependence on the state error"""
    psi_state: float
    """bound of the proportional term's dependence on the state error (b_C)"""
    phi_disturbance: float
    """disturbance entering the derivative term"""
    psi_disturbance: float
    """disturbance entering the proportional term"""

    def __post_init__(self) -> None:
        for name in ("phi_state", "psi_state", "phi_disturbance", "psi_disturbance"):
            object.__setattr__(self, name, nonnegative(float(getattr(self, name)), name))

    @classmethod
    def paper(cls, b_C: float, k_f: float, *, b_dC: float = 0.0,
              disturbances: DisturbanceBounds | None = None) -> Couplings:
        """The couplings of the paper's D-type form (see class docstring).

        Parameters
        ----------
        b_C : float
            Bound on the norm of C (>= 0).
        k_f : float
            Lipschitz constant of f (>= 0).
        b_dC : float, optional
            Bound on the norm of the derivative of C (0 for a constant C).
        disturbances : DisturbanceBounds, optional
            Bounds on the disturbances and their derivatives (default: none).
        """
        dist = disturbances if disturbances is not None else DisturbanceBounds()
        b_C = nonnegative(b_C, "b_C")
        return cls(phi_state=nonnegative(b_dC, "b_dC") + b_C * nonnegative(k_f, "k_f"),
                   psi_state=b_C,
                   phi_disturbance=b_C * dist.omega_bound(0) + dist.nu_bound(1),
                   psi_disturbance=dist.nu_bound(0))


def xi_mu0(gain_norms, couplings: Couplings, *, gamma2: float, a_max: float,
           delta_u0: float = 0.0) -> tuple[float, float, float]:
    r""":math:`\xi_1, \xi_2, \mu_0` of eq (27), with the corrected Lipschitz term.

    .. math::

        \xi_1 = b_{\Phi_1}\phi_x + b_{\Psi_1}\psi_x,\qquad
        \xi_2 = b_{\Phi_2}\phi_x + b_{\Psi_2}\psi_x,

        \mu_0 = \gamma_2\left[(b_{\Phi_1}+b_{\Phi_2})\phi_d + (b_{\Psi_1}+b_{\Psi_2})\psi_d
                \right] + \gamma_2\, a_{\max}\, \|\Delta u_0\| .

    Parameters
    ----------
    gain_norms : PDGains or dict
        The gains, or their sup norms ``{'Phi1': b_Phi1, ...}`` (:meth:`PDGains.sup_norms`).
    couplings : Couplings
        :meth:`Couplings.paper` for the paper's form.
    gamma2 : float
        From :func:`gamma_factors`.
    a_max : float
        The largest forgetting factor value.
    delta_u0 : float
        :math:`\sup_t\|u_d(t) - u_0(t)\|`, which bounds :math:`\|\Delta u_0\|_\lambda` for every
        :math:`\lambda \ge 0` (the paper's μ0 uses the λ-norm; the sup norm keeps c independent
        of λ and is never smaller).
    """
    norms = gain_norms.sup_norms() if hasattr(gain_norms, "sup_norms") else dict(gain_norms)
    missing = sorted({"Phi1", "Phi2", "Psi1", "Psi2"} - set(norms))
    if missing:
        raise ParameterError(f"gain_norms is missing {missing}")
    b = {k: nonnegative(float(norms[k]), f"gain_norms[{k!r}]")
         for k in ("Phi1", "Phi2", "Psi1", "Psi2")}
    a_max = nonnegative(a_max, "a_max")
    delta_u0 = nonnegative(delta_u0, "delta_u0")
    xi1 = b["Phi1"] * couplings.phi_state + b["Psi1"] * couplings.psi_state
    xi2 = b["Phi2"] * couplings.phi_state + b["Psi2"] * couplings.psi_state
    mu0 = gamma2 * ((b["Phi1"] + b["Phi2"]) * couplings.phi_disturbance
                    + (b["Psi1"] + b["Psi2"]) * couplings.psi_disturbance) \
        + gamma2 * a_max * delta_u0
    return float(xi1), float(xi2), float(mu0)


# ---------------------------------------------------------------------------------------------
# eqs (31)-(35): the lambda-norm condition
# ---------------------------------------------------------------------------------------------
def _g(x: float, T: float) -> float:
    r""":math:`(1 - e^{-xT})/x` for x > 0 (its limit T at x = 0)."""
    return T if x == 0.0 else -math.expm1(-x * T) / x


#: Below this u = x T, :func:`_dg` sums its series (the closed form cancels: e^-u (1 + u) - 1
#: is about -u^2/2, so it loses digits as 1e-16/u^2; at u = 0.0034 the optimum's root moved by
#: 2.6e-9, relative).
_DG_SERIES_BELOW = 1.0


def _dg(x: float, T: float) -> float:
    r"""d/dx of :func:`_g`: :math:`(e^{-u}(1 + u) - 1)/x^2` with u = x T.

    For :math:`u <` :data:`_DG_SERIES_BELOW` its series, without cancellation,

    .. math::

        \frac{d g}{d x} = T^2 \sum_{k \ge 2} (-1)^k \frac{1 - k}{k!}\,u^{k-2}
                         = -T^2\left(\tfrac12 - \tfrac{u}{3} + \tfrac{u^2}{8} - \dots\right),

    summed until a term is below rounding (at most 30 terms for u < 1)."""
    u = x * T
    if u < _DG_SERIES_BELOW:
        total, power, factorial = 0.0, 1.0, 2.0     # u^(k-2) and k! at k = 2
        for k in range(2, 32):
            term = (-1) ** k * (1 - k) / factorial * power
            total += term
            if abs(term) <= 1e-17 * abs(total):
                break
            power *= u
            factorial *= k + 1
        return T * T * total
    return (math.exp(-u) * (1.0 + u) - 1.0) / (x * x)


def lambda_rho(lam: float, *, b_B: float, T: float, k_f: float) -> float:
    r""":math:`\rho(\lambda) = b_B(1 - e^{-(\lambda-k_f)T})/(\lambda - k_f)` (eq 31 with
    :math:`k_f` kept).

    Parameters
    ----------
    lam : float
        The λ of the λ-norm (> k_f).
    b_B : float
        Bound on the norm of B.
    T : float
        Trial duration [s].
    k_f : float
        Lipschitz constant of f.

    Raises
    ------
    ParameterError
        If :math:`\lambda \le k_f` (the Gronwall step needs :math:`\lambda > k_f`).
    """
    lam = float(lam)
    if not math.isfinite(lam) or lam <= k_f:
        raise ParameterError(f"lambda must be a finite number > k_f = {k_f:g} (the lambda-norm "
                             f"Gronwall step needs lambda > k_f); got {lam!r}")
    return b_B * _g(lam - k_f, T)


@dataclass(frozen=True)
class LambdaCondition:
    r"""The λ-norm condition of eqs (31)–(35) and what it yields.

    ``holds`` iff some :math:`\lambda > k_f` gives :math:`b > 0` and :math:`a/b < 1`, which is
    iff :math:`\gamma_1\gamma_2 < 1`, decided with a tolerance
    (:func:`~ilc_analysis.analysis._verdicts.threshold_verdict`): a product within it of 1
    is ``verdict = 'marginal'`` (``holds`` False, no λ reported), because
    :math:`q = 1 - \gamma_1\gamma_2` is then rounding and the smallest λ, about
    :math:`\gamma_2(\xi_1+\xi_2)b_B/q`, is not a number the computation can give.
    ``lambda_min`` is the infimum of such λ (the condition is
    strict, so at ``lambda_min`` itself :math:`b = a` and the bound is infinite unless every
    :math:`\lambda > k_f` qualifies). :math:`c/(b-a)` *decreases* in λ towards
    :math:`c/(1-\gamma_1\gamma_2)`, but it bounds a λ-norm that weighs late samples by
    :math:`e^{-\lambda t}`; what it says about the signal is
    :math:`\sup_t\|\Delta u(t)\| \le e^{\lambda T} c/(b-a)`. ``lambda_opt`` minimises that
    sup-norm guarantee and ``ultimate_bound`` is :math:`c/(b-a)` there.
    """

    gamma1: float
    r""":math:`\gamma_1 = \sup_t\|(1-a)I - \Phi_1 H\|_2` (:func:`gamma_factors`)"""
    gamma2: float
    r""":math:`\gamma_2 = \sup_t\|(I + \Phi_2 H)^{-1}\|_2` (may be inf: then it fails)"""
    xi1: float
    r""":math:`\xi_1` of eq (27): the state coupling through the previous-trial gains
    :math:`\Phi_1, \Psi_1` (:func:`xi_mu0`)"""
    xi2: float
    r""":math:`\xi_2` of eq (27): the state coupling through the current-trial gains
    :math:`\Phi_2, \Psi_2` (:func:`xi_mu0`)"""
    mu0: float
    r""":math:`\mu_0` of eq (27): the disturbance and initial-input term (:func:`xi_mu0`)"""
    b_B: float
    r""":math:`b_B = \sup_t\|B(t)\|`"""
    T: float
    """trial length [s]"""
    k_f: float
    """Lipschitz constant of f (kept: the paper silently uses 1)"""
    b_omega: float
    r""":math:`b_\omega = \sup_t\|\omega(t)\|`, the bound of the state disturbance"""
    c: float
    """the constant of eq (35): γ2(ξ1+ξ2) b_ω T + μ0"""
    holds: bool
    """some λ > k_f gives b > 0 and a/b < 1 (γ1γ2 < 1 beyond the tolerance: ``verdict`` is
    'holds')"""
    lambda_min: float | None
    """infimum of the admissible λ (None if no λ works)"""
    bound_at_lambda_min: float
    """c/(b - a) at lambda_min (inf when lambda_min > k_f: b = a there)"""
    lambda_opt: float | None
    """the λ minimising the sup-norm guarantee e^{λT} c/(b - a)"""
    ultimate_bound: float
    """c/(b - a) at lambda_opt: the λ-norm bound of lim sup ||Δu_i||_λ"""
    sup_bound: float
    """e^{λT} c/(b - a) at lambda_opt: the implied bound of lim sup sup_t ||Δu_i(t)||"""
    bound_limit: float
    """c/(1 - γ1γ2), the limit of c/(b - a) as λ → ∞"""
    verdict: str = "holds"
    """'holds', 'marginal' (γ1γ2 = 1 within the tolerance) or 'fails'"""
    reason: str = ""
    """why the condition does not hold (empty when it holds)"""

    def rho(self, lam: float) -> float:
        """:math:`\\rho(\\lambda)` (see :func:`lambda_rho`).

        Parameters
        ----------
        lam : float
            The λ of the λ-norm (> k_f).
        """
        return lambda_rho(lam, b_B=self.b_B, T=self.T, k_f=self.k_f)

    def coefficients(self, lam: float) -> tuple[float, float, float]:
        """``(a, b, c)`` of eq (35) at λ.

        Parameters
        ----------
        lam : float
            The λ of the λ-norm (> k_f).
        """
        r = self.rho(lam)
        return (self.gamma1 * self.gamma2 + self.gamma2 * self.xi1 * r,
                1.0 - self.gamma2 * self.xi2 * r, self.c)

    def admissible(self, lam: float) -> bool:
        """True iff b(λ) > 0 and a(λ)/b(λ) < 1.

        Parameters
        ----------
        lam : float
            The λ of the λ-norm (> k_f).
        """
        a, b, _ = self.coefficients(lam)
        return bool(b > 0 and a < b)

    def bound(self, lam: float) -> float:
        """c/(b - a) at λ, or inf if λ is not admissible.

        Parameters
        ----------
        lam : float
            The λ of the λ-norm (> k_f).
        """
        a, b, c = self.coefficients(lam)
        if not (b > 0 and a < b):
            return float(np.inf)
        return c / (b - a)

    def as_dict(self) -> dict:
        return {k: _json_number(getattr(self, k)) for k in self.__dataclass_fields__}


def _json_number(v):
    if isinstance(v, bool | str) or v is None:
        return v
    v = float(v)
    return v if math.isfinite(v) else None


def lambda_condition(gamma1: float, gamma2: float, xi1: float, xi2: float, *, b_B: float,
                     T: float, k_f: float, b_omega: float = 0.0,
                     mu0: float = 0.0) -> LambdaCondition:
    r"""Evaluate the λ-norm condition (eqs 31–35).

    With :math:`q = 1 - \gamma_1\gamma_2` and :math:`K = \gamma_2(\xi_1+\xi_2)b_B`, λ is
    admissible iff :math:`K\,g(\lambda - k_f) < q`, :math:`g(x) = (1-e^{-xT})/x` (decreasing
    from T to 0). The infimum solves :math:`g(x^*) = r := q/K`, in closed form with the
    Lambert W function:

    .. math::

        x^* = \frac{1}{r}\left(1 + \frac{r}{T}\,W_0\!\left(-\frac{T}{r}e^{-T/r}\right)\right),
        \qquad \lambda_{\min} = k_f + x^*\quad (r < T),

    and :math:`\lambda_{\min} = k_f` (every λ > k_f) when :math:`r \ge T`.

    Parameters
    ----------
    gamma1, gamma2 : float
        From :func:`gamma_factors` (``gamma2`` may be inf: the condition then fails).
    xi1, xi2, mu0 : float
        From :func:`xi_mu0`.
    b_B : float
        :math:`\sup_t\|B(t)\|`.
    T : float
        Trial length [s], > 0.
    k_f : float
        Lipschitz constant of f (for a linear plant a norm of A; the paper silently uses 1).
    b_omega : float
        :math:`\sup_t\|\omega(t)\|`.
    """
    gamma1 = nonnegative(gamma1, "gamma1")
    if isinstance(gamma2, bool) or not isinstance(gamma2, numbers.Real) \
            or math.isnan(gamma2) or gamma2 <= 0:
        raise ParameterError(f"gamma2 must be a positive number (inf allowed); got {gamma2!r}")
    gamma2 = float(gamma2)
    xi1, xi2, mu0 = (nonnegative(v, n) for v, n in ((xi1, "xi1"), (xi2, "xi2"), (mu0, "mu0")))
    b_B = nonnegative(b_B, "b_B")
    T = positive(T, "T (trial length)")
    k_f = nonnegative(k_f, "k_f")
    b_omega = nonnegative(b_omega, "b_omega")
    inf = float(np.inf)
    product = gamma1 * gamma2
    verdict = "fails" if not math.isfinite(gamma2) else threshold_verdict(product)
    if verdict != "holds":
        c = inf if not math.isfinite(gamma2) else gamma2 * (xi1 + xi2) * b_omega * T + mu0
        if not math.isfinite(gamma2):
            reason = "gamma2 = inf (I + Phi2 H is singular): no lambda gives b > 0"
        elif verdict == "marginal":
            reason = (f"gamma1 gamma2 = {product:.17g} equals 1 within the numerical "
                      f"tolerance {verdict_tolerance():.2g}: q = 1 - gamma1 gamma2 is rounding, "
                      "so whether some lambda gives a/b < 1 (eq 35) cannot be decided (it "
                      "would need lambda > gamma2 (xi1 + xi2) b_B / q)")
        else:
            reason = (f"gamma1 gamma2 = {product:.6g} >= 1: a(lambda)/b(lambda) > gamma1 gamma2 "
                      "for every lambda, so eq (35) never contracts")
        return LambdaCondition(gamma1, gamma2, xi1, xi2, mu0, b_B, T, k_f, b_omega, c,
                               holds=False, lambda_min=None, bound_at_lambda_min=inf,
                               lambda_opt=None, ultimate_bound=inf, sup_bound=inf,
                               bound_limit=inf, verdict=verdict, reason=reason)
    c = gamma2 * (xi1 + xi2) * b_omega * T + mu0
    q = 1.0 - gamma1 * gamma2
    K = gamma2 * (xi1 + xi2) * b_B
    bound_limit = c / q
    if K == 0.0:
        # rho does not matter: every lambda > k_f qualifies and the bound is c/q throughout.
        return LambdaCondition(gamma1, gamma2, xi1, xi2, mu0, b_B, T, k_f, b_omega, c,
                               holds=True, lambda_min=k_f, bound_at_lambda_min=bound_limit,
                               lambda_opt=k_f, ultimate_bound=bound_limit,
                               sup_bound=_sup(bound_limit, k_f, T), bound_limit=bound_limit)
    r = q / K
    if T / r > _EXP_NEGLIGIBLE:
        # e^{-xT} is below rounding for every x >= x_min, so g(x) = 1/x there and F has the
        # closed form of _far_optimum (no root search near the singular boundary)
        x_min, x_opt, gap = _far_optimum(q, K, T)
        if c == 0.0:
            return LambdaCondition(gamma1, gamma2, xi1, xi2, mu0, b_B, T, k_f, b_omega, c,
                                   holds=True, lambda_min=k_f + x_min, bound_at_lambda_min=0.0,
                                   lambda_opt=None, ultimate_bound=0.0,
                                   sup_bound=0.0, bound_limit=0.0)
        ultimate = c / gap
        return LambdaCondition(gamma1, gamma2, xi1, xi2, mu0, b_B, T, k_f, b_omega, c,
                               holds=True, lambda_min=k_f + x_min, bound_at_lambda_min=inf,
                               lambda_opt=k_f + x_opt, ultimate_bound=ultimate,
                               sup_bound=_sup(ultimate, k_f + x_opt, T),
                               bound_limit=bound_limit)
    if r >= T:
        x_min = 0.0
        gap0 = q - K * T
        at_min = c / gap0 if gap0 > 0 else inf
    else:
        w = scipy.special.lambertw(-(T / r) * math.exp(-T / r), 0).real
        x_min = (1.0 + (r / T) * w) / r
        # polish against the defining equation (W near its branch point loses digits)
        f = lambda x: K * _g(x, T) - q  # noqa: E731
        lo, hi = x_min * (1 - 1e-6), x_min * (1 + 1e-6) + 1e-300
        if f(lo) > 0 > f(hi):
            x_min = scipy.optimize.brentq(f, lo, hi, rtol=LAMBDA_RTOL, xtol=1e-300)
        at_min = inf
    lambda_min = k_f + x_min

    # lambda_opt: minimise F(x) = x T + ln c - ln(q - K g(x)) over x > x_min
    if c == 0.0:
        return LambdaCondition(gamma1, gamma2, xi1, xi2, mu0, b_B, T, k_f, b_omega, c,
                               holds=True, lambda_min=lambda_min, bound_at_lambda_min=0.0,
                               lambda_opt=None, ultimate_bound=0.0,
                               sup_bound=0.0, bound_limit=0.0)

    def dF(x: float) -> float:
        return T + K * _dg(x, T) / (q - K * _g(x, T))

    if math.isfinite(at_min) and dF(x_min) >= 0.0:
        x_opt = x_min  # the guarantee only grows with lambda: best at the (open) boundary
    else:
        # F' -> -inf at a singular boundary; step just inside it
        lo = x_min + max(x_min, 1.0 / T) * 1e-9 if not math.isfinite(at_min) else x_min
        hi = max(2.0 * lo, lo + 1.0 / T)
        while dF(hi) <= 0.0:
            hi *= 2.0
        x_opt = scipy.optimize.brentq(dF, lo, hi, rtol=LAMBDA_RTOL)
    lambda_opt = k_f + x_opt
    ultimate = c / (q - K * _g(x_opt, T))
    return LambdaCondition(gamma1, gamma2, xi1, xi2, mu0, b_B, T, k_f, b_omega, c,
                           holds=True, lambda_min=lambda_min, bound_at_lambda_min=at_min,
                           lambda_opt=lambda_opt, ultimate_bound=ultimate,
                           sup_bound=_sup(ultimate, lambda_opt, T), bound_limit=bound_limit)


#: Above this x T, :math:`e^{-xT}` is below double rounding relative to 1 (e^-40 = 4e-18).
_EXP_NEGLIGIBLE = 40.0


def _far_optimum(q: float, K: float, T: float) -> tuple[float, float, float]:
    r"""``(x_min, x_opt, q - K g(x_opt))`` when :math:`x_{\min}T = KT/q > 40`.

    There :math:`g(x) = 1/x` to rounding, so :math:`x_{\min} = K/q` and
    :math:`F(x) = xT + \ln c - \ln(q - K/x)` has :math:`F'(x) = 0` at the positive root of
    :math:`q x^2 - K x - K/T = 0`,

    .. math::

        x_{\mathrm{opt}} = \frac{K + \sqrt{K^2 + 4qK/T}}{2q},\qquad
        q - \frac{K}{x_{\mathrm{opt}}} = \frac{1}{x_{\mathrm{opt}}}\,
        \frac{2qK/T}{K + \sqrt{K^2 + 4qK/T}},

    written without the cancellation of :math:`q x - K` (which a root search of
    :math:`F'` near the singular boundary :math:`x_{\min}` cannot resolve when
    :math:`x_{\mathrm{opt}}/x_{\min} - 1 \approx q/(KT)` is below rounding).
    """
    root = K + math.sqrt(K * K + 4.0 * q * K / T)
    x_opt = root / (2.0 * q)
    gap = (2.0 * q * K / T) / root / x_opt
    return K / q, x_opt, gap


def _sup(bound: float, lam: float, T: float) -> float:
    """e^{λT}·bound without overflow warnings (inf when it does not fit a float)."""
    if bound == 0.0:
        return 0.0
    log_v = lam * T + math.log(bound)
    return math.exp(log_v) if log_v < 709.0 else float(np.inf)
