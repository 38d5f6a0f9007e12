r"""Gradient (adjoint) ILC, with a model or model-free by time reversal.

Both laws take a steepest-descent step of :math:`\tfrac12\|e\|^2` in the lifted input:

.. math::

    u_{i+1} = u_i + \beta\,G^\top e_i,\qquad
    T = I - \beta G^\top G,\qquad e_{i+1} = (I - \beta GG^\top)\,e_i

for the exact plant. The eigenvalues of :math:`GG^\top` are :math:`\sigma_k^2` (and 0), so
:math:`\|e_i\|_2` is non-increasing for every initial error iff
:math:`0 < \beta \le 2/\sigma_{\max}(G)^2`, and every error component in the range of G decays
iff :math:`0 < \beta < 2/\sigma_{\max}(G)^2` (:func:`gradient_step_bound`). For a square
invertible G the same bound is exactly :math:`\rho(T) < 1`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._validation import as_finite_array, as_vector, positive
from ..exceptions import ParameterError, ShapeError
from ..lifting import LiftedSystem, sampled_shift
from ..lifting._lifted_operator import LiftedOperator, MatrixOperator
from ..lifting._lti_lifting import lti_markov_blocks
from ..lifting._trial_map import adjoint_product
from ..lifting._validation import check_shift
from ..model import DiscretePlant
from ._base import (
    LawOperators,
    LawResponse,
    LearningLaw,
    LiftedLaw,
    as_lti_plant,
    check_lifted_plant,
    check_lifted_system,
    check_omega,
    check_same_trial,
    check_trial_signals,
    check_ts_match,
    lift_model,
    lift_model_operator,
    lifted_model_is_plant,
    plant_response,
    shift_of,
)

__all__ = ["GradientLaw", "TimeReversalLaw", "gradient_step_bound", "adjoint_blocks",
           "ReversedExperimentsOperator"]

#: relative mismatch above which a plant's Markov parameters are not the law's lifted model
_MODEL_RTOL = 1e-8


def gradient_step_bound(G) -> float:
    r"""The step-size bound :math:`2/\sigma_{\max}(G)^2` of gradient ILC (dense SVD).

    Monotone convergence of :math:`\|e\|_2` for the exact plant holds for
    :math:`0 < \beta < 2/\sigma_{\max}^2` (Owens, Hätönen & Daley 2009).

    Parameters
    ----------
    G : array_like (N*n_y, N*n_u) or LiftedSystem
        The lifted plant (a LiftedSystem's ``G``).

    Returns
    -------
    float
        :math:`2/\sigma_{\max}(G)^2`.

    Raises
    ------
    ParameterError
        G is zero (or empty), or not finite.
    """
    Gm = G.G if isinstance(G, LiftedSystem) else as_finite_array(G, "G", ndim=2)
    sigma = float(np.linalg.norm(Gm, 2)) if Gm.size else 0.0
    if sigma == 0.0:
        raise ParameterError("G is zero: the output does not depend on the input, so no step "
                             "size learns anything")
    return 2.0 / sigma**2


def adjoint_blocks(G: np.ndarray, n_u: int, n_y: int) -> np.ndarray:
    r"""What one time-reversed experiment per (output i, input j) pair measures, lifted.

    Applying :math:`\mathcal J e_i` on input j and flipping output i gives, summed over the pairs,
    :math:`R(G)` with :math:`R(G)_{(t,j),(\tau,i)} = G_{(N-1-t,\,i),(N-1-\tau,\,j)}`: the
    block-transpose of :math:`\mathcal J G \mathcal J`. For an LTI lifting (block Toeplitz)
    :math:`R(G) = G^\top` exactly; for an LTV lifting it is not.

    Parameters
    ----------
    G : array_like (N*n_y, N*n_u)
        The lifted plant, sample-major (block (t, tau) is ``n_y x n_u``).
    n_u, n_y : int
        Numbers of inputs and outputs per sample (G's block size).

    Returns
    -------
    ndarray (N*n_u, N*n_y)
        :math:`R(G)`.
    """
    G = np.asarray(G)
    N = G.shape[0] // n_y
    flipped = G.reshape(N, n_y, N, n_u)[::-1, :, ::-1, :]      # J G J, blocks (N-1-t, N-1-tau)
    return flipped.transpose(0, 3, 2, 1).reshape(N * n_u, N * n_y)


class ReversedExperimentsOperator(LiftedOperator):
    r""":math:`R(G)` of :func:`adjoint_blocks` from the products of G: what the time-reversed
    experiments measure, never a matrix.

    .. math::

        R(G)\,y = \sum_{i,j} E_j\,\mathcal J\,\big(G\,E_j\mathcal J y_{(i)}\big)_{(i)},\qquad
        R(G)^\top x = \sum_{i,j} E_i\,\mathcal J\,\big(G^\top E_i\mathcal J x_{(j)}\big)_{(j)}

    (:math:`y_{(i)}` channel i of a lifted output, :math:`E_j` placing a signal on channel j,
    :math:`\mathcal J` the time reversal): one product of G per (output, input) pair, as the
    experiments run. :math:`R(G) = G^\top` for a block Toeplitz (LTI) G.

    Parameters
    ----------
    G : LiftedOperator
        The plant ``(N*n_y, N*n_u)``, blocks ``(n_y, n_u)``.
    """

    def __init__(self, G: LiftedOperator):
        if not isinstance(G, LiftedOperator):
            raise ParameterError(f"G must be a LiftedOperator; got {type(G).__name__}")
        super().__init__(G.shape[::-1], G.block[::-1])
        self.G = G

    @staticmethod
    def _reversed_pairs(X, N: int, n_from: int, n_to: int, product) -> np.ndarray:
        """Sum over pairs (c, k) of channel c of X reversed, placed on channel k, through
        ``product``, read at channel c, reversed, onto channel k (both formulas above)."""
        r = X.shape[1]
        Xs = X.reshape(N, n_from, r)
        out = np.zeros((N, n_to, r))
        for c in range(n_from):
            for k in range(n_to):
                V = np.zeros((N, n_to, r))
                V[:, k, :] = Xs[::-1, c, :]
                W = product(V.reshape(N * n_to, r)).reshape(N, n_from, r)
                out[:, k, :] += W[::-1, c, :]
        return out.reshape(N * n_to, r)

    def _matvec(self, Y):
        n_y, n_u = self.G.block
        return self._reversed_pairs(Y, self.N, n_y, n_u, self.G._matvec)

    def _rmatvec(self, X):
        n_y, n_u = self.G.block
        return self._reversed_pairs(X, self.N, n_u, n_y, self.G._rmatvec)

    def norm_upper(self, ord=2):
        r"""G's bound for a SISO plant (:math:`R(G) = \mathcal J G \mathcal J`, the same 2- and
        ∞-norms), else None."""
        if self.block != (1, 1):
            return None
        return self.G.norm_upper(ord)

    def state_form(self, reverse=False):
        r""":math:`R(G) = G^\top` for a block Toeplitz (LTI) G: the transpose of G's form;
        None otherwise."""
        from ..lifting import ToeplitzOperator

        if not isinstance(self.G, ToeplitzOperator):
            return None
        f = self.G.state_form(reverse)
        return None if f is None else f.transpose()

    def describe(self):
        return f"R({self.G.describe()}) (time-reversed experiments)"


def _beta(beta) -> float:
    return positive(beta, "beta (step size)")


def _check_plant_is_model(dp, model: LiftedSystem, s: int) -> None:
    """The frequency response of a model-based law needs the LTI system behind its lifted model."""
    if model.kind != "lti":
        raise ParameterError("the law's model is an LTV lifting: no frequency response (use the "
                             "lifted analysis)")
    if s != model.shift or (dp.n_u, dp.n_y) != (model.n_u, model.n_y):
        raise ParameterError(f"plant (shift {s}, {dp.n_u} inputs, {dp.n_y} outputs) is not the "
                             f"law's model (shift {model.shift}, {model.n_u} inputs, "
                             f"{model.n_y} outputs)")
    check_ts_match(dp.ts, model.ts, "the law's model")
    Ad, Bd, C, D, _ = dp.matrices
    # two LTI systems of orders <= n with the same first 2n + 1 Markov parameters have the
    # same transfer function (Cayley-Hamilton), so these decide it at any N
    n_x = max(Ad.shape[0], getattr(model, "n_x", model.N))
    count = min(model.N, 2 * n_x + 2)
    H = lti_markov_blocks(Ad, Bd, C, D, s, count)
    ref = model.markov_blocks(count)
    if np.max(np.abs(H - ref)) > _MODEL_RTOL * max(np.max(np.abs(ref)), 1e-300):
        raise ParameterError("plant is not the law's model: its Markov parameters differ from "
                             "the lifted model's first block column; pass the LTI system the "
                             "model was lifted from")


@dataclass(frozen=True, eq=False)
class GradientLaw(LearningLaw):
    r"""Gradient ILC :math:`u_{i+1} = u_i + \beta\,\hat G^\top e_i` (module docstring).

    .. math::

        L_1 = \beta\,\hat G^\top,\qquad T = I - \beta\,\hat G^\top G,

    with the model :math:`\hat G` (the lifted model, or the Jacobian of the nonlinear trial map
    along the last trial). For the exact plant the error norm is monotone iff
    :math:`0 < \beta \le 2/\sigma_{\max}(G)^2` (:meth:`step_bound`).

    Reference: D. H. Owens, J. J. Hätönen, S. Daley, "Robust monotone gradient-based
    discrete-time iterative learning control", Int. J. Robust Nonlinear Control 19(6),
    634-661, 2009.

    Parameters
    ----------
    beta : float
        Step size > 0.
    model : LiftedSystem or DiscretePlant
        A LiftedSystem: :math:`\hat G` is its fixed matrix. A DiscretePlant (linear or not):
        :meth:`update` computes :math:`\hat G^\top e` as the CasADi adjoint product along the
        last trial's input (:func:`ilc_analysis.lifting.adjoint_product`, with ``x0``, ``w``,
        ``t0``, ``shift``), and :meth:`lifted` lifts the model on the trial it is given
        (:meth:`lifted_model`: the same Jacobian, along the trial's nominal input), never
        taking that trial's G as the model.
    x0 : array_like (n_x,), optional
        Initial state of the trial the adjoint product is taken along (DiscretePlant model
        only; default zero).
    w : array_like (N, n_x), optional
        Known state disturbance of that trial (DiscretePlant model only; default zero).
    t0 : float
        Time of sample 0 [s] (DiscretePlant model only; default 0).
    shift : int, optional
        The output shift s (DiscretePlant model only; default: the plant's sampled relative
        degree).
    name : str
        Label used in results and reports.
    """

    beta: float
    model: LiftedSystem | DiscretePlant
    x0: object | None = None
    w: object | None = None
    t0: float = 0.0
    shift: int | None = None
    name: str = "gradient"

    def __post_init__(self) -> None:
        object.__setattr__(self, "beta", _beta(self.beta))
        if not isinstance(self.model, LiftedSystem | DiscretePlant):
            raise ParameterError(f"model must be a LiftedSystem or a DiscretePlant; got "
                                 f"{type(self.model).__name__}")

    def step_bound(self, lifted_system=None) -> float:
        r""":math:`2/\sigma_{\max}(G)^2` of ``lifted_system`` (default: the law's lifted model).

        Parameters
        ----------
        lifted_system : LiftedSystem, optional
            The lifted plant to bound; required when the law's model is a DiscretePlant.

        Returns
        -------
        float

        Raises
        ------
        ParameterError
            No lifted system for a plant model, not a LiftedSystem, or G zero.
        """
        if lifted_system is None:
            if not isinstance(self.model, LiftedSystem):
                raise ParameterError("the model is a plant: pass the lifted system to bound")
            lifted_system = self.model
        return gradient_step_bound(check_lifted_system(lifted_system))

    def check(self, lifted_system) -> None:
        self._check_trial(check_lifted_system(lifted_system))

    def _check_trial(self, trial) -> None:
        """The model fits the trial (a LiftedSystem or a lifted plant)."""
        if isinstance(self.model, LiftedSystem):
            check_same_trial(self.model, trial)
        else:
            if (trial.n_u, trial.n_y) != (self.model.n_u, self.model.n_y):
                raise ShapeError(f"the model plant has {self.model.n_u} inputs and "
                                 f"{self.model.n_y} outputs; the lifted system {trial.n_u} and "
                                 f"{trial.n_y}")
            check_ts_match(trial.ts, self.model.ts, "the model plant")

    def _model_shift(self) -> int:
        """The output shift of the law's model: a lifted model's own; for a model plant
        ``shift``, else its sampled relative degree at ``(x0, 0, t0)`` (the one
        :meth:`update`'s adjoint uses)."""
        m = self.model
        if isinstance(m, LiftedSystem):
            return m.shift
        if self.shift is not None:
            return check_shift(self.shift)
        x0 = None if self.x0 is None else as_vector(self.x0, "x0 (the law's initial state)",
                                                    m.n_x)
        return sampled_shift(m, x=x0, t=self.t0)

    def lifted_model(self, lifted_system) -> LiftedSystem:
        r"""The law's model :math:`\hat G` on the trial ``lifted_system``: the lifted model
        itself, or the model plant lifted on that trial (:func:`~.base.lift_model`: its N and
        nominal input, the law's ``x0``, ``w``, ``t0`` and shift), the matrix whose transpose
        :meth:`update`'s adjoint product applies. Never the plant's G.

        Parameters
        ----------
        lifted_system : LiftedSystem
            The trial the law runs on.

        Returns
        -------
        LiftedSystem

        Raises
        ------
        ParameterError, ShapeError
            The law does not fit the trial (:meth:`check`).
        """
        self.check(lifted_system)
        if isinstance(self.model, LiftedSystem):
            return self.model
        return lift_model(self.model, lifted_system, x0=self.x0, w=self.w, t0=self.t0,
                          shift=self._model_shift())

    def lifted(self, lifted_system) -> LiftedLaw:
        r""":math:`L_1 = \beta\hat G^\top` with the law's own model :math:`\hat G`
        (:meth:`lifted_model`), so :math:`T = I - \beta\hat G^\top G` on the plant G of the
        trial.

        Parameters
        ----------
        lifted_system : LiftedSystem
            The trial the law runs on (the plant's G enters T only).

        Returns
        -------
        LiftedLaw
        """
        model = self.lifted_model(lifted_system)
        return LiftedLaw(self.beta * model.G.T, None, None, 0.0,
                         description=self._description(lifted_system))

    def lifted_operators(self, lifted_plant) -> LawOperators:
        r""":math:`L_1 = \beta\hat G^\top` as an operator: the transpose of the lifted model's
        matrix, or of the model plant lifted on the trial as an operator
        (:func:`~ilc_analysis.laws._base.lift_model_operator`: its adjoint products, never a
        matrix).

        Parameters
        ----------
        lifted_plant : LiftedPlant
            The trial the law runs on (the plant's G enters T only).

        Returns
        -------
        LawOperators

        Raises
        ------
        ParameterError, ShapeError
            Not a lifted plant, or the model does not fit the trial.
        """
        lp = check_lifted_plant(lifted_plant)
        self._check_trial(lp)
        if isinstance(self.model, LiftedSystem):
            # the plant's own lifted G (entry for entry): its operator, the same map
            L1: LiftedOperator = lp.G.T if lifted_model_is_plant(self.model, lp) else \
                MatrixOperator(self.model.G.T, (lp.n_u, lp.n_y), "G_model^T")
        else:
            model = lift_model_operator(self.model, lp, x0=self.x0, w=self.w, t0=self.t0,
                                        shift=self._model_shift())
            L1 = model.G.T
        return LawOperators(self.beta * L1, description=self._description(lp))

    def _description(self, trial) -> str:
        return (f"gradient ILC, beta={self.beta:g}, L1 = beta G_model^T with "
                f"{self.model_text()}; N={trial.N}, shift {trial.shift}")

    def model_text(self) -> str:
        m = self.model
        if isinstance(m, LiftedSystem):
            return (f"the law's own lifted model (N={m.N}, shift {m.shift}, ts={m.ts:g}, "
                    f"{m.kind} lifting)")
        kind = "LTI" if m.matrices is not None else "nonlinear"
        return (f"the law's own model plant {m.name!r} ({kind}), lifted on the trial (its N "
                f"and nominal input; the law's x0, w, t0 and shift {self._model_shift()})")

    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        r""":math:`u_i + \beta\hat G^\top e_i` (adjoint product along ``u_i`` for a plant).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial (N the model's trial length for a lifted
            model).
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
        m = self.model
        u, e = check_trial_signals(u_i, e_i, m.n_u, m.n_y)
        check_ts_match(ts, m.ts, "the law's model")
        N = u.shape[0]
        if isinstance(m, LiftedSystem):
            if N != m.N:
                raise ShapeError(f"u_i must have shape ({m.N}, {m.n_u}) (the model's trial); "
                                 f"found shape {u.shape}")
            step = m.G.T @ e.reshape(-1)
        else:
            step = adjoint_product(m, N, e, x0=self.x0, u_nominal=u, w=self.w, t0=self.t0,
                                   shift=self._model_shift())
        return u + self.beta * step.reshape(N, -1)

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r""":math:`L(e^{j\theta}) = \beta\,\hat P(e^{j\theta})^H` of the law's model
        :math:`\hat P` (the shift cancels: :math:`z^s (z^s\hat P)^\top(z^{-1}) =
        \hat P^\top(z^{-1})`).

        A lifted model has no transfer function of its own: ``plant`` must then be the LTI
        system behind it (its Markov parameters are checked), so :math:`\hat P` = ``plant``.
        A model plant (linear) is used itself; ``plant`` (the plant the law runs on) only
        fixes the grid's sample time, and the model must be lifted with the trial's shift.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete-time python-control system
            The LTI plant the law runs on (for a lifted model: the system behind the model,
            whose Markov parameters must be the model's).
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
            The plant is not the law's lifted model (or that model is an LTV lifting), the
            model plant is nonlinear, has another sample time or is lifted with another shift
            than s.
        """
        dp = as_lti_plant(plant)
        s = shift_of(dp, shift)
        if isinstance(self.model, LiftedSystem):
            _check_plant_is_model(dp, self.model, s)
            model = dp
        else:
            model = as_lti_plant(self.model, "the law's model")
            check_ts_match(dp.ts, model.ts, "the law's model")
            if (model.n_u, model.n_y) != (dp.n_u, dp.n_y):
                raise ShapeError(f"the law's model has {model.n_u} inputs and {model.n_y} "
                                 f"outputs; the plant {dp.n_u} and {dp.n_y}")
            if self._model_shift() != s:
                raise ParameterError(f"the law's model is lifted with shift "
                                     f"{self._model_shift()}, the trial has shift {s}: no "
                                     f"frequency response (use the lifted analysis)")
        omega = check_omega(omega, dp.ts)
        P = plant_response(model, omega)
        return LawResponse(omega, self.beta * np.conj(P.transpose(0, 2, 1)), None, None, 0.0,
                           dp.ts)

    def describe(self) -> dict:
        m = self.model
        model = ({"kind": "lifted", "N": m.N, "shift": m.shift, "ts": m.ts, "lifting": m.kind}
                 if isinstance(m, LiftedSystem) else {"kind": "plant", "name": m.name})
        return {"law": "gradient", "name": self.name, "beta": self.beta, "model": model}


@dataclass(frozen=True, eq=False)
class TimeReversalLaw(LearningLaw):
    r"""Model-free gradient ILC: :math:`G^\top e_i` measured by time-reversed experiments.

    For an LTI plant the lifted G is block Toeplitz, so for each output i and input j
    :math:`G_{ij}^\top = \mathcal J G_{ij} \mathcal J` with the flip
    :math:`(\mathcal J v)(k) = v(N-1-k)`. Hence :math:`G^\top e_i` is measured, without a model,
    by applying :math:`\mathcal J e_{i,(i)}` on input j, flipping output i and summing:

    .. math::

        u_{i+1} = u_i + \beta \sum_{i,j} E_j\,\mathcal J\big(y^{(ij)} - d^{(ij)}\big)_{(i)},
        \qquad y^{(ij)} = G\,E_j \mathcal J e_{i,(i)} + d^{(ij)},

    one extra experiment per (output, input) pair: **one** for SISO plants, so each iteration
    runs 2 experiments (:meth:`experiments_per_iteration`). The extra experiment's free response
    :math:`d^{(ij)}` (initial state, repeating disturbance) must be removed: by default the plant
    is taken to start at rest with no disturbance (d = 0); pass ``free_response`` (the measured
    output window of a run with zero input, ``(N, n_y)``) to subtract it, or
    ``free_response="paired"`` to run each extra experiment with :math:`\pm\mathcal J e` and use
    half the difference (d cancels without being known; twice the extra experiments).

    Lifted form: :math:`L_1 = \beta R(G)` (:func:`adjoint_blocks`) of the true plant, which is
    :math:`\beta G^\top` for an LTI plant: the lifted law of :class:`GradientLaw` with the exact
    model. For an LTV lifting the reversed experiments do not give :math:`G^\top`, and
    :meth:`lifted` returns what they do give. The extra experiments run on the plant, so their
    free response :math:`d` (the lifted system's ``d``: initial state, known disturbance)
    enters the measured gradient as far as ``free_response`` does not remove it: the update is
    affine, :math:`u_{i+1} = u_i + \beta R(G)e_i + c` with the constant
    :math:`c` of :meth:`experiment_offset`, kept in ``LiftedLaw.parts['offset']`` (the
    analysis' error floor includes it).

    References: Y. Ye, D. Wang, "Zero phase learning control using reversed time input runs",
    J. Dynamic Systems, Measurement, and Control 127(1), 2005; P. Janssens, G. Pipeleers,
    J. Swevers, "Model-free iterative learning control for LTI systems and experimental
    validation on a linear motor test setup", American Control Conference, 2011.

    Parameters
    ----------
    beta : float
        Step size > 0 (monotone for :math:`\beta < 2/\sigma_{\max}(G)^2`, G unknown: bound it
        by the plant's peak gain, :math:`\sigma_{\max}(G) \le \sup_\theta\bar\sigma P`).
    free_response : None, array_like (N, n_y) or "paired"
        How the extra experiments' free response is removed (see above): None (taken as
        zero), the measured output of a zero-input run, or ``"paired"`` (:math:`\pm` runs).
    name : str
        Label used in results and reports.
    """

    beta: float
    free_response: object | None = None
    name: str = "time-reversal gradient"

    def __post_init__(self) -> None:
        object.__setattr__(self, "beta", _beta(self.beta))
        fr = self.free_response
        if isinstance(fr, str):
            if fr != "paired":
                raise ParameterError(f"free_response must be None, an (N, n_y) array or "
                                     f"'paired'; got {fr!r}")
        elif fr is not None:
            arr = as_finite_array(fr, "free_response (output of a zero-input run, (N, n_y))",
                                  ndim=2)
            arr.setflags(write=False)
            object.__setattr__(self, "free_response", arr)

    @property
    def paired(self) -> bool:
        return isinstance(self.free_response, str)

    def experiments_per_iteration(self, n_u: int = 1, n_y: int = 1) -> int:
        """1 (the trial) + one reversed run per (output, input) pair (two when ``paired``).

        Parameters
        ----------
        n_u, n_y : int
            Numbers of inputs and outputs of the plant (default 1: SISO).

        Returns
        -------
        int
        """
        return 1 + n_u * n_y * (2 if self.paired else 1)

    def check(self, lifted_system) -> None:
        self._check_trial(check_lifted_system(lifted_system))

    def _check_trial(self, trial) -> None:
        if isinstance(self.free_response, np.ndarray) and \
                self.free_response.shape != (trial.N, trial.n_y):
            raise ShapeError(f"free_response must have shape {(trial.N, trial.n_y)}; found "
                             f"shape {self.free_response.shape}")

    def experiment_offset(self, lifted_system) -> np.ndarray:
        r"""The constant the extra experiments' free response adds to each update.

        Experiment (i, j) applies :math:`v = E_j\mathcal J e_{(i)}` and measures
        :math:`y^{(ij)} = Gv + d` (``lifted_system.d``: the free response on the window);
        :meth:`update` subtracts ``free_response`` f (None: f = 0; ``"paired"``: d cancels in
        :math:`\tfrac12(y^{(ij)}_+ - y^{(ij)}_-)`), flips output i and adds it to input j, so

        .. math::

            u_{i+1} = u_i + \beta R(G)\,e_i + c,\qquad
            c(t, j) = \beta\sum_{i=1}^{n_y} (d - f)(N-1-t,\ i)\quad\text{for every input } j,

        and :math:`c = 0` when paired. Random disturbances of a simulated experiment are not
        in ``d`` (their mean over experiments is zero only when they are zero-mean noise).

        Parameters
        ----------
        lifted_system : LiftedSystem
            The plant the experiments run on (its ``d`` and trial).

        Returns
        -------
        ndarray (N*n_u,)
            :math:`c`, lifted sample-major.
        """
        self.check(lifted_system)
        return self._offset(lifted_system)

    def _offset(self, ls) -> np.ndarray:
        """:meth:`experiment_offset` on a checked trial (a LiftedSystem or a lifted plant)."""
        if self.paired:
            return np.zeros(ls.N * ls.n_u)
        rest = np.asarray(ls.d, dtype=float).reshape(ls.N, ls.n_y)
        if isinstance(self.free_response, np.ndarray):
            rest = rest - self.free_response
        per_sample = rest[::-1, :].sum(axis=1)          # sum over outputs i, reversed in time
        return (self.beta * np.repeat(per_sample[:, None], ls.n_u, axis=1)).reshape(-1)

    def lifted(self, lifted_system) -> LiftedLaw:
        self.check(lifted_system)
        ls = lifted_system
        offset = self.experiment_offset(ls)
        return LiftedLaw(self.beta * adjoint_blocks(ls.G, ls.n_u, ls.n_y), None, None, 0.0,
                         description=self._description(ls), parts={"offset": offset})

    def _description(self, trial) -> str:
        return (f"time-reversal (model-free gradient) ILC, beta={self.beta:g}, "
                f"{self.experiments_per_iteration(trial.n_u, trial.n_y)} experiments per "
                f"iteration; N={trial.N}, shift {trial.shift}, {trial.kind} lifting"
                f"{' (not G^T: LTV)' if trial.kind != 'lti' else ''}")

    def lifted_operators(self, lifted_plant) -> LawOperators:
        r""":math:`L_1 = \beta R(G)` of the true plant as an operator: :math:`\beta G^\top`
        (transposed products) on an LTI lifting, where :math:`R(G) = G^\top`; else
        :class:`ReversedExperimentsOperator` (one product of G per (output, input) pair, as
        the experiments run). The offset is :meth:`experiment_offset`'s, from the plant's d.

        Parameters
        ----------
        lifted_plant : LiftedPlant
            The plant the experiments run on (its G, d and trial).

        Returns
        -------
        LawOperators

        Raises
        ------
        ParameterError, ShapeError
            Not a lifted plant, or a ``free_response`` of the wrong shape.
        """
        lp = check_lifted_plant(lifted_plant)
        self._check_trial(lp)
        G = lp.G
        L1 = G.T if lp.kind == "lti" else ReversedExperimentsOperator(G)
        return LawOperators(self.beta * L1, offset=self._offset(lp),
                            description=self._description(lp))

    def extra_inputs(self, e_i, n_u: int) -> list[np.ndarray]:
        r"""The inputs of the extra experiments, ``(N, n_u)`` each, in the order (output i,
        input j) (and, when ``paired``, :math:`+` then :math:`-` for each pair).

        Parameters
        ----------
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        n_u : int
            Number of inputs of the plant.

        Returns
        -------
        list of ndarray (N, n_u)
            Input j of experiment (i, j) is the reversed error channel i, the others zero.
        """
        e = as_finite_array(e_i, "e_i (error of the last trial on the window, (N, n_y))", ndim=2)
        out = []
        for i in range(e.shape[1]):
            for j in range(n_u):
                v = np.zeros((e.shape[0], n_u))
                v[:, j] = e[::-1, i]
                out.extend([v, -v] if self.paired else [v])
        return out

    def update(self, u_i, e_i, ts: float, *, experiment: Callable | None = None,
               extra_outputs=None) -> np.ndarray:
        r""":math:`u_i + \beta\,\widehat{G^\top e_i}` from the extra experiments.

        Give either ``experiment`` (a function of an input ``(N, n_u)`` returning the measured
        output window ``(N, n_y)``; it is called :meth:`experiments_per_iteration` - 1 times
        with :meth:`extra_inputs`) or ``extra_outputs`` (those outputs, measured, in the same
        order).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        ts : float
            Sample time [s] (> 0).
        experiment : callable, optional
            Runs the plant: input ``(N, n_u)`` -> measured output window ``(N, n_y)``.
        extra_outputs : sequence of array_like (N, n_y), optional
            The measured outputs of the extra experiments, in the order of
            :meth:`extra_inputs`.

        Returns
        -------
        ndarray (N, n_u)

        Raises
        ------
        ParameterError
            Neither or both of ``experiment`` and ``extra_outputs``, or ``experiment`` not
            callable.
        ShapeError
            The wrong number or shape of outputs, or a ``free_response`` of the wrong shape.
        """
        u, e = check_trial_signals(u_i, e_i)
        positive(ts, "ts (sample time)")
        N, n_u = u.shape
        n_y = e.shape[1]
        inputs = self.extra_inputs(e, n_u)
        if (experiment is None) == (extra_outputs is None):
            raise ParameterError("give exactly one of experiment (a callable running the plant) "
                                 "or extra_outputs (the measured outputs of extra_inputs(e_i))")
        if experiment is not None:
            if not callable(experiment):
                raise ParameterError("experiment must be callable: input (N, n_u) -> output "
                                     "(N, n_y)")
            outputs = [experiment(v) for v in inputs]
        else:
            outputs = list(extra_outputs)
        if len(outputs) != len(inputs):
            raise ShapeError(f"extra_outputs must hold {len(inputs)} outputs (one per extra "
                             f"experiment); found {len(outputs)}")
        outputs = [as_finite_array(y, f"extra output {k}", shape=(N, n_y))
                   for k, y in enumerate(outputs)]
        if isinstance(self.free_response, np.ndarray):
            if self.free_response.shape != (N, n_y):
                raise ShapeError(f"free_response must have shape {(N, n_y)}; found shape "
                                 f"{self.free_response.shape}")
            outputs = [y - self.free_response for y in outputs]
        if self.paired:
            outputs = [0.5 * (plus - minus) for plus, minus in zip(outputs[::2], outputs[1::2],
                                                                    strict=True)]
        grad = np.zeros((N, n_u))
        k = 0
        for i in range(n_y):
            for j in range(n_u):
                grad[:, j] += outputs[k][::-1, i]
                k += 1
        return u + self.beta * grad

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r""":math:`L(e^{j\theta}) = \beta P(e^{j\theta})^H` of the (true, LTI) plant.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete-time python-control system
            The true LTI plant the reversed experiments run on.
        omega : array_like (n_w,)
            Angular frequencies [rad/s] in :math:`[0, \pi/T_s]`.
        shift : int, optional
            Not used: the shift cancels in :math:`P^H` (accepted for the interface).

        Returns
        -------
        LawResponse
        """
        dp = as_lti_plant(plant)
        omega = check_omega(omega, dp.ts)
        P = plant_response(dp, omega)
        return LawResponse(omega, self.beta * np.conj(P.transpose(0, 2, 1)), None, None, 0.0,
                           dp.ts)

    def describe(self) -> dict:
        out = {"law": "time_reversal", "name": self.name, "beta": self.beta}
        if self.paired:
            out["free_response"] = "paired"
        elif self.free_response is not None:
            out["free_response"] = np.asarray(self.free_response).tolist()
        return out
