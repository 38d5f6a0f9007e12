r"""Frequency-domain synthesis for long trials: the condition on a frequency grid, convex.

For an LTI sampled plant and time-invariant gains, the law (11) has the transfer matrices
(index convention of :mod:`ilc_analysis.laws`, as in
:func:`ilc_analysis.analysis.frequency_condition`)

.. math::

    L_1(z) = z^{s+\ell}\big(\Psi_1 + \Phi_1 d(z)\big),\quad
    L_2(z) = \Psi_2 + \Phi_2 d(z),\quad d(z) = (1 - z^{-1})/T_s,

and trial to trial :math:`T(z) = q\,S(z)\big((1-a)I - L_1(z)G(z)\big)` with
:math:`S = (I + L_2G)^{-1}` and the zero-phase Q-filter's real response q. With :math:`L_2`
fixed, :math:`T(e^{j\theta})` is affine in :math:`(\Psi_1, \Phi_1)`, so

.. math::

    \min_{\Psi_1,\Phi_1}\ \max_{k,\,a,\,\text{plant}}\ \sigma_{\max} T(e^{j\theta_k})

is one convex problem: a second-order cone per frequency for one input (:math:`|T| \le t`),
an LMI on the real form :math:`\begin{bmatrix}\Re T & -\Im T\\ \Im T & \Re T\end{bmatrix}`
(same singular values) per frequency otherwise. Its size grows with the grid, not with the
trial length, which is what makes long trials (N in the thousands) cheap.

**What the certificate covers.** The peak bounds the lifted operator of every trial length
only when T(z) is causal and stable (:mod:`ilc_analysis.analysis._frequency`): no lead, no
Q-filter, plant poles strictly inside the unit circle, a stable current-trial loop. A lead makes
:math:`L_1` non-causal and the finite trial lacks the errors beyond its end (three-lag plant,
lead 2: peak 0.938, :math:`\|T_N\|_2 = 1.063` for every N); an unstable pole is cancelled only
to rounding by the gains (1/(s - 2): peak 9.5e-16, :math:`\|T_{300}\|_2 = 4.6\cdot10^9`). So
every design is re-checked on the lifted operator of the trial it is for (``N``, built by
:mod:`ilc_analysis.lifting`, judged by :func:`~ilc_analysis.analysis.lifted_checks`): the
certificate holds when the peak and the lifted norm are both below the target, for every N if
the frequency argument applies, else for that N only (and without N there is none).

The grid is :func:`~ilc_analysis.analysis.frequency_condition`'s (cell midpoints of
:math:`[0, \pi]`) plus log-spaced points towards :math:`\theta = 0` (where an integrating
plant makes T grow unless the gains cancel it), so the re-check evaluates the same points with
independent code, then a grid four times denser refined around its peak: the certificate is
that dense peak, which may exceed the synthesis value between grid points (reported as
``grid_excess``).
"""

from __future__ import annotations

import itertools
import time

import control
import cvxpy as cp
import numpy as np

from .._progress import current_stages, tracked
from .._validation import MAX_TRIAL_SAMPLES, check_lifted_size, positive_int
from ..analysis import frequency_condition
from ..exceptions import CertificateError, ParameterError
from ..laws._gains import PDGains
from ..model import DiscretePlant
from ..model._linear_analysis import first_nonzero_markov
from . import _full_trial
from ._certificate import Certificate
from ._certify import certificate_verdict, certify_frequency, certify_frequency_on_trial
from ._feedback import pd_loop_spectral_radius
from ._lifted import feedback_gains
from ._options import (
    CERTIFICATE_ATOL,
    CERTIFICATE_RTOL,
    check_bounds,
    check_target,
    forgetting_spec,
)
from ._paper_level import DEFAULT_SOLVER
from ._result import (
    INFEASIBLE,
    OPTIMAL,
    OPTIMAL_INACCURATE,
    SynthesisResult,
    check_cvxpy_status,
    solve_cvxpy,
)
from ._sigma_max_conic import minimise_sigma_max_conic
from ._symbol import plant_response, response_family

__all__ = ["synthesize_frequency", "DEFAULT_FREQUENCIES", "CHECK_DENSITY",
           "FREQUENCY_CHECK_LENGTH"]

#: Grid size when neither ``n_frequencies`` nor ``N`` is given.
DEFAULT_FREQUENCIES = 512
#: Without N, the lifted re-check runs at min(2 (K - 1), this) samples (K frequencies).
FREQUENCY_CHECK_LENGTH = 512
#: Verdicts from worst to best, to combine the peak's and the lifted operator's.
_WORST_FIRST = ("not applicable", "fails", "marginal", "unknown", "holds")
#: The re-check uses a grid this many times denser than the synthesis grid.
CHECK_DENSITY = 4
#: Log-spaced points added below the grid (towards theta = 0).
LOW_FREQUENCY_POINTS = 16
#: They reach this factor below the re-check grid's first point.
LOW_FREQUENCY_DECADE = 10.0
#: Absolute accuracy of the conic solution's objective (Clarabel's default tolerances 1e-8).
_SOLVER_ATOL = 1e-7
_HINT = ("Try solver='SCS', fewer frequencies, or bounds on the gains; check that the current-"
         "trial feedback stabilises the plant.")


def _worst(*verdicts: str) -> str:
    """The worst of several verdicts (a certificate holds only if each part holds)."""
    return next(v for v in _WORST_FIRST if v in verdicts)


def _plants(plant) -> list[control.StateSpace]:
    items = list(plant) if isinstance(plant, list | tuple) else [plant]
    if not items:
        raise ParameterError("plant must be a discrete StateSpace/DiscretePlant or a non-empty "
                             "list of them")
    out = []
    for k, p in enumerate(items):
        if isinstance(p, DiscretePlant):
            if not p.is_linear:
                raise ParameterError(f"plant[{k}] ({p.name}) is nonlinear: the frequency-domain "
                                     "condition needs an LTI plant; discretize the "
                                     "linearisation (Plant.linearize()) instead")
            p = p.statespace()
        if not isinstance(p, control.StateSpace) or not p.isdtime(strict=True):
            raise ParameterError(f"plant[{k}] must be a discrete-time control.StateSpace or a "
                                 f"linear DiscretePlant; got {type(p).__name__}")
        out.append(p)
    first = out[0]
    for k, p in enumerate(out[1:], start=1):
        if (p.ninputs, p.noutputs, float(p.dt)) != (first.ninputs, first.noutputs,
                                                    float(first.dt)):
            raise ParameterError(f"plant[{k}] differs from plant[0] in inputs, outputs or dt")
    return out


def _q_values(q_filter, theta: np.ndarray, ts: float) -> np.ndarray:
    r"""Real zero-phase response :math:`|H(e^{j\theta})|^2` of a two-pass QFilter
    (:meth:`~ilc_analysis.laws.QFilter.magnitude` at :math:`f = \theta/(2\pi T_s)`)."""
    if q_filter is None:
        return np.ones_like(theta)
    if not (hasattr(q_filter, "kind") and hasattr(q_filter, "cutoff")):
        raise ParameterError("q_filter must be an ilc_analysis.simulation.QFilter or None")
    if q_filter.kind == "dct":
        raise ParameterError(f"the frequency-domain synthesis needs a Q-filter with a "
                             f"frequency response (kind 'butterworth', 'fir' or 'first-order'); "
                             f"{q_filter.kind!r} is defined on the finite trial only: use the "
                             f"lifted synthesis")
    return q_filter.magnitude(theta / (2.0 * np.pi * ts), ts)


def _box(bounds: dict, half: int) -> tuple[np.ndarray, np.ndarray]:
    """Entry-wise bounds on (vec Psi1, vec Phi1) from {'Psi1': b, 'Phi1': b}."""
    upper = np.full(2 * half, np.inf)
    if "Psi1" in bounds:
        upper[:half] = bounds["Psi1"]
    if "Phi1" in bounds:
        upper[half:] = bounds["Phi1"]
    return -upper, upper


def _solve_direct(blocks, bounds: dict, half: int):
    """The minimax by Clarabel on the conic data built here (:mod:`.sigma_max_conic`)."""
    lower, upper = _box(bounds, half)
    sol = minimise_sigma_max_conic(blocks, lower, upper, what="frequency-domain synthesis",
                                   hint=_HINT)
    return sol.x, sol.value, sol.status


def _solve_cvxpy(blocks, bounds: dict, half: int, n_u: int, solver: str):
    """The same minimax written in cvxpy (one cone or LMI per frequency), for the solvers other
    than the default; returns ``(x, value, status)`` (x and value None without a solution)."""
    P = 2 * half
    x = cp.Variable(P)
    t = cp.Variable()
    lower, upper = _box(bounds, half)
    finite = np.isfinite(upper)
    cons = [cp.abs(x[finite]) <= upper[finite]] if finite.any() else []
    for A0, Cc in blocks:
        if n_u == 1:
            re = np.real(A0[:, 0, 0]) - np.real(Cc[:, :, 0, 0]) @ x
            im = np.imag(A0[:, 0, 0]) - np.imag(Cc[:, :, 0, 0]) @ x
            cons.append(cp.norm(cp.vstack([re, im]), 2, axis=0) <= t)
            continue
        # all entries at once: vec(T_k) = vec(A_k) - M_k x, row-major n_u x n_u
        M_re = np.real(Cc).transpose(0, 2, 3, 1).reshape(-1, P)
        M_im = np.imag(Cc).transpose(0, 2, 3, 1).reshape(-1, P)
        T_re = np.real(A0).reshape(-1) - M_re @ x
        T_im = np.imag(A0).reshape(-1) - M_im @ x
        m = n_u * n_u
        for k in range(A0.shape[0]):
            Tk_re = cp.reshape(T_re[k * m:(k + 1) * m], (n_u, n_u), order="C")
            Tk_im = cp.reshape(T_im[k * m:(k + 1) * m], (n_u, n_u), order="C")
            cons.append(cp.sigma_max(cp.bmat([[Tk_re, -Tk_im], [Tk_im, Tk_re]])) <= t)
    prob = cp.Problem(cp.Minimize(t), cons)
    solve_cvxpy(prob, solver, "frequency-domain synthesis", _HINT)
    status = check_cvxpy_status(prob, "frequency-domain synthesis", _HINT)
    if status not in (OPTIMAL, OPTIMAL_INACCURATE) or x.value is None or t.value is None:
        return None, None, status
    return np.asarray(x.value, dtype=float), float(t.value), status


def synthesize_frequency(plant, *, feedback=None, lead: int = 0, shift: int | None = None,
                         forgetting=None, q_filter=None, N: int | None = None,
                         n_frequencies: int | None = None, target: float = 1.0, bounds=None,
                         solver: str = DEFAULT_SOLVER, trial_check=None) -> SynthesisResult:
    r"""Time-invariant PD gains minimising :math:`\sup_\theta\sigma_{\max}T(e^{j\theta})`.

    Parameters
    ----------
    plant : control.StateSpace, DiscretePlant, or list of them
        Discrete-time LTI plant(s) (a list: robust, the worst case over all).
    feedback : None, PDGains or (Psi2, Phi2)
        Fixed current-trial PD; it must stabilise every plant (checked).
    lead : int
        Samples of anticipation of the open-loop term.
    shift : int, optional
        Sampled relative degree s (default: from the first non-zero Markov parameter).
    forgetting : None, float, FixedForgetting or VariableForgetting
        Constant factor(s) to cover (a variable factor: both bounds).
    q_filter : QFilter, optional
        Zero-phase Q-filter (its real response :math:`|H|^2` multiplies T).
    N : int, optional
        Trial length the gains are for: the certificate is re-checked on the lifted operator of
        N samples, and the grid has N // 2 + 1 points (the trial's DFT resolution). Needed for
        a certificate when the frequency argument does not apply (a lead, a Q-filter, a plant
        pole on or outside the unit circle: module docstring).
    n_frequencies : int, optional
        Grid size (overrides N; default :data:`DEFAULT_FREQUENCIES`).
    target : float
        In (0, 1]: the certificate must show the peak and the lifted norm below this by more
        than the tolerance band of :func:`~ilc_analysis.analysis._verdicts.threshold_verdict`.
    bounds : dict, optional
        ``{'Psi1': b, 'Phi1': b}``: bounds on the absolute value of every gain entry.
    solver : str
        cvxpy solver.
    trial_check : callable, optional
        ``trial_check(gains)``: the re-check on the lifted operator of the N-sample trial
        as the ``lifted_*`` keys, for a trial whose dense lifted operator does not fit
        (:func:`~ilc_analysis.synthesis.synthesize` passes the matrix-free judge of the
        problem, :mod:`.full_trial`, beyond its dense size). Default: the dense re-check
        (:func:`~.certify.certify_frequency_on_trial`), which refuses an N whose lifted
        matrix exceeds the 1 GiB cap.

    Returns
    -------
    SynthesisResult
        ``method='frequency'``; ``certificate['value']`` is the peak of
        :func:`~ilc_analysis.analysis.frequency_condition` on a grid
        :data:`CHECK_DENSITY` times denser and at the poles of T near the unit circle (refined
        around the maximum), ``'frequency_verdict'``/``'frequency_reason'`` say whether its
        assumptions hold; ``'lifted_norm_2'`` and ``'lifted_spectral_radius'`` are those of the
        lifted operator of ``'lifted_check_length'`` samples (N; without N
        :math:`\min(2(K-1),` :data:`FREQUENCY_CHECK_LENGTH`:math:`)`, and none when the
        frequency argument does not apply). ``'verdict'`` is the worse of the peak's and the
        lifted norm's verdict against the target; ``'holds'`` means it is ``holds``, and
        ``'every_trial_length'`` that the frequency argument extends it to every N.
    """
    dsys_list = _plants(plant)
    first = dsys_list[0]
    n_u, n_y, ts = first.ninputs, first.noutputs, float(first.dt)
    Psi2, Phi2 = feedback_gains(feedback, n_u, n_y)
    if isinstance(lead, bool) or not isinstance(lead, int | np.integer) or lead < 0:
        raise ParameterError(f"lead must be an integer >= 0 (samples); got {lead!r}")
    if shift is None:
        shift = first_nonzero_markov(first)[0]
    elif isinstance(shift, bool) or not isinstance(shift, int | np.integer) or shift < 0:
        raise ParameterError(f"shift must be an integer >= 0; got {shift!r}")
    forgetting_obj, a_values = forgetting_spec(forgetting)
    target = check_target(target)
    bounds = check_bounds(bounds, ("Psi1", "Phi1"))
    if N is not None:
        N = positive_int(N, "N (trial length in samples)", minimum=2, maximum=MAX_TRIAL_SAMPLES)
        if trial_check is None:
            check_lifted_size(N, n_y, n_u)
        if lead >= N:
            raise ParameterError(f"lead must be an integer in [0, N-1] = [0, {N - 1}]; got "
                                 f"{lead!r}")
    if n_frequencies is None:
        n_frequencies = N // 2 + 1 if N is not None else DEFAULT_FREQUENCIES
    K = positive_int(n_frequencies, "n_frequencies", minimum=8)
    if not isinstance(solver, str) or solver not in cp.installed_solvers():
        raise ParameterError(f"solver must be one of {cp.installed_solvers()}; got {solver!r}")
    probe = PDGains(np.zeros((n_u, n_y)), Phi2, np.zeros((n_u, n_y)), Psi2)
    for k, dsys in enumerate(dsys_list):
        if (np.any(Psi2) or np.any(Phi2)) and not frequency_condition(
                dsys, probe, 0.0, shift=int(shift), n_points=8).closed_loop_stable:
            raise ParameterError(
                f"the current-trial feedback does not stabilise plant[{k}] (closed-loop "
                f"spectral radius {pd_loop_spectral_radius(dsys, Psi2, Phi2):.6g}, with modes "
                f"the loop sees): the frequency condition needs a stable loop; choose another "
                f"feedback")

    t0 = time.perf_counter()
    theta = np.pi * (np.arange(K) + 0.5) / K            # frequency_condition's grid
    # plus log-spaced points below its first one, down past the check grid's first point:
    # integrating plants make T grow like 1/theta there unless the gains cancel it
    low = np.geomspace(theta[0] / (2 * CHECK_DENSITY * LOW_FREQUENCY_DECADE),
                       theta[0], LOW_FREQUENCY_POINTS, endpoint=False)
    theta = np.concatenate([low, theta])
    q = _q_values(q_filter, theta, ts)
    half = n_u * n_y
    blocks = [response_family(plant_response(dsys, theta), theta, ts, shift, int(lead),
                               Psi2, Phi2, float(a), q)
              for dsys, a in tracked(itertools.product(dsys_list, a_values),
                                     total=len(dsys_list) * len(a_values),
                                     desc="synthesis: frequency responses", unit="plant")]
    report = current_stages()
    report.stage(f"solving the frequency condition on {len(theta)} frequencies")
    if solver == DEFAULT_SOLVER:
        xv, claimed, status = _solve_direct(blocks, bounds, half)
    else:
        xv, claimed, status = _solve_cvxpy(blocks, bounds, half, n_u, solver)
    solve_time = time.perf_counter() - t0
    details = {"frequencies": K, "lead": int(lead), "shift": int(shift),
               "objective_value": claimed,
               "feedback": {"Psi2": Psi2, "Phi2": Phi2},
               "q_filter": None if q_filter is None else q_filter.as_dict()}
    if xv is None or claimed is None:
        return SynthesisResult(status=status, gains=None,
                               certificate=Certificate.from_dict(
                                   {"quantity": "frequency_peak", "value": None,
                                    "target": target, "holds": False}),
                               solver=solver, solve_time=solve_time, verified=False,
                               method="frequency", forgetting=forgetting_obj, ts=ts,
                               details=details, message=f"solver status {status}")
    Psi1 = xv[:half].reshape(n_u, n_y)
    Phi1 = xv[half:].reshape(n_u, n_y)
    gains = PDGains(Phi1=Phi1, Phi2=Phi2, Psi1=Psi1, Psi2=Psi2, lead=int(lead))
    report.stage("certifying: the frequency peak and the trial" + (
        "" if N is None else f" (N = {N})"))
    # re-check 1: the analysis code on the synthesis grid must reproduce the solver's value
    on_grid = max(float(np.max(frequency_condition(d, gains, float(a), shift=int(shift),
                                                   q_filter=q_filter, n_points=K).sigma))
                  for d in dsys_list for a in a_values)
    if on_grid > claimed + CERTIFICATE_RTOL * max(claimed, 1.0) + CERTIFICATE_ATOL + \
            _SOLVER_ATOL:
        raise CertificateError(
            f"frequency-domain certificate failed its re-check: the solver claimed a peak of "
            f"{claimed:.10g} on its grid, conditions.frequency_condition computes {on_grid:.10g} "
            f"on the same grid")
    # re-check 2: a denser grid (the certificate)
    cert = certify_frequency(dsys_list, gains, a_values, q_filter, claimed=claimed,
                             target=target, shift=int(shift), n_points=CHECK_DENSITY * K)
    cert.update({"on_synthesis_grid": on_grid, "grid_excess": cert["value"] - on_grid})
    # re-check 3: the lifted operator of the trial. The peak alone certifies finite trials
    # only for a causal, stable T(z) (frequency_verdict applicable); the lifted T_N is checked
    # in every case, at N, or without N at the length whose DFT grid the synthesis used.
    length = int(N) if N is not None else min(2 * (K - 1), FREQUENCY_CHECK_LENGTH)
    cert["trial_length"] = None if N is None else int(N)
    peak_verdict = certificate_verdict(cert["value"], target)
    if cert["frequency_verdict"] == "not applicable" and N is None:
        cert.update({"lifted_check_length": None, "lifted_norm_2": None,
                     "lifted_spectral_radius": None, "lifted_verdict": "not applicable"})
        verdict = "not applicable"
        why = (f"{cert['frequency_reason']}: the peak certifies no trial length; pass N to "
               "certify the design on the lifted operator of the trial")
    else:
        dense = length * n_u <= _full_trial.DENSE_CERTIFICATE_ROWS
        if trial_check is not None and N is not None and not dense:
            cert.update(trial_check(gains))
        else:
            cert.update(certify_frequency_on_trial(dsys_list, gains, a_values, q_filter,
                                                   N=length, shift=int(shift), target=target))
        verdict = _worst(peak_verdict, cert["lifted_verdict"])
        why = None
        if cert["lifted_verdict"] != "holds":
            why = (f"the lifted operator of N = {length} samples has ||T||_2 = "
                   f"{cert['lifted_norm_2']:.6g} ({cert['lifted_verdict']})"
                   + ("" if cert["frequency_verdict"] != "not applicable" else
                      f"; {cert['frequency_reason']}"))
    cert.update({"verdict": verdict, "holds": verdict == "holds",
                 "every_trial_length": bool(verdict == "holds"
                                            and cert["frequency_verdict"] == "holds")})
    if why is not None and peak_verdict == "holds":
        message = (f"sup sigma_max T = {cert['value']:.6g} < {target:g} on the frequency grid, "
                   f"but {why}: certificate {verdict}")
    elif cert["value"] >= target and on_grid < target:
        message = (f"peak {on_grid:.6g} < {target:g} on the synthesis grid but "
                   f"{cert['value']:.6g} between its points or at a pole of T: use more "
                   "frequencies")
    else:
        scope = ("every trial length" if cert["every_trial_length"] else
                 f"the trial of N = {length} samples")
        message = (f"sup sigma_max T = {cert['value']:.6g}, lifted ||T_N||_2 = "
                   f"{cert['lifted_norm_2']:.6g} at N = {length} (target < {target:g}): "
                   f"certificate {verdict}" + (f" for {scope}" if cert["holds"] else ""))
    if cert["value"] >= target and claimed >= target:
        status = INFEASIBLE
        message += "; the convex optimum itself is not below the target: infeasible"
    return SynthesisResult(status=status, gains=gains if status != INFEASIBLE else None,
                           certificate=Certificate.from_dict(cert), solver=solver,
                           solve_time=solve_time,
                           verified=True, method="frequency", forgetting=forgetting_obj, ts=ts,
                           details=details, message=message)

