r"""The frequency-domain condition for LTI plants and long trials (docs/theory.md §6, §8).

With time-invariant gains and an LTI sampled plant :math:`G(z) = C(zI - A_d)^{-1}B_d + D`, the
law (11) in the index convention of :mod:`ilc_analysis.laws` has the transfer matrices

.. math::

    L_1(z) = z^{s+\ell}\big(\Psi_1 + \Phi_1(1 - z^{-1})/T_s\big),\qquad
    L_2(z) = \Psi_2 + \Phi_2(1 - z^{-1})/T_s,

and trial to trial (for trials long against the plant's memory)

.. math::

    T(z) = Q(z)\,(I + L_2G)^{-1}\big((1-a)I - L_1G\big),\qquad
    \sup_{\theta\in[0,\pi]} \sigma_{\max}\,T(e^{j\theta}) < 1,

the MIMO form of :math:`\sup_\omega|Q(1 - LG)| < 1`. Q is a zero-phase filter applied between
trials (:class:`ilc_analysis.simulation.QFilter`), whose response is the real
:math:`|H(e^{j\theta})|^2` on every input channel.

**When the peak is a certificate.** If T(z) is a *causal, stable* system, the lifted operator
of a trial of N samples is a finite section of its causal block-Toeplitz operator, so
:math:`\|T_N\|_2 \le \sup_\theta\sigma_{\max}T(e^{j\theta})` for every N: a peak below 1
certifies monotone 2-norm convergence for all trial lengths. Each assumption is checked
(:func:`frequency_assumptions`), and where one fails the verdict is ``not applicable`` with
the reason, never ``holds``:

* no lead and :math:`s \le` the plant's relative degree: otherwise :math:`L_1` reads errors
  beyond the sample it updates (non-causal), the finite trial lacks them near its end and
  :math:`T_N` is not a section of T(z) (a three-lag plant with lead 2: peak 0.938, every
  :math:`\|T_N\|_2 = 1.063`);
* no Q-filter: a zero-phase (forward-backward, DCT) filter is non-causal, and its lifted
  matrix is not bounded by its frequency response (forward-backward Butterworth: peak 0.41,
  lifted norm 3.1);
* every plant pole strictly inside the unit circle (margin
  :data:`FREQUENCY_STABILITY_MARGIN`): an unstable pole stays a pole of T(z) unless the gains
  cancel it exactly, which floating-point gains never do (1/(s - 2): peak 9.5e-16, but
  :math:`\|T_{300}\|_2 = 4.6\cdot 10^9`), and an integrator puts a pole of T at z = 1,
  between the grid points (peak 0.78, :math:`\|T_{8000}\|_2 = 1.53`);
* the current-trial loop :math:`(I + L_2G)^{-1}` stable.

Then the poles of T(z) are among the plant's, the loop's and z = 0, all inside the circle. The
peak is taken over the grid **and** over points placed at every pole with modulus
:math:`\ge 1/2` (at its angle and at offsets of a few times its distance :math:`1 - |\lambda|`
to the circle), then refined around the maximum: a lightly damped pole makes a peak narrower
than any grid spacing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control
import numpy as np

from .._validation import in_interval, positive_int
from ..exceptions import ParameterError, ShapeError
from ..laws._gains import PDGains
from ._verdicts import threshold_verdict

__all__ = ["FrequencyCondition", "frequency_condition", "frequency_assumptions",
           "law_frequency_condition", "law_frequency_assumptions",
           "DEFAULT_FREQUENCY_POINTS", "FREQUENCY_STABILITY_MARGIN"]

#: Frequency grid size on [0, π] rad/sample (plus the peak refined on a local grid).
DEFAULT_FREQUENCY_POINTS = 2048
#: Closed-loop eigenvalues with modulus >= 1 - this count as not asymptotically stable.
_STABILITY_MARGIN = 1e-9
#: PBH rank threshold (smallest singular value relative to ||A_cl||) for a hidden mode.
_PBH_RTOL = 1e-8
#: Local refinement around the maximum: points between its neighbouring evaluation points.
_REFINE_POINTS = 201
#: Poles of at least this modulus get evaluation points of their own.
_POLE_MODULUS = 0.5
#: Offsets of those points from the pole's angle, in units of its distance 1 - |lambda| to the
#: unit circle (|T| peaks within a few such widths of the angle).
_POLE_OFFSETS = np.array([-8.0, -4.0, -2.0, -1.0, -0.5, -0.25, 0.0, 0.25, 0.5, 1.0, 2.0, 4.0,
                          8.0])


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
    """sample time [s] of the sampled plant (``dsys.dt``)"""
    a: float
    """the constant forgetting factor T was evaluated at, in [0, 1]"""
    verdict: str = "not applicable"
    """``holds`` / ``marginal`` / ``fails`` (:func:`~.verdicts.threshold_verdict` of the peak
    against 1) when every assumption of the module docstring holds, else ``not applicable``"""
    reason: str = ""
    """what the verdict means, or the assumption that failed"""

    @property
    def holds(self) -> bool:
        """The verdict is ``holds``: every assumption checked and the peak below 1 by more than
        the tolerance band (then :math:`\\|T_N\\|_2 < 1` for every trial length N)."""
        return self.verdict == "holds"

    @property
    def applicable(self) -> bool:
        """T(z) is causal and stable: the peak bounds the lifted operator of every N."""
        return self.verdict != "not applicable"

    def as_dict(self) -> dict:
        return {"peak": self.peak, "peak_omega": self.peak_omega,
                "closed_loop_stable": self.closed_loop_stable, "ts": self.ts, "a": self.a,
                "verdict": self.verdict, "reason": self.reason}

    def plot(self, ax=None, **line_kw):
        """Plot σ_max T against ω with the unit bound; returns ``(line, bound_line)``.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure's axes).
        """
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
        from ._relative_degree_form import _first_markov

        shift, _ = _first_markov(dsys, 1e-10)
    # cell midpoints: avoids z = 1 and z = -1, where integrators put poles on the circle
    theta = np.pi * (np.arange(n_points) + 0.5) / n_points
    q = _q_response(q_filter, theta, ts)
    sigma = _T_response(theta, Ad, Bd, C, D, gains, a, shift, ts, q)
    Acl, Bcl, Ccl = _current_loop(Ad, Bd, C, D, gains, ts)
    stable = _current_loop_stable(Acl, Bcl, Ccl)
    why = frequency_assumptions(dsys, gains, q_filter, shift=shift)
    if why is None and not stable:
        why = ("the current-trial loop (I + L2 G)^-1 is unstable: T(z) is not a stable "
               "system")

    def response(t):
        return _T_response(t, Ad, Bd, C, D, gains, a, shift, ts, _q_response(q_filter, t, ts))

    # T(z) stable: its poles are the plant's, the loop's and 0
    poles = np.concatenate([np.linalg.eigvals(Ad) if Ad.size else [], np.linalg.eigvals(Acl)])
    return _condition(response, theta, sigma, poles, why, stable, ts, a,
                      "no lead, no Q-filter, plant and current-trial loop stable")


def _condition(response, theta, sigma, poles, why: str | None, stable: bool, ts: float,
               a: float, causal_because: str) -> FrequencyCondition:
    """The peak of ``response`` (σ_max T on angles [rad/sample]) over the grid ``theta`` (values
    ``sigma``) and, when T(z) is causal and stable (``why`` None), around the ``poles`` of T
    near the unit circle, refined; the verdict is ``threshold_verdict(peak, 1)`` then, else
    ``not applicable`` with ``why``. Shared by :func:`frequency_condition` and
    :func:`law_frequency_condition`."""
    points, values = theta, sigma
    if why is None:
        # a lightly damped pole peaks between the grid points
        extra = _pole_points(poles)
        if extra.size:
            points = np.concatenate([theta, extra])
            values = np.concatenate([sigma, response(extra)])
            order = np.argsort(points, kind="stable")
            points, values = points[order], values[order]
    peak, peak_theta = _refine(response, points, values)
    if why is None:
        verdict = threshold_verdict(peak, 1.0)
        reason = ("sup_w sigma_max T(e^jw) over the grid and the poles of T near the unit "
                  f"circle; T(z) is causal and stable ({causal_because}), so < 1 bounds "
                  "||T_N||_2 for every trial length N")
    else:
        verdict, reason = "not applicable", why
    return FrequencyCondition(theta / ts, sigma, peak, peak_theta / ts, stable, ts, a,
                              verdict, reason)


def _pole_points(poles) -> np.ndarray:
    r"""Frequencies [rad/sample] in :math:`[0, \pi]` around every stable pole with modulus in
    [:data:`_POLE_MODULUS`, 1): at its angle and :data:`_POLE_OFFSETS` times its distance to the
    unit circle from it."""
    out = []
    for lam in np.asarray(poles):
        r = abs(lam)
        if not (_POLE_MODULUS <= r < 1.0 - _STABILITY_MARGIN):
            continue
        out.append(abs(np.angle(lam)) + (1.0 - r) * _POLE_OFFSETS)
    if not out:
        return np.zeros(0)
    return np.unique(np.clip(np.concatenate(out), 0.0, np.pi))


def _refine(response, points: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """The largest value, refined between the neighbours of the maximum (sorted points): a
    grid of :data:`_REFINE_POINTS`, then a bounded scalar search around its best point."""
    import scipy.optimize

    k = int(np.argmax(values))
    best, where = float(values[k]), float(points[k])
    # beyond the first and last point: half-way to z = 1 and z = -1 (the grid's cell edges)
    lo = points[k - 1] if k > 0 else points[k] / 2
    hi = points[k + 1] if k + 1 < len(points) else (points[k] + np.pi) / 2
    local = np.linspace(lo, hi, _REFINE_POINTS)
    s_local = response(local)
    j = int(np.argmax(s_local))
    if s_local[j] > best:
        best, where = float(s_local[j]), float(local[j])
    a_, b_ = local[max(j - 1, 0)], local[min(j + 1, len(local) - 1)]
    if b_ > a_:
        res = scipy.optimize.minimize_scalar(lambda t: -float(response(np.array([t]))[0]),
                                             bounds=(a_, b_), method="bounded",
                                             options={"xatol": 1e-12 * max(1.0, b_)})
        if -res.fun > best:
            best, where = float(-res.fun), float(res.x)
    return best, where


def _current_loop(Ad, Bd, C, D, gains: PDGains, ts: float):
    r"""A realisation :math:`(A_{cl}, B_{cl}, C_{cl})` of :math:`S(z) = (I + L_2(z)G(z))^{-1}`.

    :math:`L_2` as a state space: :math:`x_e(k+1) = e(k)`,
    :math:`u = (\Psi_2 + \Phi_2/T_s)e - (\Phi_2/T_s)x_e`. S maps v to u with
    :math:`u = v - L_2Gu`.
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
    return Acl, Bcl, Ccl


def _current_loop_stable(Acl, Bcl, Ccl) -> bool:
    r"""Whether :math:`S(z) = (I + L_2(z)G(z))^{-1}` (realised by :func:`_current_loop`) is
    stable.

    A closed-loop eigenvalue on or outside the unit circle makes S unstable unless it is hidden
    from it: uncontrollable from v or unobservable in u (PBH rank test), e.g. the lateral
    position Y of the mobile robot at rest, which u cannot move.
    """
    n = Acl.shape[0]
    scale = max(float(np.linalg.norm(Acl, 2)), 1.0)
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


def frequency_assumptions(dsys, gains: PDGains, q_filter, *,
                          shift: int | None = None) -> str | None:
    r"""Why the frequency condition cannot certify this law on a finite trial, or None.

    :math:`\sup_\omega\sigma_{\max}T(e^{j\omega}) < 1` bounds the lifted operator of every
    trial length only when :math:`T(z)` is a causal, stable system, so that the lifted T is a
    finite section of its Toeplitz operator. A lead, a shift s beyond the plant's relative
    degree (``shift``, if given) or a zero-phase (forward-backward or DCT) Q-filter is
    non-causal: its finite-trial matrix differs near the trial ends (a lifted norm of 3.1 was
    measured with the forward-backward filter whose frequency response is <= 1). A plant pole
    on or outside the unit circle (an integrator, an unstable plant) puts a pole of T(z) there
    unless the feedback cancels it exactly, which floating-point gains never do. (The
    current-trial loop is checked by :func:`frequency_condition`.)

    Parameters
    ----------
    dsys : control.StateSpace
        The sampled plant.
    gains : ~ilc_analysis.laws.PDGains
        The PD learning gains.
    q_filter : object or None
        The law's Q-filter (None: none).
    shift : int, optional
        The trial's output shift s, checked against the relative degree.
    """
    if gains.lead > 0:
        return (f"the lead ({gains.lead} samples) makes the learning filter non-causal: the "
                "finite-trial operator is not bounded by the frequency response")
    if q_filter is not None:
        kind = getattr(q_filter, "kind", "given")
        return (f"the {kind} Q-filter is zero-phase (non-causal) on a finite trial: "
                "its lifted matrix is not bounded by its frequency response")
    return _plant_assumptions(dsys, shift)


def _plant_assumptions(dsys, shift: int | None) -> str | None:
    """The plant's part of :func:`frequency_assumptions` (any law): the shift within the
    sampled relative degree, every plant pole strictly inside the unit circle."""
    if shift is not None:
        from ._relative_degree_form import _first_markov

        degree, _ = _first_markov(dsys, 1e-10)
        if int(shift) > degree:
            return (f"the shift s = {int(shift)} exceeds the sampled relative degree "
                    f"{degree}: L1 = z^s (...) reads errors the plant has not produced yet "
                    "(non-causal), so the finite-trial operator is not bounded by the "
                    "frequency response")
    poles = np.linalg.eigvals(np.asarray(dsys.A, dtype=float)) if dsys.nstates else np.zeros(0)
    worst = float(np.max(np.abs(poles))) if poles.size else 0.0
    if worst >= 1.0 - FREQUENCY_STABILITY_MARGIN:
        return (f"the sampled plant has a pole of modulus {worst:.6g} >= 1 (unstable or an "
                "integrator): T(z) is not a stable system")
    return None


# ---------------------------------------------------------------------------------------------
# any learning law (ilc_analysis.laws), from its frequency response
# ---------------------------------------------------------------------------------------------
def _ql_of(law):
    """The :class:`~ilc_analysis.laws.QLLaw` a law is (itself, or the ``ql`` it wraps)."""
    from ..laws import QLLaw

    if isinstance(law, QLLaw):
        return law
    inner = getattr(law, "ql", None)
    return inner if isinstance(inner, QLLaw) else None


def _filter_poles(law) -> np.ndarray:
    """Poles of a Q/L law's LTI filters L' and Q (empty for other laws)."""
    from ..laws import LTIFilter

    ql = _ql_of(law)
    if ql is None:
        return np.zeros(0)
    out = [np.linalg.eigvals(f.A) for f in (ql._L, ql._Q)
           if isinstance(f, LTIFilter) and f.A.size]
    return np.concatenate(out) if out else np.zeros(0)


def law_frequency_assumptions(dsys, law, *, shift: int | None = None) -> str | None:
    r"""Why the frequency condition cannot certify ``law`` on a finite trial, or None.

    The same argument as :func:`frequency_assumptions` (T(z) must be a causal, stable system for
    its peak to bound :math:`\|T_N\|_2` for every N), per law:

    * :class:`~ilc_analysis.laws.PDLaw` — :func:`frequency_assumptions` (no lead, no Q-filter);
    * Q/L laws (:class:`~ilc_analysis.laws.QLLaw`, inverse model) — no advance, Q absent or a
      causal LTI filter (not zero-phase, not a QFilter), and the filters L', Q stable;
    * gradient, time-reversal and norm-optimal ILC — never: their learning filter
      (:math:`\beta P^H`, :math:`(P^HW_eP + W_\Delta)^{-1}P^HW_e`) is anti-causal, so the
      peak describes infinitely long trials only;
    * any other law — not known to be causal;

    and for every law the plant's part (shift within the relative degree, plant poles inside
    the unit circle).

    Parameters
    ----------
    dsys : control.StateSpace
        The sampled plant.
    law : ~ilc_analysis.laws.LearningLaw
        The learning law.
    shift : int, optional
        The trial's output shift s, checked against the relative degree.
    """
    from ..laws import GradientLaw, NormOptimalLaw, PDLaw, TimeReversalLaw
    from ..laws._qfilter import QFilter

    if isinstance(law, PDLaw):
        return frequency_assumptions(dsys, law.gains, law.q_filter, shift=shift)
    ql = _ql_of(law)
    if ql is not None:
        if ql.advance > 0:
            return (f"the advance ({ql.advance} samples) makes the learning filter non-causal: "
                    "the finite-trial operator is not bounded by the frequency response")
        if isinstance(ql._Q, QFilter):
            return (f"the {ql._Q.kind} Q-filter is zero-phase (non-causal) on a finite trial: "
                    "its lifted matrix is not bounded by its frequency response")
        if ql.zero_phase:
            return ("the Q-filter runs forward and backward (zero phase, non-causal): its "
                    "lifted matrix is not bounded by its frequency response")
        poles = _filter_poles(law)
        worst = float(np.max(np.abs(poles))) if poles.size else 0.0
        if worst >= 1.0 - FREQUENCY_STABILITY_MARGIN:
            return (f"a learning filter (L' or Q) has a pole of modulus {worst:.6g} >= 1: "
                    "T(z) is not a stable system")
    elif isinstance(law, GradientLaw | TimeReversalLaw | NormOptimalLaw):
        return (f"the learning filter of {law.name} ILC is built on the adjoint P^H (anti-"
                "causal): the finite-trial operator is not a section of T(z), so the peak "
                "describes infinitely long trials only")
    else:
        return (f"the causality of {type(law).__name__}'s filters is not known: the peak is "
                "not a certificate for a finite trial")
    return _plant_assumptions(dsys, shift)


def law_frequency_condition(dsys: control.StateSpace, law, a: float = 0.0, *,
                            shift: int | None = None,
                            n_points: int = DEFAULT_FREQUENCY_POINTS) -> FrequencyCondition:
    r""":math:`\sup_\theta\sigma_{\max}T(e^{j\theta})` of any learning law (module docstring).

    :math:`T(e^{j\theta}) = S\,Q\,((1-a)I - L P)` from the law's
    :meth:`~ilc_analysis.laws.LearningLaw.frequency_response` and
    :meth:`~ilc_analysis.laws.LawResponse.operator` on the plant response
    :func:`~ilc_analysis.laws.plant_response`, on the grid of :func:`frequency_condition`,
    with the same peak search and verdict; the assumptions are
    :func:`law_frequency_assumptions`. A :class:`~ilc_analysis.laws.PDLaw` is passed to
    :func:`frequency_condition` itself (identical numbers).

    Parameters
    ----------
    dsys : control.StateSpace
        Discrete-time LTI plant (``dt > 0``).
    law : LearningLaw
    a : float
        Forgetting factor in [0, 1) (a value within a variable factor's bounds).
    shift : int, optional
        Sampled relative degree s (default: that of ``dsys``).
    n_points : int
        Grid size on [0, π/Ts].

    Raises
    ------
    ParameterError
        ``dsys`` not discrete, ``law`` not a LearningLaw, or a law without a frequency response
        (e.g. time-varying gains, a norm-optimal law with weights varying along the trial, a
        model-based law whose model is not ``dsys``).
    """
    from ..laws import LearningLaw, PDLaw
    from ..laws._base import as_lti_plant, plant_response

    if not isinstance(dsys, control.StateSpace) or not dsys.isdtime(strict=True):
        raise ParameterError("dsys must be a discrete-time control.StateSpace (dt > 0)")
    if not isinstance(law, LearningLaw):
        raise ParameterError(f"law must be a LearningLaw; got {type(law).__name__}")
    if isinstance(law, PDLaw):
        return frequency_condition(dsys, law.gains, a, shift=shift, q_filter=law.q_filter,
                                   n_points=n_points)
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    n_points = positive_int(n_points, "n_points", minimum=8)
    ts = float(dsys.dt)
    if shift is None:
        from ._relative_degree_form import _first_markov

        shift, _ = _first_markov(dsys, 1e-10)

    plant = as_lti_plant(dsys, "dsys")     # once: the law and P(z) are evaluated many times

    def response(t):
        omega = np.clip(np.asarray(t, dtype=float), 0.0, np.pi) / ts
        resp = law.frequency_response(plant, omega, shift=shift)
        T = resp.operator(plant_response(plant, omega), a)
        return np.linalg.norm(T, ord=2, axis=(-2, -1))

    theta = np.pi * (np.arange(n_points) + 0.5) / n_points
    sigma = response(theta)
    why = law_frequency_assumptions(dsys, law, shift=shift)
    A = np.asarray(dsys.A, dtype=float)
    poles = np.concatenate([np.linalg.eigvals(A) if A.size else [], _filter_poles(law)])
    return _condition(response, theta, sigma, poles, why, True, ts, a,
                      "no advance, causal Q and L filters, all stable, plant stable")
