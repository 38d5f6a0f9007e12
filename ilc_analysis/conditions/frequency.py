r"""The frequency-domain condition for LTI plants and long trials (design.md §4).

With time-invariant gains and an LTI sampled plant :math:`G(z) = C(zI - A_d)^{-1}B_d + D`, the
law (11) in the index convention of :mod:`ilc_analysis.law` has the transfer matrices

.. math::

    L_1(z) = z^{s+\ell}\big(\Psi_1 + \Phi_1(1 - z^{-1})/T_s\big),\qquad
    L_2(z) = \Psi_2 + \Phi_2(1 - z^{-1})/T_s,

and trial to trial (for trials long against the plant's memory)

.. math::

    T(z) = Q(z)\,(I + L_2G)^{-1}\big((1-a)I - L_1G\big),\qquad
    \sup_{\theta\in[0,\pi]} \sigma_{\max}\,T(e^{j\theta}) < 1,

the MIMO form of :math:`\sup_\omega|Q(1 - LG)| < 1`. It requires the current-trial loop
:math:`(I + L_2G)^{-1}` to be stable (checked), and then bounds the lifted operator of every
trial length: :math:`\|T_N\|_2 \le \sup_\theta\sigma_{\max}T(e^{j\theta})` (T_N is a finite
section of the causal Toeplitz operator of T(z)), so it certifies monotone convergence in the
2-norm for all N. Q is a zero-phase filter applied between trials
(:class:`ilc_analysis.simulation.QFilter`), whose response is the real
:math:`|H(e^{j\theta})|^2` on every input channel.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control
import numpy as np

from .._validation import in_interval, positive_int
from ..exceptions import ParameterError, ShapeError
from ..law import PDGains

__all__ = ["FrequencyCondition", "frequency_condition", "frequency_assumptions",
           "DEFAULT_FREQUENCY_POINTS", "FREQUENCY_STABILITY_MARGIN"]

#: Frequency grid size on [0, π] rad/sample (plus the peak refined on a local grid).
DEFAULT_FREQUENCY_POINTS = 2048
#: Closed-loop eigenvalues with modulus >= 1 - this count as not asymptotically stable.
_STABILITY_MARGIN = 1e-9
#: PBH rank threshold (smallest singular value relative to ||A_cl||) for a hidden mode.
_PBH_RTOL = 1e-8
#: Local refinement around the grid maximum: points and half-width in grid steps.
_REFINE_POINTS, _REFINE_WIDTH = 201, 2


@dataclass(frozen=True)
class FrequencyCondition:
    r""":math:`\sigma_{\max}T(e^{j\omega T_s})` on a grid and its peak."""

    omega: np.ndarray = field(repr=False)
    """angular frequencies [rad/s] in (0, π/Ts) (cell midpoints of a uniform grid)"""
    sigma: np.ndarray = field(repr=False)
    """largest singular value of T at each frequency"""
    peak: float
    """sup over the grid (refined around the maximum)"""
    peak_omega: float
    """where the peak is [rad/s]"""
    closed_loop_stable: bool
    """the current-trial loop (I + L2 G)^{-1} is stable (else the condition does not apply)"""
    ts: float
    a: float

    @property
    def holds(self) -> bool:
        """Stable current-trial loop and peak < 1."""
        return self.closed_loop_stable and self.peak < 1.0

    def as_dict(self) -> dict:
        return {"peak": self.peak, "peak_omega": self.peak_omega,
                "closed_loop_stable": self.closed_loop_stable, "ts": self.ts, "a": self.a}

    def plot(self, ax=None, **line_kw):
        """Plot σ_max T against ω with the unit bound; returns ``(line, bound_line)``."""
        if ax is None:
            import matplotlib.pyplot as plt

            _, ax = plt.subplots()
        (line,) = ax.loglog(self.omega, self.sigma, label=r"$\sigma_{\max}\,T(e^{j\omega T_s})$",
                            **line_kw)
        bound = ax.axhline(1.0, color="k", linestyle="--", linewidth=1, label="unit bound")
        ax.set_xlabel(r"$\omega$ [rad/s]")
        ax.set_ylabel("gain per trial")
        ax.set_title("frequency-domain condition" + ("" if self.closed_loop_stable else
                                                     " (current-trial loop UNSTABLE)"))
        ax.legend()
        return line, bound


def _q_response(q_filter, theta: np.ndarray, ts: float) -> np.ndarray:
    """Real zero-phase magnitude of a QFilter (or a callable of ω [rad/s]) on the grid."""
    if q_filter is None:
        return np.ones_like(theta)
    if callable(q_filter) and not hasattr(q_filter, "kind"):
        q = np.asarray(q_filter(theta / ts))
        if q.shape != theta.shape:
            raise ShapeError(f"q_filter(omega) must return shape {theta.shape}; found {q.shape}")
        return q
    # theta is in rad/sample: f = theta / (2 pi ts) Hz
    return q_filter.magnitude(theta / (2.0 * np.pi * ts), ts)


def _T_response(theta, Ad, Bd, C, D, gains, a, shift, ts, q):
    z = np.exp(1j * theta)
    n_x = Ad.shape[0]
    I_x = np.eye(n_x)
    try:
        G = np.linalg.solve(z[:, None, None] * I_x - Ad,
                            np.broadcast_to(Bd, (len(z),) + Bd.shape))
    except np.linalg.LinAlgError as exc:
        raise ParameterError("the plant has a pole on the unit circle at a grid frequency; "
                             "change n_points") from exc
    G = C @ G + D
    diff = (1.0 - 1.0 / z)[:, None, None] / ts
    L1 = (z ** (shift + gains.lead))[:, None, None] * (gains.Psi1 + gains.Phi1 * diff)
    L2 = gains.Psi2 + gains.Phi2 * diff
    n_u = Bd.shape[1]
    I_u = np.eye(n_u)
    T = np.linalg.solve(I_u + L2 @ G, (1.0 - a) * I_u - L1 @ G)
    return q * np.linalg.norm(T, ord=2, axis=(-2, -1))


def frequency_condition(dsys: control.StateSpace, gains: PDGains, a: float = 0.0, *,
                        shift: int | None = None, q_filter=None,
                        n_points: int = DEFAULT_FREQUENCY_POINTS) -> FrequencyCondition:
    r"""Evaluate :math:`\sup_\theta \sigma_{\max} T(e^{j\theta})` (module docstring).

    Parameters
    ----------
    dsys : control.StateSpace
        Discrete-time LTI plant (``dt > 0``).
    gains : PDGains
        Time-invariant gains ``(n_u, n_y)``.
    a : float
        Constant forgetting factor in [0, 1).
    shift : int, optional
        Sampled relative degree s (default: first non-zero Markov parameter of ``dsys``).
    q_filter : QFilter or callable, optional
        Zero-phase Q-filter, or a function of ω [rad/s] returning the real Q on the grid.
    n_points : int
        Grid size on [0, π/Ts].
    """
    if not isinstance(dsys, control.StateSpace) or not dsys.isdtime(strict=True):
        raise ParameterError("dsys must be a discrete-time control.StateSpace (dt > 0)")
    if not isinstance(gains, PDGains):
        raise ParameterError(f"gains must be a PDGains; got {type(gains).__name__}")
    if gains.time_varying:
        raise ParameterError("the frequency-domain condition needs time-invariant gains; "
                             "use the lifted checks for time-varying gains")
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    n_points = positive_int(n_points, "n_points", minimum=8)
    Ad, Bd, C, D = (np.asarray(M, dtype=float) for M in (dsys.A, dsys.B, dsys.C, dsys.D))
    gains.check_dimensions(Bd.shape[1], C.shape[0])
    ts = float(dsys.dt)
    if shift is None:
        from .relative_degree_form import _first_markov

        shift, _ = _first_markov(dsys, 1e-10)
    # cell midpoints: avoids z = 1 and z = -1, where integrators put poles on the circle
    theta = np.pi * (np.arange(n_points) + 0.5) / n_points
    q = _q_response(q_filter, theta, ts)
    sigma = _T_response(theta, Ad, Bd, C, D, gains, a, shift, ts, q)
    k = int(np.argmax(sigma))
    step = theta[1] - theta[0]
    local = np.clip(np.linspace(theta[k] - _REFINE_WIDTH * step, theta[k] + _REFINE_WIDTH * step,
                                _REFINE_POINTS), theta[0] / 2, np.pi - theta[0] / 2)
    s_local = _T_response(local, Ad, Bd, C, D, gains, a, shift, ts,
                          _q_response(q_filter, local, ts))
    j = int(np.argmax(s_local))
    peak, peak_theta = (float(s_local[j]), float(local[j])) if s_local[j] > sigma[k] \
        else (float(sigma[k]), float(theta[k]))
    stable = _current_loop_stable(Ad, Bd, C, D, gains, ts)
    return FrequencyCondition(theta / ts, sigma, peak, peak_theta / ts, stable, ts, a)


def _current_loop_stable(Ad, Bd, C, D, gains: PDGains, ts: float) -> bool:
    r"""Whether :math:`S(z) = (I + L_2(z)G(z))^{-1}` is stable.

    :math:`L_2` as a state space: :math:`x_e(k+1) = e(k)`,
    :math:`u = (\Psi_2 + \Phi_2/T_s)e - (\Phi_2/T_s)x_e`. S maps v to u with
    :math:`u = v - L_2Gu`. A closed-loop eigenvalue on or outside the unit circle makes S
    unstable unless it is hidden from it: uncontrollable from v or unobservable in u (PBH
    rank test), e.g. the lateral position Y of the mobile robot at rest, which u cannot move.
    """
    K_d = gains.Psi2 + gains.Phi2 / ts
    K_x = -gains.Phi2 / ts
    n_u = Bd.shape[1]
    M = np.eye(n_u) + K_d @ D
    Minv = np.linalg.inv(M)
    # u = Minv (v - K_d C x - K_x x_e)... with e = -(C x + D u) (r = 0):
    # u = Minv (v - K_d C x + K_x x_e) where x_e holds e(k-1)
    Ku_x = -Minv @ K_d @ C
    Ku_e = Minv @ K_x
    Acl = np.block([[Ad + Bd @ Ku_x, Bd @ Ku_e], [-(C + D @ Ku_x), -(D @ Ku_e)]])
    Bcl = np.vstack([Bd @ Minv, -(D @ Minv)])
    Ccl = np.hstack([Ku_x, Ku_e])
    n = Acl.shape[0]
    scale = max(np.linalg.norm(Acl, 2), 1.0)
    for lam in np.linalg.eigvals(Acl):
        if abs(lam) < 1.0 - _STABILITY_MARGIN:
            continue
        shifted = lam * np.eye(n) - Acl
        ctrb = np.linalg.svd(np.hstack([shifted, Bcl]), compute_uv=False)[-1]
        obsv = np.linalg.svd(np.vstack([shifted, Ccl]), compute_uv=False)[-1]
        if ctrb > _PBH_RTOL * scale and obsv > _PBH_RTOL * scale:
            return False
    return True


#: Plant poles with modulus above 1 - this are treated as unstable or marginal (an integrator).
FREQUENCY_STABILITY_MARGIN = 1e-9


def frequency_assumptions(dsys, gains: PDGains, q_filter) -> str | None:
    r"""Why the frequency condition cannot certify this law on a finite trial, or None.

    :math:`\sup_\omega\sigma_{\max}T(e^{j\omega}) < 1` bounds the lifted operator of every
    trial length only when :math:`T(z)` is a causal, stable system, so that the lifted T is a
    finite section of its Toeplitz operator. A lead or a zero-phase (forward-backward or DCT)
    Q-filter is non-causal: its finite-trial matrix differs near the trial ends (a lifted norm
    of 3.1 was measured with the forward-backward filter whose frequency response is <= 1). A
    plant pole on or outside the unit circle (an integrator, an unstable plant) puts a pole of
    T(z) there unless the feedback cancels it exactly, which floating-point gains never do.
    """
    if gains.lead > 0:
        return (f"the lead ({gains.lead} samples) makes the learning filter non-causal: the "
                "finite-trial operator is not bounded by the frequency response")
    if q_filter is not None:
        return (f"the {q_filter.kind} Q-filter is zero-phase (non-causal) on a finite trial: "
                "its lifted matrix is not bounded by its frequency response")
    poles = np.linalg.eigvals(np.asarray(dsys.A, dtype=float)) if dsys.nstates else np.zeros(0)
    worst = float(np.max(np.abs(poles))) if poles.size else 0.0
    if worst >= 1.0 - FREQUENCY_STABILITY_MARGIN:
        return (f"the sampled plant has a pole of modulus {worst:.6g} >= 1 (unstable or an "
                "integrator): T(z) is not a stable system")
    return None
