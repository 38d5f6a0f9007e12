r"""Single precision with a proof: the rounding of the update as a bounded disturbance per trial.

The generated update in single precision computes, from the last input and the record, a next
input :math:`\hat f_{i+1} = F(f_i, y_i) + \delta_i` with the rounding :math:`\delta_i`
bounded stage by stage (:meth:`~ilc_analysis.export._plan.UpdatePlan.rounding`: the standard
model of floating-point arithmetic, forward error bounds :math:`\gamma_n`); the in-trial step
rounds the applied input by :math:`\xi_i`. On the certified operator (the lifted law
:math:`u_{i+1} = T(A_i)u_i + c(A_i)` on ``problem.lifted``, u the input the trial applies,
:math:`A_i` the forgetting the trial's error gives), the float run :math:`\tilde u_i` obeys

.. math::

    \tilde u_{i+1} = T(A_i)\,\tilde u_i + c(A_i) + p_i,\qquad
    p_i = S\big(\delta_i + \xi_{i+1} - Q(I - A_i)\xi_i\big),\qquad S = (I + L_2G)^{-1},

so its distance :math:`d_i = \tilde u_i - u'_i` to the exact run :math:`u'` of the same law
(with the same factors :math:`A_i`: for a fixed forgetting factor, simply the exact run)
satisfies :math:`\|d_{i+1}\|_2 \le \tau\|d_i\|_2 + \|p_i\|_2` with the certificate's proven
contraction :math:`\tau \ge \sup_A\|T(A)\|_2` (``norm_2``, or ``forgetting_box_upper`` for a
variable factor). With :math:`\|p_i\|_2 \le P(\|d_i\|_2)`, the bound of the rounding at the
magnitudes of a run within :math:`\|d_i\|` of the exact one (:math:`\|u'_i\|_2 \le M_u`,
:math:`\|e'_i\|_2 \le M_e`), and the first input's rounding :math:`d_1`, induction gives

.. math::

    \|\tilde u_i - u'_i\|_2 \le D^\star\ \ \forall i,\qquad
    D^\star = \min\{D \ge \|d_1\|_2:\ P(D) \le (1 - \tau)D\},

the input-error floor the rounding adds, and :math:`\|G\|_2 D^\star` for the tracking error.
:math:`D^\star` exists iff the certificate's margin :math:`1 - \tau` absorbs the rounding's
growth with D (:math:`P'(D) < 1 - \tau`); else single precision is refused. The magnitudes
are bounded a priori on the certified operator: for a fixed factor the exact run contracts to
its fixed point :math:`u^\star`, :math:`\|u'_i\|_2 \le \|u^\star\|_2 + \|u'_1 - u^\star\|_2`;
for a variable one, with :math:`u^\star_0` the fixed point at :math:`A_0 = a_{max}I`,
:math:`\|u'_i - u^\star_0\|_2 \le \max(\|u'_1 - u^\star_0\|_2,\ \|SQ\|_2 a_{max}
\|u_0 - u^\star_0\|_2/(1-\tau))` (:math:`T(A)u^\star_0 + c(A) - u^\star_0 =
SQ(A - A_0)(u_0 - u^\star_0)`). The error :math:`e = r - Gu`, :math:`r = y_d - d`, gives
:math:`M_e = \|r\|_2 + \|G\|_2M_u`.

Assumptions (stated in the generated header): IEEE 754 binary32 with round to nearest
(:math:`u = 2^{-24}`; a fused multiply-add or wider intermediates only remove roundings),
libm's double ``exp`` within a few ulps of double, and the plant the certified lifted
operator (the guarantee is on the model the certificate is about).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import ExportRefusedError
from ._c import UNIT_ROUNDOFF
from ._plan import UpdatePlan
from ._signals import ForgettingStage, spectral_norm
from ._stage import Sig

__all__ = ["RoundingBound", "single_precision_bound"]

#: Relative widening of the certificate's contraction for the rounding of its computation.
_TAU_WIDENING = 1e-9
#: Fixed-point iterations of D* before the rounding is declared not absorbed.
_MAX_STEPS = 500


@dataclass(frozen=True)
class RoundingBound:
    r"""The proven effect of single-precision rounding on the certified iteration (module
    docstring). Norms are 2-norms over the trial."""

    tau: float
    """the certificate's contraction :math:`\\tau` (proven bound of :math:`\\|T\\|_2`)"""
    tau_source: str
    """which certificate number gives it (``norm_2`` or ``forgetting_box_upper``)"""
    unit_roundoff: float
    """u of the arithmetic (2^-24)"""
    norms: dict
    """:math:`\\|S\\|_2, \\|Q\\|_2, \\|G\\|_2, \\|L_2\\|_2` of the certified operator"""
    magnitudes: dict
    """the a-priori bounds :math:`M_u, M_e, M_f` of the exact run's applied input, error and
    feed-forward"""
    first: float
    """:math:`\\|d_1\\|_2`, the rounding of the first input"""
    per_trial: float
    """:math:`P(D^\\star)`: the rounding each trial adds, at most"""
    input_floor: float
    """:math:`D^\\star`: the input-error floor the rounding adds, at most"""
    tracking_floor: float
    """:math:`\\|G\\|_2 D^\\star`: the tracking-error floor it adds, at most"""
    slope: float
    """:math:`P'(D^\\star)/(1 - \\tau)`, below 1 when the margin absorbs the rounding"""

    def as_dict(self) -> dict:
        return {"tau": self.tau, "tau_source": self.tau_source,
                "unit_roundoff": self.unit_roundoff, "norms": dict(self.norms),
                "magnitudes": dict(self.magnitudes), "first_input_rounding": self.first,
                "per_trial_rounding": self.per_trial, "input_error_floor": self.input_floor,
                "tracking_error_floor": self.tracking_floor, "slope": self.slope}

    def summary(self) -> str:
        return (f"single precision: the rounding adds at most {self.per_trial:.3g} per trial "
                f"(2-norm over the trial, at the run's a-priori magnitudes |u| <= "
                f"{self.magnitudes['M_u']:.3g}, |e| <= {self.magnitudes['M_e']:.3g}); with the "
                f"certificate's contraction tau = {self.tau:.6g} ({self.tau_source}) the float "
                f"run stays within {self.input_floor:.3g} of the exact one in the input "
                f"(||u_i - u'_i||_2, every trial) and within {self.tracking_floor:.3g} in the "
                f"tracking error (||G||_2 = {self.norms['G']:.4g}); proven, u = 2^-24")


def _tau(check, certificate: dict) -> tuple[float, str]:
    """The certificate's proven contraction in the 2-norm, from the re-check's numbers."""
    numbers = dict(check.numbers)
    if "forgetting_box_upper" in numbers:
        value, source = float(numbers["forgetting_box_upper"]), "forgetting_box_upper"
    else:
        value, source = float(numbers["norm_2"]), "norm_2"
    if not value < 1.0:
        raise ExportRefusedError(
            "in single precision", f"the certificate does not make the trial-to-trial operator "
            f"a contraction in the 2-norm ({source} = {value:.6g} >= 1; it certifies "
            f"{certificate.get('quantity', 'norm_2')}): no margin absorbs the rounding, so no "
            f"floor can be proven; export in double")
    return value * (1.0 + _TAU_WIDENING), source


def single_precision_bound(problem, law, plan: UpdatePlan, check,
                           certificate: dict) -> RoundingBound:
    """The proven floor single-precision rounding adds (module docstring).

    Parameters
    ----------
    problem : ILCProblem
        The design's problem (its lifted system is the certified operator's plant).
    law : LearningLaw
        The design's law.
    plan : UpdatePlan
        The generated update (its stages' rounding bounds).
    check : DesignCheck
        The certificate's re-check (its numbers give the contraction).
    certificate : dict
        The design's certificate.

    Returns
    -------
    RoundingBound

    Raises
    ------
    ExportRefusedError
        No contraction in the 2-norm, a law without a rounding analysis, or a margin that
        does not absorb the rounding.
    """
    if plan.stateful is not None:
        raise ExportRefusedError(
            "in single precision", "the time-reversal law's extra experiments run the plant on "
            "the rounded error and accumulate the measured gradient across runs; this export "
            "has no rounding analysis of that loop: export in double")
    u = UNIT_ROUNDOFF["single"]
    tau, source = _tau(check, certificate)
    ls = problem.lifted
    ll = law.lifted(ls)
    q = ls.N * ls.n_u
    G = np.asarray(ls.G, dtype=float)
    L1 = _dense(ll.L1)
    L2 = None if ll.L2 is None else _dense(ll.L2)
    Q = np.eye(q) if ll.Q is None else _dense(ll.Q)
    S = np.eye(q) if L2 is None else np.linalg.inv(np.eye(q) + L2 @ G)
    norms = {"S": spectral_norm(S), "Q": spectral_norm(Q), "G": spectral_norm(G),
             "L2": 0.0 if L2 is None else spectral_norm(L2), "SQ": spectral_norm(S @ Q)}
    r = np.asarray(problem.r, dtype=float).reshape(-1)
    offset = ll.parts.get("offset")
    offset = np.zeros(q) if offset is None else np.asarray(offset, dtype=float)
    forgetting = next((s for s in plan.stages if isinstance(s, ForgettingStage)), None)
    a_max = 0.0 if forgetting is None else forgetting.a_max
    u0 = (np.zeros(q) if forgetting is None or forgetting.u0 is None
          else np.asarray(forgetting.u0, dtype=float).reshape(-1))
    a_fixed = (ll.a if not isinstance(ll.a, tuple) else a_max)

    def fixed_point(a: float) -> np.ndarray:
        T = S @ Q @ ((1.0 - a) * np.eye(q) - L1 @ G)
        c = S @ (Q @ (a * u0 + L1 @ r) + offset + (0.0 if L2 is None else L2 @ r))
        return np.linalg.solve(np.eye(q) - T, c)

    ff1 = np.asarray(problem.initial_input(), dtype=float).reshape(-1)
    u1 = S @ (ff1 + (0.0 if L2 is None else L2 @ r))
    u_c = fixed_point(float(a_fixed))
    if isinstance(ll.a, tuple):
        spread = max(float(np.linalg.norm(u1 - u_c)),
                     norms["SQ"] * a_max * float(np.linalg.norm(u0 - u_c)) / (1.0 - tau))
    else:
        spread = float(np.linalg.norm(u1 - u_c))
    # the exact run's signals around the centre u_c: a signal M u + c of the run is within
    # ||M|| ||u - u_c|| of its value at u_c (the error's differences and the learning terms
    # through G, which is far smaller than their worst-case norms times ||e||)
    e_c = r - G @ u_c
    Dfull = np.kron(np.eye(ls.N + 1, ls.N) - np.eye(ls.N + 1, ls.N, -1), np.eye(ls.n_y))
    probes = {"e": (e_c, G), "De": (Dfull @ e_c, Dfull @ G), "L1e": (L1 @ e_c, L1 @ G)}
    if L2 is not None:
        probes["L2e"] = (L2 @ e_c, L2 @ G)
    centre = {k: float(np.linalg.norm(v)) for k, (v, _) in probes.items()}
    slopes = {k: spectral_norm(M) for k, (_, M) in probes.items()}
    u_norm = float(np.linalg.norm(u_c))
    first = norms["S"] * u * float(np.linalg.norm(ff1))
    feedback = plan.feedback
    error_stage = plan.stages[0]

    def magnitudes(D: float) -> dict[str, float]:
        spread_D = spread + D
        mags = {k: centre[k] + slopes[k] * spread_D for k in probes}
        mags["u"] = u_norm + spread_D
        mags["ff"] = mags["u"] + mags.get("L2e", 0.0)
        return mags

    def P(D: float) -> float:
        mags = magnitudes(D)
        xi = 0.0
        if feedback is not None:
            sig_e = error_stage.bound({"e_exact": Sig(mags["e"], 0.0)}, u)
            aux = {k: Sig(mags[k], 0.0) for k in ("De", "L2e")}
            xi = feedback.bound({"ff": Sig(mags["ff"], 0.0), "e": sig_e, **aux}, u).err
            mags["ff"] += xi                  # the float state: u - L2 e - xi
        delta = plan.rounding(mags, u).err
        return norms["S"] * (delta + (1.0 + norms["Q"]) * xi)

    margin = 1.0 - tau
    if margin <= 0.0:
        raise ExportRefusedError(
            "in single precision", f"the certificate's contraction {source} = {tau:.12g} "
            f"leaves no margin below 1 for the rounding: export in double")
    D = first
    for _ in range(_MAX_STEPS):
        new = max(first, P(D) / margin)
        if new <= D * (1.0 + 1e-12):
            break
        if not math.isfinite(new) or new > 1e6 * max(P(first) / margin, first, 1e-300):
            D = math.inf
            break
        D = new
    else:
        D = math.inf
    if math.isfinite(D):
        D *= 1.0 + 1e-6                   # strictly above the fixed point: P(D) <= (1-tau) D
        if P(D) > margin * D:
            D = math.inf
    at = D if math.isfinite(D) else max(u_norm, spread, 1.0)
    step = max(at, 1e-300) * 1e-6
    slope = (P(at + step) - P(at)) / step / margin
    if not math.isfinite(D) or slope >= 1.0:
        raise ExportRefusedError(
            "in single precision", f"the certificate's margin 1 - tau = {margin:.3g} ({source}"
            f" = {tau:.9g}) does not absorb the rounding: the rounding each trial adds grows "
            f"with the run's distance to the exact one {slope:.3g} times as fast as the "
            f"margin removes it; export in double")
    mags = magnitudes(D)
    return RoundingBound(tau, source, u, norms,
                         {"M_u": mags["u"], "M_e": mags["e"], "M_f": mags["ff"],
                          "M_De": mags["De"], "M_L1e": mags["L1e"]}, first,
                         P(D), D, norms["G"] * D, slope)


def _dense(M) -> np.ndarray:
    return M.toarray() if hasattr(M, "toarray") else np.asarray(M, dtype=float)
