r"""Independent re-checks of synthesised gains by the analysis stage.

Each function takes **only the gains** (and the plant data), rebuilds the quantity of the
certificate with :mod:`ilc_analysis.analysis` and :mod:`ilc_analysis.lifting` — code that
shares nothing with the solvers' formulations — and compares it with the solver's claim:

* paper level: :func:`~ilc_analysis.analysis.gamma_factors` and
  :func:`~ilc_analysis.analysis.tight_contraction`; the LMI values are upper bounds, so the
  recomputed value must not exceed the claim;
* lifted: :func:`~ilc_analysis.lifting.learning_operators` (the law's own lifted operators),
  :func:`~ilc_analysis.lifting.learning_operator` and
  :func:`~ilc_analysis.analysis.lifted_checks`, judged by the one judge
  (:func:`~ilc_analysis.analysis._judge.judge_checks`, the function ``analyze`` and
  ``Design.check`` take their verdicts from; on the dense T the synthesis formed, recorded as
  ``engine = 'dense'``); the claim is the same quantity, so both must agree;
* frequency: :func:`~ilc_analysis.analysis.frequency_condition` on a grid denser than the
  synthesis grid, at the poles of T near the unit circle, refined around its peak; it may
  exceed the claim between synthesis grid points (reported), but not at them. The peak is a
  certificate for every trial length only where its assumptions hold (T(z) causal and stable,
  :func:`~ilc_analysis.analysis.frequency_assumptions`), so the design is also re-checked on
  the lifted operator of the trial (:func:`certify_frequency_on_trial`).

Every certificate carries a ``verdict`` (the lifted ones the one judge's against
:math:`\min(\text{target}, 1)`; the paper-level and frequency ones :func:`certificate_verdict`,
i.e. :func:`~ilc_analysis.analysis._verdicts.threshold_verdict` of the value against the
target, which is at most 1) and ``holds = verdict == 'holds'``: a value within rounding of the
target is ``marginal``, never certified.

A disagreement beyond :data:`~.options.CERTIFICATE_RTOL` raises
:class:`~ilc_analysis.exceptions.CertificateError`.
"""

from __future__ import annotations

import math

import numpy as np

from .._progress import progress
from ..analysis import frequency_condition, lifted_checks
from ..analysis._forgetting_box import forgetting_box_bounds, forgetting_box_norm_inf
from ..analysis._judge import certificate_threshold, judge_checks
from ..analysis._paper_theorem import gamma_factors, tight_contraction
from ..analysis._structured import BlockToeplitzOperator, structured_learning_operator
from ..analysis._verdicts import threshold_verdict
from ..exceptions import CertificateError, InternalError
from ..laws._gains import PDGains, learning_operators
from ..lifting import LiftedSystem, learning_operator
from ..lifting._lti_lifting import block_toeplitz, lti_markov_blocks
from ..lifting._operators import forgetting_matrix
from ._options import CERTIFICATE_ATOL, CERTIFICATE_RTOL

__all__ = ["certify_paper", "certify_lifted", "certify_frequency", "certify_frequency_on_trial",
           "certificate_verdict", "LIFTED_CHECK_HORIZON"]

#: Powers of T examined by the lifted re-checks (synthesis, Design.certify, Design.check).
LIFTED_CHECK_HORIZON = 50


def certificate_verdict(value: float, target: float) -> str:
    r"""``holds`` / ``marginal`` / ``fails`` of a re-checked certificate value against
    :math:`\min(\text{target}, 1)` (:func:`~ilc_analysis.analysis._verdicts.threshold_verdict`):
    "holds" always means a contraction with a margin larger than rounding, whatever the
    target (the synthesis refuses targets above 1; this does not rely on it)."""
    return threshold_verdict(value, min(float(target), 1.0))


def _box(lifted, gains: PDGains, lo: float, hi: float, q_matrix):
    r"""The per-sample forgetting box of one plant
    (:func:`~ilc_analysis.analysis._forgetting_box.forgetting_box_bounds`) and
    :math:`\max_A\|T(A)\|_\infty` (exact), with the law's operators."""
    L1, L2 = learning_operators(gains, lifted.N, lifted.shift, lifted.ts, n_u=lifted.n_u,
                                n_y=lifted.n_y)

    def operator(a):
        A = float(a) if np.ndim(a) == 0 else forgetting_matrix(np.asarray(a), lifted.n_u)
        return learning_operator(lifted.G, L1, L2, A, Q=q_matrix)

    sq = learning_operator(lifted.G, None, L2, 0.0, Q=q_matrix)
    box = forgetting_box_bounds(operator, sq, lo, hi, lifted.N)
    return box, forgetting_box_norm_inf(operator(lo), operator(hi), lifted.N)


def _box_certificate(systems, gains: PDGains, a_values, q_matrix, target: float) -> dict:
    r"""What a certificate of a variable forgetting factor (two bounds) adds: the worst
    per-sample box over the plants (``forgetting_box_upper`` proven,
    ``forgetting_box_lower`` attained at ``forgetting_box_witness``, the exact
    ``forgetting_box_norm_inf``) and its verdict against :math:`\min(\text{target}, 1)` —
    ``holds`` when every plant's proven bound holds, ``fails`` when an attained vertex fails,
    else ``unknown``. The constant bounds' numbers do not cover a factor that varies per sample
    and between iterations. Empty for a constant factor."""
    if len(a_values) < 2:
        return {}
    lo, hi = float(min(a_values)), float(max(a_values))
    boxes = [_box(lifted, gains, lo, hi, q_matrix) for lifted in systems]
    verdicts = [b.verdict_against(target) for b, _ in boxes]
    verdict = "holds" if all(v == "holds" for v in verdicts) else \
        ("fails" if "fails" in verdicts else "unknown")
    top = max(boxes, key=lambda b: b[0].lower)[0]
    return {"forgetting_box_upper": max(b.upper for b, _ in boxes),
            "forgetting_box_lower": top.lower,
            "forgetting_box_norm_inf": max(n for _, n in boxes),
            "forgetting_box_witness": [float(v) for v in top.witness],
            "forgetting_box_verdict": verdict, "forgetting_covers": top.covers}


def _tolerance(claim: float) -> float:
    return CERTIFICATE_RTOL * max(abs(claim), 1.0) + CERTIFICATE_ATOL


def certify_paper(couplings, gains: PDGains, a_values, *, quantity: str, claimed: float,
                  target: float, slack: float = 0.0) -> dict:
    r"""Re-check the paper-level certificate (eq 25 and its tight form) over every coupling
    matrix H (vertices) and forgetting value.

    ``quantity`` is ``'tight_contraction'`` (:math:`\sup\|X^{-1}Y\|`) or
    ``'gamma1_gamma2'``. The LMI claim is an upper bound of the quantity, up to ``slack``
    (the solver's absolute accuracy carried to the quantity).
    """
    g1 = g2 = tight = 0.0
    for H in couplings:
        a1, a2 = gamma_factors(H, gains.Phi1, gains.Phi2, a_values)
        g1, g2 = max(g1, a1), max(g2, a2)
        tight = max(tight, tight_contraction(H, gains.Phi1, gains.Phi2, a_values))
    value = tight if quantity == "tight_contraction" else g1 * g2
    if not np.isfinite(value) or value > claimed + slack + _tolerance(claimed):
        raise CertificateError(
            f"paper-level certificate failed its re-check: the solver claimed {quantity} <= "
            f"{claimed:.10g}, the analysis code computes {value:.10g} from the returned gains")
    return {"quantity": quantity, "value": float(value), "target": float(target),
            "verdict": certificate_verdict(value, target),
            "holds": certificate_verdict(value, target) == "holds",
            "gamma1": float(g1), "gamma2": float(g2),
            "gamma1_gamma2": float(g1 * g2), "tight_contraction": float(tight),
            "claimed": float(claimed), "forgetting_values": [float(a) for a in a_values],
            "vertices": len(couplings)}


def lifted_operator(lifted, gains: PDGains, a: float, q_matrix) -> np.ndarray:
    r""":math:`T = (I + L_2G)^{-1} Q (I - aI - L_1G)` from the law's lifted operators."""
    L1, L2 = learning_operators(gains, lifted.N, lifted.shift, lifted.ts, n_u=lifted.n_u,
                                n_y=lifted.n_y)
    return learning_operator(lifted.G, L1, L2, a, Q=q_matrix)


def certify_lifted(systems, gains: PDGains, a_values, q_matrix, *, claimed: float,
                   target: float) -> dict:
    r"""Re-check :math:`\max_{j,a}\|T_j(a)\|_2` with the law's operators and the lifted checks.

    Returns the certificate: the worst 2-norm, spectral radius, ∞-norm and transient peak over
    the plants and forgetting values (``peak_settled``: that peak is the supremum over every
    k), and the 2-norm per plant. For a variable forgetting factor (two values: its bounds)
    the verdict is the per-sample box's (:func:`_box_certificate`, its numbers added): the
    constant bounds do not cover a factor set per sample and varied between iterations.
    """
    notes: list[str] = []
    every: dict = {}                    # the lifted checks of each plant and forgetting value
    per_plant: list[float] = []
    # the horizon Design.certify and Design.check walk too: the numbers resting on the powers
    # (a transient peak, a spectral radius certified by min_k ||T^k||^(1/k)) then agree
    horizon = LIFTED_CHECK_HORIZON
    systems, a_values = list(systems), list(a_values)
    c = certificate_threshold("norm_2", target)
    with progress(total=len(systems) * len(a_values), desc="synthesis: certificate re-check",
                  unit="T") as bar:
        for j, lifted in enumerate(systems):
            mine = {}
            for a in a_values:
                T = lifted_operator(lifted, gains, float(a), q_matrix)
                mine[f"plant {j}, a={float(a):g}"] = lifted_checks(
                    T, block_size=lifted.n_u, warn=False, horizon=horizon)
                bar.update()
            every.update(mine)
            worst = judge_checks(mine, "norm_2", c).value
            per_plant.append(math.nan if worst is None else worst)      # None: not proven
    if not every:
        raise InternalError("_systems and forgetting_spec guarantee one operator at least")
    norm = judge_checks(every, "norm_2", c)
    value = norm.value
    if value is None or abs(value - claimed) > _tolerance(claimed):
        raise CertificateError(
            f"lifted certificate failed its re-check: the solver claimed max ||T||_2 = "
            f"{claimed:.10g}, the analysis code computes {norm.text()} from the returned gains "
            f"(lifting.learning_operators / analysis.lifted_checks)")
    side = {q: judge_checks(every, q, 1.0) for q in ("spectral_radius", "norm_inf",
                                                       "transient_peak")}
    if side["spectral_radius"].value is None:
        notes.append(f"spectral radius: not established for some plant or forgetting value "
                     f"(an estimate of a non-triangular T that no computed power certifies); "
                     f"rho(T) <= ||T||_2 <= {value:.6g} bounds it, and the 2-norm certificate "
                     f"does not use it")
    box: dict = {}
    if len(a_values) > 1:                  # a variable factor: its per-sample box
        with progress(desc="synthesis: per-sample forgetting box", unit="plant") as bar:
            box = _box_certificate(systems, gains, a_values, q_matrix, target)
            bar.update(len(systems))
    verdict = box.get("forgetting_box_verdict", norm.verdict)
    worst = max(every.values(), key=lambda ch: ch.bounds("norm_2")[0])
    return {"quantity": "norm_2", "value": float(value), "target": float(target),
            "verdict": verdict, "holds": verdict == "holds",
            **{k: float(v) for k, v in (("lower", norm.lower), ("upper", norm.upper))
               if v is not None},
            **{k: v for k, v in box.items() if k != "forgetting_box_verdict"},
            **{q: float(j.value) for q, j in side.items() if j.value is not None},
            "peak_settled": all(bool(ch.peak_settled) for ch in every.values()),
            "iterations_to_reduce": worst.iterations_to_reduce, "claimed": float(claimed),
            "norm_2_per_plant": [float(v) for v in per_plant], "plants": len(per_plant),
            "forgetting_values": [float(a) for a in a_values], "engine": "dense",
            "monotone_in": "||u_i - u_inf||_2 (input error to the fixed point)",
            "notes": notes}


def _trial_operator(lifted, gains: PDGains, a: float, q_matrix):
    r"""T of an LTI trial: without a Q-filter and with time-invariant gains without lead it is
    block lower-triangular Toeplitz, held by its first block column
    (:func:`~ilc_analysis.analysis.structured_learning_operator`: products by FFT, the exact
    spectral radius from the lag-0 block, no dense :math:`2N \times 2N` product); otherwise the
    dense :func:`lifted_operator`."""
    if q_matrix is not None or gains.time_varying or gains.lead:
        return lifted_operator(lifted, gains, a, q_matrix)
    L1, L2 = learning_operators(gains, lifted.N, lifted.shift, lifted.ts, n_u=lifted.n_u,
                                n_y=lifted.n_y)
    return structured_learning_operator(lifted.G, L1, L2, a, n_u=lifted.n_u, n_y=lifted.n_y,
                                        toeplitz=True)


def _finite(T) -> bool:
    """Every entry of T (dense, or the first block column of a Toeplitz operator) is finite."""
    return bool(np.all(np.isfinite(T.blocks if isinstance(T, BlockToeplitzOperator) else T)))


def certify_frequency(dsys_list, gains: PDGains, a_values, q_filter, *, claimed: float,
                      target: float, shift: int, n_points: int) -> dict:
    r"""Re-check :math:`\sup_\theta \sigma_{\max}T(e^{j\theta})` with
    :func:`~ilc_analysis.analysis.frequency_condition` on ``n_points`` frequencies (and the
    poles of T near the unit circle).

    ``frequency_verdict`` is ``not applicable`` (with ``frequency_reason``) when an assumption
    of the frequency argument fails for some plant or forgetting value (a lead, a Q-filter, a
    plant pole on or outside the unit circle, an unstable current-trial loop): the peak then
    says nothing about a finite trial. Otherwise it is :func:`certificate_verdict` of the peak,
    and ``holds`` means :math:`\|T_N\|_2 <` target for every trial length N.
    """
    peak, stable, where, reason = 0.0, True, 0.0, None
    for dsys in dsys_list:
        for a in a_values:
            fc = frequency_condition(dsys, gains, float(a), shift=shift, q_filter=q_filter,
                                     n_points=n_points)
            stable &= fc.closed_loop_stable
            if not fc.applicable and reason is None:
                reason = fc.reason
            if fc.peak >= peak:
                peak, where = fc.peak, fc.peak_omega
    verdict = "not applicable" if reason is not None else certificate_verdict(peak, target)
    variable = len(a_values) > 1
    return {"quantity": "frequency_peak", "value": float(peak), "target": float(target),
            "forgetting_covers": (
                f"constant factors a in [{min(a_values):g}, {max(a_values):g}] only: the peak "
                "says nothing of a factor varying per sample or between iterations (the "
                "lifted re-check of the trial covers that)" if variable else
                f"the constant factor a = {float(a_values[0]):g}"),
            "verdict": verdict, "holds": verdict == "holds",
            "frequency_verdict": verdict,
            "frequency_reason": reason if reason is not None else (
                "T(z) causal and stable: the peak bounds ||T_N||_2 for every trial length N"),
            "every_trial_length": verdict == "holds" and not variable,
            "peak_omega": float(where),
            "closed_loop_stable": bool(stable), "claimed": float(claimed),
            "grid_points": int(n_points), "forgetting_values": [float(a) for a in a_values],
            "plants": len(dsys_list)}


def certify_frequency_on_trial(dsys_list, gains: PDGains, a_values, q_filter, *, N: int,
                               shift: int, target: float) -> dict:
    r"""Re-check a frequency-domain design on the lifted operator of a trial of N samples.

    The peak :math:`\sup_\theta\sigma_{\max}T(e^{j\theta}) < 1` bounds every finite trial only
    when T(z) is causal and stable (:func:`~ilc_analysis.analysis.frequency_assumptions`);
    a lead, a zero-phase Q-filter or a plant pole on or outside the unit circle void it. This
    builds, for each plant and forgetting value, the lifted
    :math:`T_N = (I + L_2G)^{-1}Q((1-a)I - L_1G)` of N samples (G from the Markov parameters
    by :mod:`ilc_analysis.lifting`, :func:`lifted_operator`, the simulation's lifted Q) and
    judges it with :func:`~ilc_analysis.analysis.lifted_checks`: the worst 2-norm and
    spectral radius, and :func:`certificate_verdict` of the 2-norm against ``target``; for a
    variable forgetting factor (two values) ``lifted_verdict`` is the per-sample box's
    (:func:`_box_certificate`), whose numbers it adds. Markov
    parameters that overflow (an unstable plant over a long trial) give an infinite norm
    (``fails``).
    """
    every, infinite, trials = {}, False, []
    for dsys in dsys_list:
        Ad, Bd = np.asarray(dsys.A, dtype=float), np.asarray(dsys.B, dtype=float)
        C, D = np.asarray(dsys.C, dtype=float), np.asarray(dsys.D, dtype=float)
        G = block_toeplitz(lti_markov_blocks(Ad, Bd, C, D, int(shift), int(N)))
        if not np.all(np.isfinite(G)):
            infinite = True
            continue
        lifted = LiftedSystem(G=G, d=np.zeros(G.shape[0]), shift=int(shift), ts=float(dsys.dt),
                              N=int(N), n_u=Bd.shape[1], n_y=C.shape[0])
        q_matrix = None if q_filter is None else q_filter.lifted_matrix(N, lifted.n_u, lifted.ts)
        trials.append((lifted, q_matrix))
        for a in a_values:
            with np.errstate(over="ignore", invalid="ignore"):
                T = _trial_operator(lifted, gains, float(a), q_matrix)
            if not _finite(T):
                infinite = True
                continue
            every[f"plant {len(trials) - 1}, a={float(a):g}"] = lifted_checks(
                T, block_size=lifted.n_u, warn=False, horizon=LIFTED_CHECK_HORIZON)
    if infinite or not every:
        value, rho, verdict = np.inf, np.inf, "fails"
    else:
        norm = judge_checks(every, "norm_2", certificate_threshold("norm_2", target))
        radius = judge_checks(every, "spectral_radius", 1.0).value
        value = math.nan if norm.value is None else norm.value      # None: not proven
        verdict = norm.verdict
        rho = np.nan if radius is None else radius
    out = {"lifted_check_length": int(N), "lifted_norm_2": float(value),
           "lifted_spectral_radius": float(rho), "lifted_verdict": verdict}
    if len(a_values) > 1 and np.isfinite(value):
        boxes = [_box_certificate([lifted], gains, a_values, q_matrix, target)
                 for lifted, q_matrix in trials]
        worst = max(boxes, key=lambda b: b["forgetting_box_lower"])
        verdicts = [b["forgetting_box_verdict"] for b in boxes]
        out.update({k: v for k, v in worst.items() if k != "forgetting_box_verdict"},
                   forgetting_box_upper=max(b["forgetting_box_upper"] for b in boxes),
                   forgetting_box_norm_inf=max(b["forgetting_box_norm_inf"] for b in boxes),
                   lifted_verdict="holds" if all(v == "holds" for v in verdicts) else
                   ("fails" if "fails" in verdicts else "unknown"))
    return out
