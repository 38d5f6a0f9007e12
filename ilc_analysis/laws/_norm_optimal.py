r"""Norm-optimal ILC: Amann/Owens weights (Q, R) and the Gunnarsson-Norrlöf (ρ, λ) form.

Each trial's input minimises, for the lifted prediction :math:`e_{i+1} = e_i - G(u_{i+1}-u_i)`,

.. math::

    J = e_{i+1}^\top W_e\, e_{i+1} + u_{i+1}^\top W_u\, u_{i+1}
        + (u_{i+1} - u_i)^\top W_{\Delta}\,(u_{i+1} - u_i),

whose stationarity condition :math:`(H + W_u)u_{i+1} = H u_i + G^\top W_e e_i`,
:math:`H = G^\top W_e G + W_\Delta`, gives the Q/L form

.. math::

    u_{i+1} = Q_{no}\,(u_i + L_{no}\, e_i),\qquad
    L_{no} = H^{-1} G^\top W_e,\qquad Q_{no} = (H + W_u)^{-1} H,

and :math:`T = Q_{no}(I - L_{no}G) = (H + W_u)^{-1}W_\Delta` for the exact model.

A step size :math:`0 < \alpha \le 1` (``step_size``; Liao-McPherson et al. 2022) takes only
the fraction α of that step, :math:`u_{i+1} = u_i + \alpha\,(u^{no}_{i+1} - u_i)` with
:math:`u^{no}_{i+1}` the minimiser of J, i.e. a Newton step of length α on J:

.. math::

    u_{i+1} = u_i + \alpha P\big(G^\top W_e e_i - W_u u_i\big),\qquad P = (H + W_u)^{-1},

    L_{no} = \alpha\,\big(H + (1-\alpha)W_u\big)^{-1}G^\top W_e,\qquad
    Q_{no} = (H + W_u)^{-1}\big(H + (1-\alpha)W_u\big),

(:math:`Q_{no}L_{no} = \alpha PG^\top W_e`, :math:`Q_{no} = I - \alpha PW_u`) and
:math:`T = (1-\alpha)I + \alpha (H + W_u)^{-1}W_\Delta` for the exact model; α = 1 is the
law above.
With :math:`W_u = 0` (Amann, Owens & Rogers 1996, weights Q = W_e, R = W_Δ) this is
:math:`u_{i+1} = u_i + (G^\top QG + R)^{-1}G^\top Q e_i`; with :math:`W_e = I`, :math:`R = rI`
the input error contracts along the k-th right singular vector of G by exactly
:math:`1/(1 + \sigma_k^2/r)`. The (ρ, λ) form of Gunnarsson & Norrlöf (2001) is
:math:`W_e = I,\ W_u = \rho I,\ W_\Delta = \lambda I`.

:func:`norm_optimal_gains` is the one place these gains are computed (dense model).

On a state-space trial model (:class:`~ilc_analysis.laws._riccati.StateSpaceTrial`, LTI or
LTV; :meth:`NormOptimalLaw.from_problem`) the law never forms G: the update is

.. math::

    u_{i+1} = P\big(W_\Delta u_i + G^\top W_e(Gu_i + e_i)\big),\qquad
    P = (G^\top W_eG + W_\Delta + W_u)^{-1},

(the same map: :math:`Q_{no}(u + L_{no}e) = P(Hu + G^\top W_e e)`), P applied by the Riccati
recursion of :mod:`~ilc_analysis.laws._riccati` (Amann, Owens & Rogers 1996), O(N n^2) per
trial; its operators are :math:`L_1 = PG^\top W_e`, :math:`Q = I - PW_u`
(:meth:`NormOptimalLaw.lifted_operators`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse

from .._progress import progress
from .._validation import as_finite_array, nonnegative, positive
from ..exceptions import InternalError, ParameterError, ShapeError, SolverError
from ..lifting import LiftedOperator, LiftedSystem, MatrixOperator
from ..lifting._lifted_operator import IdentityOperator
from ._base import (
    LawOperators,
    LawResponse,
    LearningLaw,
    LiftedLaw,
    as_lti_plant,
    as_problem,
    check_lifted_system,
    check_omega,
    check_same_trial,
    check_trial_signals,
    check_ts_match,
    lifted_model_is_plant,
    plant_response,
    shift_of,
)
from ._qfilter import QFilter, apply_q
from ._riccati import (
    NormOptimalInverse,
    RiccatiSolver,
    StateSpaceTrial,
    as_state_space_trial,
    problem_state_space,
    state_space_operator,
)

__all__ = ["NormOptimalLaw", "norm_optimal_gains", "lifted_weight", "step_size_value"]

#: relative asymmetry tolerated in a full weight matrix
_SYMMETRY_RTOL = 1e-10


def lifted_weight(value, name: str, n: int, N: int, *, definite: bool) -> np.ndarray:
    r"""A lifted weight: a scalar, per channel ``(n,)``, per lifted entry ``(N*n,)`` (all
    diagonal, returned as the diagonal ``(N*n,)``) or a full symmetric ``(N*n, N*n)`` matrix.

    ``definite``: positive definite required (else positive semi-definite).
    """
    if isinstance(value, bool):
        raise ParameterError(f"{name} must be a number or an array; got {value!r}")
    arr = as_finite_array(value, name)
    need = "positive definite" if definite else "positive semi-definite"
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.ndim == 1:
        if arr.shape[0] not in (n, N * n):
            raise ShapeError(f"{name} must be a scalar, shape ({n},) per channel, ({N * n},) per "
                             f"lifted entry or ({N * n}, {N * n}); found shape {arr.shape}")
        bad = arr <= 0 if definite else arr < 0
        if np.any(bad):
            raise ParameterError(f"{name} must be {need}: its diagonal has "
                                 f"{'non-positive' if definite else 'negative'} entries "
                                 f"(min {arr.min():g})")
        return np.tile(arr, N) if arr.shape[0] == n else arr.copy()
    if arr.shape != (N * n, N * n):
        raise ShapeError(f"{name} must be a scalar, shape ({n},), ({N * n},) or "
                         f"({N * n}, {N * n}); found shape {arr.shape}")
    scale = max(np.max(np.abs(arr)), 1e-300)
    if np.max(np.abs(arr - arr.T)) > _SYMMETRY_RTOL * scale:
        raise ParameterError(f"{name} must be symmetric")
    lam = float(np.min(np.linalg.eigvalsh(0.5 * (arr + arr.T))))
    if (definite and lam <= 0) or (not definite and lam < -_SYMMETRY_RTOL * scale):
        raise ParameterError(f"{name} must be {need}; its smallest eigenvalue is {lam:.3g}")
    return 0.5 * (arr + arr.T)


def _times(W: np.ndarray, M: np.ndarray) -> np.ndarray:
    """W M for a diagonal (1-D) or full weight."""
    return W[:, None] * M if W.ndim == 1 else W @ M


def _plus(M: np.ndarray, W: np.ndarray) -> np.ndarray:
    out = np.array(M, dtype=float)
    if W.ndim == 1:
        out[np.diag_indices_from(out)] += W
    else:
        out += W
    return out


def norm_optimal_gains(G, weight_error, weight_input_change, weight_input=None,
                       step_size: float = 1.0):
    """The dense gains, with a progress bar (:mod:`ilc_analysis._progress`): O(n^3) work that
    takes tens of seconds at a few thousand samples (:func:`_dense_gains`)."""
    with progress(desc=f"norm-optimal gains ({np.shape(G)[1]} x {np.shape(G)[1]}, dense)",
                  unit="step") as bar:
        out = _dense_gains(G, weight_error, weight_input_change, weight_input, step_size)
        bar.update()
    return out


def _dense_gains(G, weight_error, weight_input_change, weight_input=None,
                 step_size: float = 1.0):
    r"""The norm-optimal gains :math:`L_{no} = \alpha H_\alpha^{-1}G^\top W_e` and
    :math:`Q_{no} = (H + W_u)^{-1}H_\alpha`, :math:`H = G^\top W_e G + W_\Delta`,
    :math:`H_\alpha = H + (1-\alpha)W_u` (module docstring; α = 1: :math:`H_\alpha = H`).

    Parameters
    ----------
    G : ndarray (p, q)
    weight_error : ndarray
        :math:`W_e`: the diagonal ``(p,)`` or the full ``(p, p)`` matrix (PSD).
    weight_input_change : ndarray
        :math:`W_\Delta`: diagonal ``(q,)`` or full ``(q, q)`` (positive definite).
    weight_input : ndarray or None
        :math:`W_u`: diagonal or full (PSD); None or all zero: no Q (returned as None).
    step_size : float
        α in (0, 1] (default 1: the full norm-optimal step).

    Returns
    -------
    (L_no, Q_no) : ndarray (q, p), ndarray (q, q) or None
    """
    G = np.asarray(G, dtype=float)
    GtWe = _times(weight_error, G).T           # G^T W_e (W_e symmetric)
    H = _plus(GtWe @ G, weight_input_change)
    try:
        factor = scipy.linalg.cho_factor(H, lower=True)
    except np.linalg.LinAlgError as exc:     # H is PD in exact arithmetic (W_Delta > 0)
        raise SolverError(
            "norm-optimal gains: H = G^T W_e G + W_Delta is not positive definite in double "
            f"precision (largest |G| = {np.max(np.abs(G)):.3g}: a plant or loop whose response "
            "grows over the trial makes W_Delta vanish against G^T W_e G); shorten the trial, "
            "stabilise the plant, or raise weight_input_change") from exc
    if weight_input is None or not np.any(weight_input):
        return step_size * scipy.linalg.cho_solve(factor, GtWe), None
    H_alpha = H if step_size == 1.0 else _plus(H, (1.0 - step_size) * weight_input)
    if step_size != 1.0:            # H + (1 - alpha) W_u >= H > 0: its factor exists if H's does
        factor = scipy.linalg.cho_factor(H_alpha, lower=True)
    L = step_size * scipy.linalg.cho_solve(factor, GtWe)
    Qm = np.linalg.solve(_plus(H, weight_input), H_alpha)
    return L, Qm


@dataclass(frozen=True, eq=False)
class NormOptimalLaw(LearningLaw):
    r"""Norm-optimal ILC on a lifted model (module docstring).

    .. math::

        u_{i+1} = Q_{no}(u_i + L_{no} e_i),\quad L_{no} = (G^\top W_e G + W_\Delta)^{-1}G^\top W_e,
        \quad Q_{no} = (G^\top W_e G + W_\Delta + W_u)^{-1}(G^\top W_e G + W_\Delta).

    References: N. Amann, D. H. Owens, E. Rogers, "Iterative learning control for discrete-time
    systems with exponential rate of convergence", IEE Proc. Control Theory Appl. 143(2),
    217-224, 1996; S. Gunnarsson, M. Norrlöf, "On the design of ILC algorithms using
    optimization", Automatica 37(12), 2011-2016, 2001.

    Parameters
    ----------
    model : LiftedSystem or state-space trial model
        The lifted model :math:`\hat G` (its trial: N, shift, ts); or a per-sample state-space
        trial model (:class:`~ilc_analysis.laws._riccati.StateSpaceTrial`, or any record with
        ``state_space`` = (A, B, C, D) per sample, ``N``, ``shift``, ``ts``, e.g. a
        ``LiftedPlant``): the Riccati form, G never formed (diagonal weights only).
    weight_input_change : float or array_like
        :math:`R = W_\Delta` (positive definite): scalar, per input channel, per lifted entry,
        or a full matrix. Required: it sets the learning speed (small: fast; large: cautious).
    weight_error : float or array_like
        :math:`Q = W_e` (positive semi-definite), same forms per output channel; default 1.
    weight_input : float or array_like
        :math:`S = W_u` (positive semi-definite); default 0 (no Q-filter, zero error floor).
    name : str
        Label used in results and reports.
    q_filter : QFilter, optional
        A zero-phase filter :math:`Q_f` applied after the update,
        :math:`u_{i+1} = Q_f Q_{no}(u_i + L_{no}e_i)` (:func:`~ilc_analysis.laws._qfilter.apply_q`;
        lifted: :math:`Q = Q_f Q_{no}`); default none.
    step_size : float
        α in (0, 1]: the fraction of the norm-optimal step taken each trial (module
        docstring); default 1 (the full step). A smaller α learns more slowly and is more
        robust to model error.
    """

    model: LiftedSystem | StateSpaceTrial
    weight_input_change: object
    weight_error: object = 1.0
    weight_input: object = 0.0
    name: str = "norm-optimal"
    q_filter: QFilter | None = None
    step_size: float = 1.0
    _We: np.ndarray = field(init=False, repr=False)
    _Wd: np.ndarray = field(init=False, repr=False)
    _Wu: np.ndarray = field(init=False, repr=False)
    _L: np.ndarray | None = field(init=False, repr=False)
    _Q: np.ndarray | None = field(init=False, repr=False)
    _trial: LiftedSystem | StateSpaceTrial = field(init=False, repr=False)
    _solver: RiccatiSolver | None = field(init=False, repr=False)
    _Gm: LiftedOperator | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        riccati = not isinstance(self.model, LiftedSystem)
        m: LiftedSystem | StateSpaceTrial = (as_state_space_trial(self.model) if riccati
                                             else check_lifted_system(self.model, "model"))
        if self.q_filter is not None and not isinstance(self.q_filter, QFilter):
            raise ParameterError(f"q_filter must be a QFilter or None; got "
                                 f"{type(self.q_filter).__name__}")
        We = lifted_weight(self.weight_error, "weight_error (Q)", m.n_y, m.N, definite=False)
        Wd = lifted_weight(self.weight_input_change, "weight_input_change (R)", m.n_u, m.N,
                           definite=True)
        Wu = lifted_weight(self.weight_input, "weight_input (S)", m.n_u, m.N, definite=False)
        object.__setattr__(self, "step_size", step_size_value(self.step_size))
        L = Qm = solver = Gm = None
        if riccati:
            for W, name in ((We, "weight_error"), (Wd, "weight_input_change"),
                            (Wu, "weight_input")):
                if W.ndim != 1:
                    raise ParameterError(
                        f"{name}: a full weight matrix needs the dense model (pass a "
                        "LiftedSystem, e.g. problem.lifted); the state-space (Riccati) form "
                        "takes scalars, per-channel or per-lifted-entry diagonals")
            if not isinstance(m, StateSpaceTrial):
                raise InternalError("the Riccati form runs on a StateSpaceTrial")
            solver = RiccatiSolver(m, We, Wd + Wu)
            Gm = state_space_operator(m)
        else:
            if not isinstance(m, LiftedSystem):
                raise InternalError("the dense form runs on a LiftedSystem")
            L, Qm = norm_optimal_gains(m.G, We, Wd, Wu, self.step_size)
        for name, value in (("_We", We), ("_Wd", Wd), ("_Wu", Wu), ("_L", L), ("_Q", Qm)):
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_trial", m)
        object.__setattr__(self, "_solver", solver)
        object.__setattr__(self, "_Gm", Gm)

    @classmethod
    def from_problem(cls, problem, weight_input_change, weight_error=1.0, weight_input=0.0, *,
                     name: str = "norm-optimal", q_filter: QFilter | None = None,
                     step_size: float = 1.0) -> NormOptimalLaw:
        r"""The law in Riccati form on ``problem``'s state-space trial model (G never formed).

        The model is ``problem.dplant`` (LTI: its matrices) or its per-sample Jacobians along
        ``problem.u_nominal`` (:func:`~ilc_analysis.laws._riccati.problem_state_space`): the
        same G as ``problem.lifted``, so the law equals ``NormOptimalLaw(problem.lifted, ...)``
        (to rounding) at any N, in O(N n^3) to set up and O(N n^2) per trial.

        Parameters
        ----------
        problem : ILCProblem
            The problem whose plant (or its Jacobians along ``u_nominal``) is the model.
        weight_input_change : float or array_like
            :math:`W_\Delta` (positive), diagonal forms only (scalar, per channel, per lifted
            entry), as for the class.
        weight_error : float or array_like
            :math:`W_e` (non-negative), diagonal forms only; default 1.
        weight_input : float or array_like
            :math:`W_u` (non-negative), diagonal forms only; default 0.
        name : str
            Label used in results and reports.
        q_filter : QFilter, optional
            A zero-phase filter applied after the update (as for the class).
        step_size : float
            α in (0, 1], as for the class; default 1.

        Returns
        -------
        NormOptimalLaw

        Raises
        ------
        ParameterError, ShapeError
            A problem that is not an ILCProblem, weights of the wrong form.
        SolverError
            The Riccati factorisation fails (the sample is named).
        """
        problem = as_problem(problem)
        return cls(problem_state_space(problem), weight_input_change=weight_input_change,
                   weight_error=weight_error, weight_input=weight_input, name=name,
                   q_filter=q_filter, step_size=step_size)

    @classmethod
    def rho_lambda(cls, model: LiftedSystem, rho: float, lam: float) -> NormOptimalLaw:
        r"""The Gunnarsson & Norrlöf (2001) scalar form: :math:`W_e = I`, :math:`W_u = \rho I`,
        :math:`W_\Delta = \lambda I` (ρ >= 0, λ > 0):
        :math:`Q = (G^\top G + (\rho+\lambda)I)^{-1}(G^\top G + \lambda I)`,
        :math:`L = (G^\top G + \lambda I)^{-1}G^\top`.

        Parameters
        ----------
        model : LiftedSystem
            The lifted model :math:`\hat G`.
        rho : float
            :math:`\rho \ge 0`, the weight on the input (0: no Q-filter).
        lam : float
            :math:`\lambda > 0`, the weight on the input change.

        Returns
        -------
        NormOptimalLaw

        Raises
        ------
        ParameterError
            ``rho`` negative or ``lam`` not positive (or not finite numbers).
        """
        rho = nonnegative(rho, "rho (weight on the input)")
        lam = positive(lam, "lam (weight on the input change)")
        return cls(model, weight_input_change=lam, weight_error=1.0, weight_input=rho,
                   name=f"norm-optimal (rho={rho:g}, lambda={lam:g})")

    # the interface ---------------------------------------------------------------------------
    @property
    def riccati(self) -> bool:
        """Whether the law runs in Riccati form (a state-space model, G never formed)."""
        return self._solver is not None

    @property
    def gains(self) -> tuple[np.ndarray, np.ndarray | None]:
        """``(L_no, Q_no)`` on the model's trial (Q_no None without an input weight); dense
        (formed from the model's G on first use in Riccati form)."""
        if self._L is None:
            if not isinstance(self._trial, StateSpaceTrial):
                raise InternalError("dense gains are missing only in Riccati form")
            from ..lifting._trial_map import _assemble

            A, B, C, D = self._trial.state_space
            G = _assemble(A, B, C, D, self._trial.N, self._trial.shift)
            L, Qm = norm_optimal_gains(G, self._We, self._Wd, self._Wu, self.step_size)
            for name, value in (("_L", L), ("_Q", Qm)):
                if value is not None:
                    value.setflags(write=False)
                object.__setattr__(self, name, value)
        if self._L is None:
            raise InternalError("norm_optimal_gains returned no L")
        return self._L, self._Q

    @property
    def inverse_operator(self) -> NormOptimalInverse:
        r""":math:`P = (G^\top W_eG + W_\Delta + W_u)^{-1}` as a lifted operator (Riccati form).

        Raises
        ------
        ParameterError
            The law runs on a dense model (use :attr:`gains`).
        """
        if self._solver is None:
            raise ParameterError(f"{self.name}: the inverse operator needs a state-space model "
                                 "(NormOptimalLaw.from_problem); this law has a dense one")
        return self._solver.operator

    def check(self, lifted_system) -> None:
        trial: Any = self._trial          # a LiftedSystem or a record of the same trial fields
        check_same_trial(trial, lifted_system)

    def check_problem(self, problem) -> None:
        """Raise unless the law's trial (N, n_u, n_y, shift, ts) is ``problem``'s, without
        lifting the problem (what :meth:`check` compares).

        Parameters
        ----------
        problem : ILCProblem
            The problem the law is to run on.

        Raises
        ------
        ShapeError, ParameterError
            Another trial, or another sample time.
        """
        _check_trial(self._trial, as_problem(problem), "the problem")

    def lifted(self, lifted_system) -> LiftedLaw:
        self.check(lifted_system)
        ls = lifted_system
        _, Q = self.gains
        if self.q_filter is not None:
            Qf = self.q_filter.lifted_matrix(ls.N, ls.n_u, ls.ts)
            Q = Qf if Q is None else Qf @ Q
        return LiftedLaw(self.gains[0], None, Q, 0.0,
                         description=f"{self.name} ILC on the lifted model (N={ls.N}, "
                                     f"shift {ls.shift}); T = Q(I - L G)")

    def lifted_operators(self, lifted_plant) -> LawOperators:
        r"""The law's lifted operators without forming an N x N matrix (Riccati form):
        :math:`L_1 = L_{no} = \alpha H_\alpha^{-1}G^\top W_e`, :math:`Q = Q_fQ_{no}`,
        :math:`Q_{no} = I - \alpha PW_u` (None without an input weight and Q-filter),
        :math:`L_2` None, a = 0, no offset; G the law's own model,
        :math:`H_\alpha = G^\top W_eG + W_\Delta + (1-\alpha)W_u`,
        :math:`P = (G^\top W_eG + W_\Delta + W_u)^{-1}` (Riccati solvers;
        :math:`H_\alpha^{-1} = P` when :math:`W_u = 0`, else a second factorisation). A dense
        model gives its matrices as :class:`~ilc_analysis.lifting.MatrixOperator`\ s.

        Parameters
        ----------
        lifted_plant : LiftedPlant, LiftedSystem or ILCProblem-like record
            The trial the law runs on (its N, n_u, n_y, shift, ts must be the law's).

        Returns
        -------
        LawOperators

        Raises
        ------
        ShapeError, ParameterError
            Another trial.
        """
        m = self._trial
        _check_trial(m, lifted_plant, "the lifted plant")
        N, n_u, n_y = m.N, m.n_u, m.n_y
        Q: LiftedOperator | None
        if self._solver is None or self._Gm is None:
            L_dense, Q_dense = self.gains
            L1: LiftedOperator = MatrixOperator(L_dense, (n_u, n_y), "L_no")
            Q = None if Q_dense is None else MatrixOperator(Q_dense, (n_u, n_u), "Q_no")
        else:
            if not isinstance(m, StateSpaceTrial):
                raise InternalError("the Riccati form runs on a StateSpaceTrial")
            P = self._solver.operator
            alpha = self.step_size
            We = MatrixOperator(scipy.sparse.diags_array(alpha * self._We), (n_y, n_y),
                                "alpha W_e")
            Q = None
            Hinv = P
            if np.any(self._Wu):
                # Q_no = I - alpha P W_u, L_no = alpha H_alpha^-1 G^T W_e: Q L1 = alpha P G^T W_e
                Wu = MatrixOperator(scipy.sparse.diags_array(alpha * self._Wu), (n_u, n_u),
                                    "alpha W_u")
                Q = IdentityOperator(N * n_u, n_u) - P @ Wu
                Hinv = RiccatiSolver(m, self._We, self._Wd + (1.0 - alpha) * self._Wu,
                                     "W_Delta").operator
            L1 = Hinv @ self._Gm.T @ We
        closed = plant = None
        if self.q_filter is not None:
            Qf = self.q_filter.operator(N, n_u, m.ts)
            Q = Qf if Q is None else Qf @ Q
        else:
            exact = self._exact_model_inverse(lifted_plant)
            if exact is not None:
                # the exact model: T = Q_no (I - L_no G) = I - a P (G^T W_e G + W_u)
                #                    = (1 - a) I + a P W_Delta
                closed = exact @ MatrixOperator(scipy.sparse.diags_array(self._Wd), (n_u, n_u),
                                            "W_Delta")
                if self.step_size != 1.0:
                    closed = (1.0 - self.step_size) * IdentityOperator(N * n_u, n_u) \
                        + self.step_size * closed
                plant = lifted_plant.G
        return LawOperators(L1, None, Q, 0.0, None, closed_form=closed, closed_form_plant=plant,
                            description=f"{self.name} ILC ({'Riccati' if self.riccati else 'dense'}"
                                        f" form, N={N}, shift {m.shift}, step "
                                        f"{self.step_size:g}): L1 = a H_a^-1 G^T W_e, "
                                        "Q = I - a P W_u, H_a = G^T W_e G + W_Delta + "
                                        "(1 - a) W_u, P = (G^T W_e G + W_Delta + W_u)^-1")

    def exact_model(self, problem) -> bool:
        r"""Whether the law's model is ``problem``'s own plant, entry for entry, however the
        law was built: in Riccati form (:meth:`from_problem`, or any state-space trial model)
        its per-sample matrices are those of ``problem.lifted_plant``; in dense form
        (``NormOptimalLaw(problem.lifted, ...)``) its G is the problem's lifted G (the dense
        lifting, when the problem has formed it, else, for an LTI problem, the block Toeplitz
        matrix of the plant operator's Markov parameters, :func:`lifted_model_is_plant`).

        The structural proofs of norm-optimal ILC with the exact model
        (:math:`T_e = (I + GW_\Delta^{-1}G^\top W_e)^{-1}`, :math:`T = PW_\Delta`) rest on it.

        Parameters
        ----------
        problem : ILCProblem
        """
        problem = as_problem(problem)
        m = self._trial
        if (m.N, m.n_u, m.n_y, m.shift) != (problem.N, problem.n_u, problem.n_y, problem.shift) \
                or not np.isclose(m.ts, problem.ts, rtol=1e-12, atol=0.0):
            return False
        lp = problem.lifted_plant
        if self._solver is not None or isinstance(m, StateSpaceTrial):
            return _same_model(m, lp)
        G = np.asarray(m.G)
        if "lifted" in getattr(problem, "__dict__", {}):
            return np.array_equal(G, np.asarray(problem.lifted.G))
        if lp.G.toeplitz_blocks() is not None:     # LTI: the same Markov parameters, exactly
            return lifted_model_is_plant(m, lp)
        return np.array_equal(G, np.asarray(problem.lifted.G))

    def _exact_model_inverse(self, lifted_plant) -> NormOptimalInverse | None:
        r""":math:`P = (G^\top W_eG + W_\Delta + W_u)^{-1}` (Riccati form) when the law's model
        is the plant's own lifted G, entry for entry: its state-space model
        (:func:`_same_model`), or a dense model equal to the lifted plant's block Toeplitz
        matrix of an LTI state-space realisation (then P is factored on that realisation,
        with the law's diagonal weights). None otherwise (model error, full weights), and for a
        dense model when the Riccati form would store more than the dense matrix it replaces:
        its per-sample :math:`n_x \times n_x` matrices take :math:`(N+s) n_x^2` numbers against
        :math:`(N n_u)^2` for P (a FIR model of M taps realised with M states: M = 700, N = 1000
        asked for more than 20 GB)."""
        m = self._trial
        if self._solver is not None:
            return self._solver.operator if _same_model(m, lifted_plant) else None
        if isinstance(m, StateSpaceTrial):      # a state-space model without its solver
            return None
        if getattr(lifted_plant, "state_space", None) is None \
                or any(W.ndim != 1 for W in (self._We, self._Wd, self._Wu)):
            return None
        trial = as_state_space_trial(lifted_plant)
        if (trial.N + trial.shift) * trial.n_x ** 2 > (trial.N * trial.n_u) ** 2 \
                or not lifted_model_is_plant(m, lifted_plant):
            return None
        return RiccatiSolver(trial, self._We, self._Wd + self._Wu).operator

    def model_text(self) -> str:
        m = self._trial
        if self.riccati:
            return (f"the law's own state-space trial model (N={m.N}, shift {m.shift}, "
                    f"ts={m.ts:g}, {m.kind}): L_no, Q_no of its G (Riccati form)")
        return (f"the law's own lifted model (N={m.N}, shift {m.shift}, ts={m.ts:g}, {m.kind} "
                f"lifting): L_no, Q_no of its G")

    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        r""":math:`Q_{no}(u_i + L_{no}e_i)` on the model's trial (with the step size:
        :math:`u_i + \alpha P(G^\top W_e e_i - W_u u_i)`).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial (N the model's).
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        ts : float
            Sample time [s]; must match the model's.

        Returns
        -------
        ndarray (N, n_u)

        Raises
        ------
        ParameterError
            A sample time that differs from the model's.
        ShapeError
            Signals that do not fit the model's trial.
        """
        m = self._trial
        u, e = check_trial_signals(u_i, e_i, m.n_u, m.n_y)
        check_ts_match(ts, m.ts, "the law's model")
        if u.shape[0] != m.N:
            raise ShapeError(f"u_i must have shape ({m.N}, {m.n_u}) (the model's trial); found "
                             f"shape {u.shape}")
        if self._solver is not None and self._Gm is not None:
            # P (W_Delta u + G^T W_e (G u + e)): two sweeps of the model, two of the solver
            uf = u.reshape(-1)
            v = self._solver.solve(self._Wd * uf + self._Gm.rmatvec(
                self._We * (self._Gm.matvec(uf) + e.reshape(-1))))
            if self.step_size != 1.0:        # u + alpha (full step - u)
                v = uf + self.step_size * (v - uf)
        else:
            if self._L is None:
                raise InternalError("the dense form has its gains")
            v = u.reshape(-1) + self._L @ e.reshape(-1)
            if self._Q is not None:
                v = self._Q @ v
        return apply_q(self.q_filter, v.reshape(u.shape), ts)

    def _channel_weights(self):
        """Per-channel diagonal weights, or None when they vary along the trial / are full."""
        m = self._trial
        out = []
        for W, n in ((self._We, m.n_y), (self._Wd, m.n_u), (self._Wu, m.n_u)):
            if W.ndim != 1:
                return None
            per = W.reshape(m.N, n)
            if np.any(per != per[0]):
                return None
            out.append(per[0])
        return out

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r"""The infinite-trial (non-causal) counterpart for time-invariant diagonal weights:
        :math:`L = \alpha(P^HW_eP + W_\Delta + (1-\alpha)W_u)^{-1}P^HW_e`,
        :math:`Q = (P^HW_eP + W_\Delta + W_u)^{-1}(P^HW_eP + W_\Delta + (1-\alpha)W_u)` (the
        shift cancels);
        ``plant`` must be the LTI system behind the model.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete-time python-control system
            The LTI system behind the lifted model (its Markov parameters must be the
            model's).
        omega : array_like (n_w,)
            Angular frequencies [rad/s] in :math:`[0, \pi/T_s]`.
        shift : int, optional
            s (default: the plant's sampled relative degree); must be the model's.

        Returns
        -------
        LawResponse

        Raises
        ------
        ParameterError
            Weights that vary along the trial or are full matrices, or a plant that is not
            the law's model.
        """
        from ._gradient import _check_plant_is_model

        weights = self._channel_weights()
        if weights is None:
            raise ParameterError("the frequency response needs time-invariant diagonal weights "
                                 "(scalars or per channel); these vary along the trial or are "
                                 "full matrices: use the lifted analysis")
        We, Wd, Wu = weights
        dp = as_lti_plant(plant)
        model: Any = self._trial          # kind, shift, n_u, n_y, ts and markov_blocks()
        _check_plant_is_model(dp, model, shift_of(dp, shift))
        omega = check_omega(omega, dp.ts)
        P = plant_response(dp, omega)
        PhWe = np.conj(P.transpose(0, 2, 1)) * We[None, None, :]
        alpha = self.step_size
        H = PhWe @ P + np.diag(Wd)
        H_alpha = H + np.diag((1.0 - alpha) * Wu)
        L = alpha * np.linalg.solve(H_alpha, PhWe)
        Q = np.linalg.solve(H + np.diag(Wu), H_alpha) if np.any(Wu) else None
        if self.q_filter is not None:
            mag = self.q_filter.magnitude(omega / (2.0 * np.pi), dp.ts)[:, None, None]
            Q = mag * (np.eye(dp.n_u) if Q is None else Q)
        return LawResponse(omega, L, Q, None, 0.0, dp.ts)

    def describe(self) -> dict:
        m = self._trial

        def plain(W):
            if W.ndim == 1 and np.all(W == W[0]):
                return float(W[0])
            return W.tolist()

        out = {"law": "norm_optimal", "name": self.name,
               "weight_error": plain(self._We), "weight_input_change": plain(self._Wd),
               "weight_input": plain(self._Wu),
               "model": {"kind": "state_space" if self.riccati else "lifted", "N": m.N,
                         "shift": m.shift, "ts": m.ts, "lifting": m.kind}}
        if self.q_filter is not None:
            out["q_filter"] = self.q_filter.as_dict()
        if self.step_size != 1.0:
            out["step_size"] = self.step_size
        return out


def step_size_value(value, name: str = "step_size") -> float:
    r"""The step size α of a norm-optimal law: a real number in (0, 1] (1: the full step).

    Parameters
    ----------
    value : float
        The step size given by the caller.
    name : str
        Its name in messages (a design file's key path).

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        Not a finite real number in (0, 1].
    """
    what = f"{name} (alpha, the fraction of the norm-optimal step)"
    alpha = positive(value, what)
    if alpha > 1.0:
        raise ParameterError(f"{what} must be in (0, 1] (1: the full step); got {value!r}")
    return alpha


def _check_trial(mine, theirs, what: str) -> None:
    """Raise unless ``theirs`` (any record of N, n_u, n_y, shift, ts) is the law's trial."""
    a = (mine.N, mine.n_u, mine.n_y, mine.shift)
    b = tuple(getattr(theirs, k, None) for k in ("N", "n_u", "n_y", "shift"))
    if a != b:
        raise ShapeError(f"the law's model is a trial with (N, n_u, n_y, shift) = {a}; {what} "
                         f"has {b}")
    check_ts_match(theirs.ts, mine.ts, "the law's model")


def _same_model(model, lifted_plant) -> bool:
    """The law's state-space model is the lifted plant's own, entry for entry (same trial,
    same per-sample matrices): T then has the exact-model closed form."""
    ss = getattr(lifted_plant, "state_space", None)
    G = getattr(lifted_plant, "G", None)
    if ss is None or not isinstance(G, LiftedOperator) or not isinstance(model, StateSpaceTrial):
        return False
    if (model.N, model.shift) != (lifted_plant.N, lifted_plant.shift):
        return False
    return all(np.shape(a) == np.shape(b) and np.array_equal(a, b)
               for a, b in zip(model.state_space, ss, strict=True))
