r"""The tracking error's norm from trial to trial: the error operator :math:`T_e` (issue 24).

The lifted conditions judge the input error :math:`u_\star - u_i` through
:math:`T = (I + L_2G)^{-1}Q((1-a)I - L_1G)`. What a user measures is the tracking error
:math:`e_i = r - Gu_i`; where an operator :math:`T_e` with :math:`GT = T_eG` exists, the
error obeys :math:`e_{i+1} - e_\infty = T_e(e_i - e_\infty)`, and :math:`\|T_e\|_2 \le 1` means
that the 2-norm of the error (about its limit) never grows from trial to trial.

Where :math:`T_e` comes from
----------------------------
* No Q-filter and no forgetting (:math:`Q = I`, :math:`a = 0`): from
  :math:`u_{i+1} = u_i + L_1e_i + L_2e_{i+1} + c`,

  .. math::

      (I + GL_2)e_{i+1} = (I - GL_1)e_i - Gc,\qquad T_e = (I + GL_2)^{-1}(I - GL_1),

  exactly (:math:`GT = T_eG` by the push-through identity). Without a constant update term c
  (``LiftedLaw.parts['offset']``) the limit plays no part: :math:`e_{i+1} = T_ee_i`.
* A Q-filter or a constant forgetting factor, and G of full column rank (with a margin):
  :math:`T_e = GTG^{+}` on the range of G, for the error about its limit
  :math:`e_i - e_\infty = -G(u_i - u_\infty)`.
* Otherwise (G with a null space and a Q-filter or forgetting, or a variable forgetting factor):
  no :math:`T_e` in general; ``not applicable`` with the reason.

Structural proofs (no rounded spectral radius decides them)
-----------------------------------------------------------
* **Gradient ILC with the exact adjoint** (:class:`~ilc_analysis.laws.GradientLaw` whose lifted
  :math:`L_1` is exactly :math:`\beta G^\top`, bit for bit, as is
  :class:`~ilc_analysis.laws.TimeReversalLaw` on an LTI lifting; no Q, no L2, a = 0):
  :math:`T_e = I - \beta GG^\top` is symmetric with eigenvalues :math:`1 - \beta\sigma_k^2`
  (and 1 on the null space of :math:`G^\top`), so :math:`\|T_e\|_2 \le 1` iff
  :math:`\beta\sigma_{\max}(G)^2 \le 2`. The condition is checked with a rigorous margin:
  the computed :math:`\hat\sigma_{\max}` (LAPACK SVD, backward stable) satisfies
  :math:`|\hat\sigma - \sigma| \le \delta\sigma`, :math:`\delta` =
  :data:`SVD_RELATIVE_ERROR_FACTOR` :math:`\cdot\max(m, n)\cdot\varepsilon`, so the condition
  is proven when :math:`\beta\hat\sigma^2(1 + \mu) \le 2` and refuted when
  :math:`\beta\hat\sigma^2(1 - \mu) > 2`, :math:`\mu = 2\delta + \delta^2 + 4\varepsilon`;
  between the two it is ``unknown``.
* **Norm-optimal ILC with the exact model** (:class:`~ilc_analysis.laws.NormOptimalLaw` whose
  model is the problem's plant entry for entry, :meth:`~ilc_analysis.laws.NormOptimalLaw.
  exact_model`, dense or in Riccati form; no input weight :math:`W_u`, so no Q; the full
  step, ``step_size`` 1: a shorter step is judged by its computed norm):
  from :math:`L_{no} = (G^\top W_eG + W_\Delta)^{-1}G^\top W_e` and the Woodbury identity,

  .. math::

      T_e = I - GL_{no} = (I + G W_\Delta^{-1}G^\top W_e)^{-1},

  whose eigenvalues lie in (0, 1] for :math:`W_\Delta` positive definite and :math:`W_e`
  positive semi-definite (:math:`GW_\Delta^{-1}G^\top W_e` is similar to a PSD matrix).
  With :math:`W_e = wI` (w > 0), :math:`T_e` is symmetric, so :math:`\|T_e\|_2 \le 1`: proven.
  With another positive definite :math:`W_e`, :math:`T_e` is self-adjoint in the
  :math:`W_e`-inner product: :math:`\|e_i\|_{W_e}` is non-increasing (stated), and the 2-norm is
  judged by the computed :math:`\|T_e\|_2`. The weights' symmetry is exact (the law stores
  diagonal weights as vectors and symmetrises full ones); their definiteness is checked here
  (a diagonal exactly, a full matrix by its smallest eigenvalue with a margin).

The proofs are about the law's mathematical form on the lifted G (for a nonlinear plant: its
linearisation along the lifted trajectory, so local); the floating-point implementation of
the law's gains is not part of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse

from ._condition import Condition, _fmt
from ._structured import dense_norm_2
from ._verdicts import threshold_verdict, verdict_tolerance

__all__ = ["ErrorOperator", "error_operator", "error_norm_condition", "error_clause",
           "SVD_RELATIVE_ERROR_FACTOR", "DENSE_MAX_DIMENSION"]

#: :math:`p` in the relative error bound :math:`p\max(m, n)\varepsilon` of a computed singular
#: value of an m x n matrix (LAPACK: "a modestly growing function of m and n"; 10 is generous).
SVD_RELATIVE_ERROR_FACTOR = 10.0
_EPS = float(np.finfo(float).eps)
#: Largest dimension of G for which the dense SVDs of G and T_e are computed.
DENSE_MAX_DIMENSION = 3000


@dataclass(frozen=True)
class ErrorOperator:
    """The error operator of a lifted law on G, or why there is none."""

    T_e: np.ndarray | None
    """:math:`T_e` ``(N n_y, N n_y)``, or None (not applicable)"""
    formula: str
    """how it was formed, or why it does not exist"""
    about_limit: bool
    """True: it maps :math:`e_i - e_\\infty` (a Q-filter, forgetting or a constant update
    term); False: it maps :math:`e_i` itself"""


def _dense(M) -> np.ndarray:
    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M, dtype=float)


def _has_offset(lifted_law) -> bool:
    c = lifted_law.parts.get("offset")
    return c is not None and bool(np.any(np.asarray(c)))


def error_operator(G, lifted_law, sigma: np.ndarray | None = None) -> ErrorOperator:
    r""":math:`T_e` with :math:`GT = T_eG` (module docstring), or the reason there is none.

    Parameters
    ----------
    G : ndarray (N n_y, N n_u)
        The lifted plant the law runs on.
    lifted_law : LiftedLaw
        The law lifted on G.
    sigma : ndarray, optional
        G's singular values (descending), when already computed.

    Returns
    -------
    ErrorOperator
    """
    G = np.asarray(G, dtype=float)
    p, q = G.shape
    L1 = _dense(lifted_law.L1)
    if lifted_law.variable_forgetting:
        return ErrorOperator(None, "a variable forgetting factor changes T from trial to trial "
                                   "(with the error): no single error operator", True)
    a = float(lifted_law.a)
    offset = _has_offset(lifted_law)
    if lifted_law.Q is None and a == 0.0:
        M = np.eye(p) - G @ L1
        if lifted_law.L2 is not None:
            M = np.linalg.solve(np.eye(p) + G @ _dense(lifted_law.L2), M)
        return ErrorOperator(M, "T_e = (I + G L2)^-1 (I - G L1) (no Q-filter, no forgetting: "
                                "e_{i+1} = T_e e_i" + (" - G S c" if offset else "") + ")",
                             offset)
    s = np.linalg.svd(G, compute_uv=False) if sigma is None else sigma
    s_max = float(s[0]) if s.size else 0.0
    rank_margin = SVD_RELATIVE_ERROR_FACTOR * max(p, q) * _EPS * s_max
    if p < q or s.size < q or float(s[-1]) <= rank_margin:
        return ErrorOperator(None, "the law has a Q-filter or forgetting and G has a (numerical) "
                                   "null space: G T = T_e G has no solution in general, so the "
                                   "tracking error has no operator of its own", True)
    T = lifted_law.operator(G)
    return ErrorOperator(G @ T @ np.linalg.pinv(G), "T_e = G T G^+ on the range of G (G has "
                         "full column rank; e_i - e_inf = -G (u_i - u_inf))", True)


# ---------------------------------------------------------------------------------------------
# structural proofs
# ---------------------------------------------------------------------------------------------
def _gradient_proof(law, lifted_law, G: np.ndarray, sigma: np.ndarray) -> dict | None:
    r"""The gradient proof's facts (module docstring), or None when the structure is absent."""
    beta = getattr(law, "beta", None)
    if beta is None or lifted_law.Q is not None or lifted_law.L2 is not None \
            or lifted_law.variable_forgetting or float(lifted_law.a) != 0.0:
        return None
    if not np.array_equal(_dense(lifted_law.L1), beta * G.T):
        return None
    p, q = G.shape
    delta = SVD_RELATIVE_ERROR_FACTOR * max(p, q) * _EPS
    mu = 2.0 * delta + delta * delta + 4.0 * _EPS
    s_max = float(sigma[0]) if sigma.size else 0.0
    v = beta * s_max * s_max
    if v * (1.0 + mu) <= 2.0:
        status = "holds"
    elif v * (1.0 - mu) > 2.0:
        status = "fails"
    else:
        status = "unknown"
    return {"structure": "gradient ILC with the exact adjoint: L1 = beta G^T exactly, so "
                         "T_e = I - beta G G^T, symmetric, eigenvalues 1 - beta sigma_k^2",
            "condition": "beta sigma_max(G)^2 <= 2", "beta_sigma_max_sq": v,
            "relative_margin": mu, "status": status, "decides": True,
            "strict": status == "holds" and v * (1.0 + mu) < 2.0 and _full_row_rank(G, sigma)}


def _positive_definite(W: np.ndarray) -> str:
    """'holds' / 'fails' / 'unknown': W (a diagonal as a vector, decided exactly, or a full
    matrix, exactly symmetric, judged by its smallest eigenvalue with a rounding margin) is
    positive definite."""
    if W.ndim == 1:
        return "holds" if bool(np.all(W > 0)) else "fails"
    if not np.array_equal(W, W.T):
        return "fails"
    lam = np.linalg.eigvalsh(W)
    margin = SVD_RELATIVE_ERROR_FACTOR * W.shape[0] * _EPS * float(np.max(np.abs(lam)))
    if float(lam[0]) > margin:
        return "holds"
    return "fails" if float(lam[0]) < -margin else "unknown"


def _full_row_rank(G: np.ndarray, sigma: np.ndarray) -> bool:
    """G G^T is nonsingular with a margin (its smallest singular value above rounding)."""
    p, q = G.shape
    return sigma.size == p and float(sigma[-1]) > SVD_RELATIVE_ERROR_FACTOR * max(p, q) \
        * _EPS * float(sigma[0])


def _norm_optimal_proof(law, lifted_law, G: np.ndarray, sigma: np.ndarray,
                        problem=None) -> dict | None:
    """The norm-optimal proof's facts (module docstring), or None when the structure is
    absent."""
    from ..laws import NormOptimalLaw

    if not isinstance(law, NormOptimalLaw) or law.step_size != 1.0 or lifted_law.Q is not None \
            or lifted_law.L2 is not None or lifted_law.variable_forgetting \
            or float(lifted_law.a) != 0.0 or _has_offset(lifted_law):
        return None
    # the law's own test, however it was built (dense model or Riccati form: F18, issue 34)
    if problem is None or not law.exact_model(problem):
        return None
    We, Wd = law._We, law._Wd            # noqa: SLF001 - the law's own validated weights
    wd = _positive_definite(Wd)
    we = _positive_definite(We)
    scalar_we = We.ndim == 1 and bool(np.all(We == We[0])) and float(We[0]) > 0
    status = "holds" if wd == "holds" and scalar_we else "unknown"
    return {"structure": "norm-optimal ILC with the exact model: T_e = I - G L_no = "
                         "(I + G W_delta^-1 G^T W_e)^-1, eigenvalues in (0, 1]"
                         + (", symmetric for W_e = w I" if scalar_we else ""),
            "condition": "W_delta positive definite (" + wd + "), W_e = w I with w > 0 ("
                         + ("holds" if scalar_we else "no") + ")",
            "status": status, "decides": status == "holds",
            "weighted_norm_proven": wd == "holds" and we == "holds",
            "strict": status == "holds" and _full_row_rank(G, sigma)}


# ---------------------------------------------------------------------------------------------
# the condition
# ---------------------------------------------------------------------------------------------
def error_norm_condition(problem, law, lifted_law,
                         sigma: np.ndarray | None = None) -> Condition:
    r"""``error_norm_2``: the tracking error's 2-norm from trial to trial (module docstring).

    The norm is a dense factorisation of :math:`T_e`
    (:func:`~ilc_analysis.analysis._structured.dense_norm_2`: the SVD up to 300 columns, the
    largest eigenvalue of the Gram matrix beyond, relatively accurate to about
    :math:`n\varepsilon`): exact up to the verdicts' tolerance band, so the condition's
    ``lower`` and ``upper`` are both that value.

    ``holds``: :math:`\|e_{i+1}\|_2 \le \|e_i\|_2` for every trial (about the limit when
    ``details['about_limit']``), proven by the law's structure (``details['proof'] =
    'structure'``), or by a computed :math:`\|T_e\|_2 < 1` with a margin (then strictly
    decreasing); ``fails``: :math:`\|T_e\|_2 > 1` (some error grows), or the structural
    condition is violated; ``marginal``: the computed norm equals 1 within rounding and no
    structure decides; ``unknown``: the structural condition within rounding of its bound;
    ``not applicable``: no :math:`T_e`.

    Parameters
    ----------
    problem : ILCProblem
        Its lifted plant ``problem.lifted`` is G.
    law : LearningLaw
        The law (its class and parameters decide the structural proofs).
    lifted_law : LiftedLaw
        ``law.lifted(problem.lifted)``.
    sigma : ndarray, optional
        G's singular values (LAPACK SVD, descending), when already computed.

    Returns
    -------
    Condition
    """
    ls = problem.lifted
    G = np.asarray(ls.G, dtype=float)
    if max(G.shape) > DENSE_MAX_DIMENSION:
        return Condition("error_norm_2", None, "unknown",
                         f"tracking error e_i: not evaluated (G is {G.shape[0]} x {G.shape[1]}, "
                         f"above the dense limit {DENSE_MAX_DIMENSION} of its SVD)", {})
    if sigma is None:
        sigma = np.linalg.svd(G, compute_uv=False)
    local = "" if ls.kind == "lti" else (" (on the lifting along the nominal trajectory: for a "
                                          "nonlinear plant a local statement)")
    op = error_operator(G, lifted_law, sigma)
    if op.T_e is None:
        return Condition("error_norm_2", None, "not applicable",
                         "tracking error e_i: " + op.formula + "; the input-error conditions "
                         "and error_floor decide", {"about_limit": True})
    quantity = "e_i - e_inf (the tracking error about its limit)" if op.about_limit \
        else "e_i (the tracking error)"
    norm = dense_norm_2(op.T_e)[0] if op.T_e.size else 0.0
    details = {"formula": op.formula, "about_limit": op.about_limit, "quantity": quantity,
               "sigma_max": float(sigma[0]) if sigma.size else 0.0,
               "sigma_min": float(sigma[-1]) if sigma.size else 0.0}
    proof = None if op.about_limit else (_gradient_proof(law, lifted_law, G, sigma)
                                         or _norm_optimal_proof(law, lifted_law, G, sigma,
                                                                problem))
    if proof is not None and proof["decides"]:
        status = proof["status"]
        details.update({"proof": "structure", **proof})
        if status == "holds":
            strict = bool(proof["strict"])
            meaning = (f"tracking error e_i: ||e_(i+1)||_2 <= ||e_i||_2 for every trial, proven "
                       f"by structure ({proof['structure']}; {proof['condition']}"
                       + (f": beta sigma_max^2 = {_fmt(proof['beta_sigma_max_sq'])} with a "
                          f"relative rounding margin {proof['relative_margin']:.2g}"
                          if "beta_sigma_max_sq" in proof else "") + ")"
                       + ("; strictly decreasing" if strict else
                          "; non-increasing (a component may stay: unreachable part of r, or "
                          "eigenvalue -1 / 1 of T_e)") + local)
            return Condition("error_norm_2", norm, "holds", meaning, details, lower=norm,
                             upper=norm)
        if status == "fails":
            return Condition("error_norm_2", norm, "fails",
                             f"tracking error e_i: {proof['condition']} is violated "
                             f"(beta sigma_max^2 = {_fmt(proof.get('beta_sigma_max_sq'))}): "
                             "the error along the top singular direction grows (eigenvalue "
                             "of T_e below -1)" + local, details, lower=norm, upper=norm)
        return Condition("error_norm_2", norm, "unknown",
                         f"tracking error e_i: {proof['condition']} is within rounding of its "
                         f"bound (beta sigma_max^2 = {_fmt(proof.get('beta_sigma_max_sq'))}, "
                         f"relative margin {proof.get('relative_margin', 0.0):.2g}): not "
                         "established" + local, details, lower=norm, upper=norm)
    if proof is not None:
        details.update({"structure": proof["structure"],
                        "weighted_norm_proven": proof.get("weighted_norm_proven", False)})
    scale = max(1.0, float(np.max(np.abs(op.T_e))) if op.T_e.size else 1.0)
    verdict = threshold_verdict(norm, 1.0, scale=scale)
    details.update({"proof": "computed norm", "tolerance": verdict_tolerance(1.0, scale=scale),
                    "strict": verdict == "holds"})
    weighted = (" (||e||_W_e is non-increasing by structure: T_e is W_e-self-adjoint with "
                "eigenvalues in (0, 1])" if details.get("weighted_norm_proven") else "")
    text = {"holds": f"||T_e||_2 = {_fmt(norm)} < 1: ||{'e_i - e_inf' if op.about_limit else 'e_i'}"
                     "||_2 decreases strictly from trial to trial",
            "marginal": f"||T_e||_2 = {_fmt(norm)} equals 1 within rounding: non-increasing "
                        "not established",
            "fails": f"||T_e||_2 = {_fmt(norm)} > 1: some tracking error grows in the next "
                     "trial"}[verdict]
    return Condition("error_norm_2", norm, verdict,
                     f"tracking error {quantity}: {text} [{op.formula}]" + weighted + local,
                     details, lower=norm, upper=norm)


def error_clause(condition: Condition) -> str:
    """The summary's clause for ``error_norm_2`` (the quantity named)."""
    d = condition.details
    q = "||e_i - e_inf||_2" if d.get("about_limit") else "||e||_2"
    if condition.verdict == "not applicable":
        return "tracking error: not judged (no error operator T_e)"
    if condition.verdict == "holds":
        if d.get("proof") == "structure":
            return (f"tracking error {q} non-increasing (proven by structure: "
                    f"{d.get('condition', '')})")
        shown = (f"= {_fmt(condition.value)}" if condition.lower is None
                 or _fmt(condition.lower) == _fmt(condition.upper) else
                 f"in [{_fmt(condition.lower)}, {_fmt(condition.upper)}]")
        return f"tracking error {q} decreases monotonically (||T_e||_2 {shown})"
    if condition.verdict == "fails":
        return f"tracking error {q} can GROW from trial to trial (error_norm_2 fails)"
    return f"tracking error {q}: monotonicity {condition.verdict}"
