r"""Proven bounds of the matrix-free analysis from the operators' state-space forms.

The cheap structural bounds of :mod:`._operator_checks` (the symbol of a block-Toeplitz T,
sub-multiplicativity over T's factors) are tight for a long trial and a causal law; they are
loose for a law that is not causal (a zero-phase Q-filter, a lead, an adjoint), for short
trials, and for a non-minimum-phase plant, whose finite trial is far from its symbol. Here
the operators' realisations over the trial
(:meth:`~ilc_analysis.lifting.LiftedOperator.state_form`) decide instead:

* :func:`refined_norm_upper`: :math:`\|T\|_2 < \gamma` by the finite-horizon bounded-real
  certificate (:func:`~ilc_analysis.lifting._state_forms.norm_below`: a Riccati recursion over
  the trial whose every step is verified with its rounding; exact up to its margins), tried at
  the levels that decide the verdict and tighten the interval: just below the threshold 1
  (:data:`THRESHOLD_GAP`), and just above the Lanczos lower bound (:data:`TIGHT_GAPS`);
* :func:`refined_radius_bound`: :math:`\rho(T) \le \|DTD^{-1}\|_2` with
  :math:`D = \operatorname{diag}(r^k)` (:func:`~ilc_analysis.lifting._state_forms.radius_below`)
  for a T that is not block triangular and whose norm is not below 1.

Each returns the bound with a phrase saying what proved it, or why nothing did (no state-space
form: which factor has none and what would have one; the certificate refused: its reason).
"""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import ILCError
from ..lifting._lifted_operator import LiftedOperator
from ..lifting._state_forms import TwoSided, norm_below, radius_below
from ._condition import _fmt

__all__ = ["refined_norm_upper", "refined_radius_bound", "state_form_of", "THRESHOLD_GAP",
           "TIGHT_GAPS", "STATE_FORM_WORK"]

#: The certificate is tried at 1 - THRESHOLD_GAP: a proof there decides ``holds`` (the
#: verdicts' tolerance band is 1e-8).
THRESHOLD_GAP = 1e-7
#: Relative gaps above the Lanczos lower bound at which the certificate tightens the interval.
TIGHT_GAPS = (1e-3, 1e-2)
#: Most work (clock steps times the cube of states plus inputs) one certificate may cost.
STATE_FORM_WORK = 2e10
#: Radii r of the weighting :math:`\operatorname{diag}(r^k)` tried for the spectral radius.
RADIUS_WEIGHTS = (0.98, 0.9, 0.7, 0.5)


def state_form_of(T: LiftedOperator) -> tuple[TwoSided | None, bool, str]:
    """T's state-space form (forward, else reversed: the same norms), whether it is the
    reversed one, and why there is none."""
    try:
        form = T.state_form()
        if form is not None:
            return form, False, ""
        form = T.state_form(reverse=True)
        if form is not None:
            return form, True, ""
    except (ILCError, ValueError, np.linalg.LinAlgError) as exc:
        return None, False, f"building its state-space form failed ({exc})"
    return None, False, _why_none(T)


def _why_none(T: LiftedOperator) -> str:
    """Which factor of T has no state-space form and what would have one (a phrase)."""
    leaves = list(_leaves(T))
    missing = [leaf for leaf in leaves
               if leaf.state_form() is None and leaf.state_form(reverse=True) is None]
    n = T.shape[1]
    dense = (f"engine='dense' forms T ({n} x {n}) and decides it exactly" if n <= 5000 else
             f"T is {n} x {n}: too large for the dense engine")
    if missing:
        parts = dict.fromkeys(_remedy(leaf) for leaf in missing)
        return "no state-space form of " + "; ".join(parts) + f"; or {dense}"
    return f"its factors' forms did not assemble into one; {dense}"


def _remedy(leaf: LiftedOperator) -> str:
    """A leaf without a state-space form, and what would give the law one."""
    q = getattr(leaf, "q_filter", None)
    what = leaf.describe()
    if q is not None and getattr(q, "kind", None) == "dct":
        return (f"{what} (the DCT filter multiplies DCT coefficients: no finite state; a "
                "Butterworth, FIR or first-order QFilter has one)")
    if q is not None and getattr(q, "passes", None) == "backward-forward":
        return f"{what} (the backward-forward order: passes='forward-backward' has one)"
    if type(leaf).__name__ == "MatrixOperator":
        return (f"{what} (a dense lifted matrix: a law built on a dense model with a model "
                "error; a model plant (GradientLaw(beta, plant)) or the exact model "
                "(NormOptimalLaw.from_problem, proven by structure) has one)")
    if type(leaf).__name__ == "NormOptimalInverse":
        return (f"{what} (a Riccati solve: with a model error or an input weight the "
                "norm-optimal T has no form; the exact model is proven by structure)")
    if type(leaf).__name__ == "LTVPlantOperator" or getattr(leaf, "state_space", None) \
            is not None:
        return f"{what} (time-varying along the trial: an LTV lifting)"
    return what


def _leaves(T: LiftedOperator):
    children = [c for name in ("a", "b", "op")
                if isinstance(c := getattr(T, name, None), LiftedOperator)]
    if children:
        for child in children:
            yield from _leaves(child)
        return
    terms = getattr(T, "terms", None)
    if terms:
        for _, op in terms:
            yield from _leaves(op)
        return
    yield T


def _work(form: TwoSided) -> float:
    """Clock steps times the cube of the joint system's size (states + inputs)."""
    pairs, _, _, K = form.layout()
    states = 0
    for p in pairs:
        for side, off in ((p.a, 0), (p.b, 0)):
            states += side.clock(off, side.N_in + side.latency + side.N_out).n
    m = form.n_in + form.n_out
    return float(K) * float(states + m) ** 3


def refined_norm_upper(T: LiftedOperator, lower: float, upper: float | None,
                       tolerance: float) -> tuple[float | None, str]:
    r"""A proven upper bound of :math:`\|T\|_2` from T's state-space form (module docstring),
    no larger than ``upper``.

    Parameters
    ----------
    T : LiftedOperator
    lower : float
        A lower bound (the Lanczos Ritz value): the levels are placed above it.
    upper : float or None
        The cheap structural bound (None: none).
    tolerance : float
        The verdicts' relative tolerance (a bound below 1 - tolerance decides ``holds``).

    Returns
    -------
    (float or None, str)
        The bound and how it was proven (or why it was not improved).
    """
    form, reversed_, why = state_form_of(T)
    if form is None:
        composed = _composed_bound(T)
        if composed is not None and (upper is None or composed < upper):
            return composed, (f"the product of T's factors' proven norms, each certified on "
                              f"its own state-space form where it has one, {composed:.6g}; T "
                              f"itself has no finite-horizon certificate: {why}")
        return upper, f"no finite-horizon certificate: {why}"
    work = _work(form)
    if work > STATE_FORM_WORK:
        return upper, (f"no finite-horizon certificate: its Riccati recursion would cost "
                       f"{work:.2g} (steps x size^3) > {STATE_FORM_WORK:.2g}")
    best = math.inf if upper is None else float(upper)
    proven, refused = None, ""

    def attempt(gamma: float) -> bool:
        nonlocal best, proven, refused
        if not 0.0 < gamma < best:
            return False
        cert = norm_below(form, gamma)
        if cert.proven:
            best = proven = gamma * (1.0 - cert.delta)
            return True
        refused = refused or f"refused at {gamma:.6g}: {cert.reason}"
        return False

    # tight first (one test decides most cases); then just below the threshold, which decides
    # the verdict when the tight level failed or lies above 1 (a Lanczos value within
    # TIGHT_GAPS[0] of 1); then, if the tight level failed, a looser one
    tight = attempt(lower * (1.0 + TIGHT_GAPS[0]))
    if lower < 1.0 - THRESHOLD_GAP and best >= 1.0 - tolerance:
        attempt(1.0 - THRESHOLD_GAP)
    if not tight:
        for g in TIGHT_GAPS[1:]:
            if attempt(lower * (1.0 + g)):
                break
    side = "J T J (time reversed)" if reversed_ else "T"
    if proven is None:
        return upper, f"finite-horizon certificate on {side}: {refused or 'not needed'}"
    return best, (f"finite-horizon bounded-real certificate on {side} (verified Riccati "
                  f"recursion over the trial) at {_fmt(best)}")


#: Power steps of the estimate a factor's certificate is placed above (:func:`_composed_bound`).
FACTOR_POWER_STEPS = 20
#: Relative levels above that estimate at which a factor's norm is certified.
FACTOR_GAPS = (1e-3, 1e-2, 0.1, 1.0)
#: Most work (N^2 b^3) spent on a factor's Toeplitz blocks by block convolution.
TOEPLITZ_WORK = 1e9


def _estimate(op: LiftedOperator) -> float:
    """A power-iteration estimate of ``||op||_2`` (:data:`FACTOR_POWER_STEPS` steps; an
    estimate, never a bound)."""
    v = np.random.default_rng(0).standard_normal(op.shape[1])
    est = 0.0
    for _ in range(FACTOR_POWER_STEPS):
        w = op.rmatvec(op.matvec(v))
        nw = float(np.linalg.norm(w))
        if not math.isfinite(nw) or nw == 0.0:
            break
        est, v = math.sqrt(nw), w / nw
    return est


def _certified_factor(op: LiftedOperator, est: float) -> float | None:
    """A proven bound of ``||op||_2`` from its state-space form, placed above the estimate
    (:data:`FACTOR_GAPS`); None when it has no form or no level is proven."""
    form, _, _ = state_form_of(op)
    if form is None or not est > 0.0 or _work(form) > STATE_FORM_WORK:
        return None
    for g in FACTOR_GAPS:
        cert = norm_below(form, est * (1.0 + g))
        if cert.proven:
            return est * (1.0 + g) * (1.0 - cert.delta)
    return None


def _own_bound(op: LiftedOperator) -> float | None:
    """``op.norm_upper(2)``, and for a block-Toeplitz op its symbol's certified peak (its
    blocks by exact block convolution while affordable)."""
    from ..lifting._toeplitz import ToeplitzOperator

    own = op.norm_upper(2)
    own = None if own is None or not math.isfinite(own) else float(own)
    if float(op.N) ** 2 * op.block[0] ** 3 <= TOEPLITZ_WORK:
        blocks = op.toeplitz_blocks()
        if blocks is not None and np.all(np.isfinite(blocks)):
            sym = ToeplitzOperator(blocks).norm_upper(2)
            if math.isfinite(sym):
                own = sym if own is None else min(own, float(sym))
    return own


def _composed_bound(op: LiftedOperator) -> float | None:
    r"""A proven bound of :math:`\|op\|_2` from the operator's tree: its own structural
    bound (:func:`_own_bound`) when it is within :data:`FACTOR_GAPS` [0] of an estimate, else
    its state-space certificate (:func:`_certified_factor`), else products and sums of the
    factors' bounds (sub-multiplicativity, the triangle inequality)."""
    from ..lifting._lifted_operator import ProductOperator, ScaledOperator, SumOperator

    own = _own_bound(op)
    est = _estimate(op)
    if own is not None and own <= est * (1.0 + FACTOR_GAPS[0]):
        return own
    best = _certified_factor(op, est)
    if best is None:
        if isinstance(op, ProductOperator):
            a = _composed_bound(op.a)
            b = None if a is None else _composed_bound(op.b)
            best = None if a is None or b is None else a * b
        elif isinstance(op, ScaledOperator):
            inner = _composed_bound(op.op)
            best = None if inner is None else abs(op.c) * inner
        elif isinstance(op, SumOperator):
            parts = [_composed_bound(t) for _, t in op.terms]
            known = [p for p in parts if p is not None]
            best = None if len(known) < len(parts) else \
                sum(abs(c) * p for (c, _), p in zip(op.terms, known, strict=True))
    if best is None:
        return own
    return best if own is None else min(best, own)


def refined_radius_bound(T: LiftedOperator, tolerance: float) -> tuple[float | None, str]:
    r"""A proven :math:`\rho(T) < 1 - 10^{-7}` through :math:`\|DTD^{-1}\|_2` for the weights
    :data:`RADIUS_WEIGHTS` (module docstring), or None with the reason."""
    form, _, why = state_form_of(T)
    if form is None:
        return None, f"no weighted-norm bound of rho: {why}"
    if form.N_in * form.n_in != form.N_out * form.n_out:
        return None, "no weighted-norm bound of rho: T is not square"
    if _work(form) > STATE_FORM_WORK:
        return None, "no weighted-norm bound of rho: the recursion would cost too much"
    target = 1.0 - THRESHOLD_GAP
    _, off_u, off_v, _ = form.layout()
    gap = off_v - off_u
    for r in RADIUS_WEIGHTS:
        cert, bound = radius_below(form, target * r ** gap, r)
        if cert.proven and bound < 1.0 - tolerance:
            return bound, (f"rho(T) <= ||D T D^-1||_2 with D = diag({r:g}^k), proven below "
                           f"{bound:.6g} by the finite-horizon certificate")
    return None, ("no weighted norm ||D T D^-1||_2, D = diag(r^k), r in "
                  f"{', '.join(f'{r:g}' for r in RADIUS_WEIGHTS)}, is proven below 1")
