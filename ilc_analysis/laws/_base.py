r"""The one learning-law interface: every law's lifted update, frequency response and data update.

Every learning law of this package is a :class:`LearningLaw`. On a lifted trial
:math:`y = G u + d` (:class:`~ilc_analysis.lifting.LiftedSystem`, index convention of
:mod:`ilc_analysis.laws`: input :math:`u(0..N-1)`, error window :math:`e(j) = y_d(j+s) - y(j+s)`)
its lifted form (:class:`LiftedLaw`) is

.. math::

    u_{i+1} = Q\,\big[(1-a)\,u_i + a\,u_0 + L_1 e_i\big] + L_2\, e_{i+1},

with the previous-trial learning matrix :math:`L_1` (``N*n_u x N*n_y``, may be non-causal), the
current-trial feedback :math:`L_2` (causal: it acts inside the trial), the lifted Q-filter and the
forgetting factor a. Substituting :math:`e = r - G u`, :math:`r = y_d - d`:

.. math::

    u_{i+1} - u_\star = T\,(u_i - u_\star),\qquad
    T = S\,Q\,\big((1-a)I - L_1 G\big),\qquad S = (I + L_2 G)^{-1},

for the fixed point :math:`u_\star` (constant forgetting). :meth:`LiftedLaw.operator` is the one
place T is built for these laws as a matrix; it delegates to
:func:`ilc_analysis.lifting.learning_operator` (which also checks that :math:`L_2` is causal).
The same form with operators instead of matrices is :class:`LawOperators`
(:meth:`LearningLaw.lifted_operators` on a lifted plant whose G is a
:class:`~ilc_analysis.lifting.LiftedOperator`); :meth:`LawOperators.operator` is the one place T
is built as an operator, never an N x N matrix.

The frequency response (:class:`LawResponse`, LTI laws on LTI plants only) is given for the error
:math:`e(t) = y_d(t) - y(t)` at the plant's own time (the shift s folded into :math:`L`), the
convention of :mod:`ilc_analysis.analysis._frequency`:
:math:`T(e^{j\theta}) = S\,Q\,((1-a)I - L P)` with :math:`S = (I + L_2P)^{-1}`.
"""

from __future__ import annotations

import abc
import numbers
from dataclasses import dataclass, field
from types import SimpleNamespace

import control
import numpy as np
import scipy.linalg
import scipy.sparse

from .._validation import as_finite_array
from ..exceptions import ParameterError, ShapeError
from ..lifting import LiftedSystem, learning_operator
from ..lifting._lifted_operator import IdentityOperator, LiftedOperator, MatrixOperator
from ..lifting._operators import forgetting_matrix
from ..model import DiscretePlant
from ..problem._problem import is_problem

__all__ = ["as_problem", "LiftedLaw", "LawOperators", "LearningLaw", "LawResponse",
           "as_lti_plant", "plant_response", "check_lifted_plant", "lifted_model_is_plant",
           "check_lifted_system", "check_trial_signals", "check_omega", "lift_model",
           "NO_SEPARATE_MODEL"]

#: Relative tolerance on sample times that must agree (filter dt against the trial's ts).
TS_RTOL = 1e-9
#: :meth:`LearningLaw.model_text` of a law that carries no plant model of its own.
NO_SEPARATE_MODEL = ("no separate model: the law's learning matrices are its own gains or "
                     "filters, or measured on the problem's plant (only the problem's plant "
                     "enters T)")


# ---------------------------------------------------------------------------------------------
# the lifted form
# ---------------------------------------------------------------------------------------------
def _matrix(M, name: str, shape: tuple[int, int]):
    """A finite dense or sparse matrix of the given shape (sparse stays sparse, CSR)."""
    if scipy.sparse.issparse(M):
        if M.shape != shape:
            raise ShapeError(f"{name} must have shape {shape}; found shape {M.shape}")
        M = scipy.sparse.csr_array(M)
        if not np.all(np.isfinite(M.data)):
            raise ParameterError(f"{name} must be finite; it contains NaN or inf")
        return M
    arr = np.array(as_finite_array(M, name, shape=shape))
    arr.setflags(write=False)
    return arr


def _forgetting_value(a) -> float | tuple[float, float]:
    if isinstance(a, tuple):
        if len(a) != 2:
            raise ParameterError(f"a must be a number in [0, 1) or bounds (lo, hi); got {a!r}")
        lo, hi = (_unit(v, "a (forgetting bounds)") for v in a)
        if lo > hi:
            raise ParameterError(f"a (forgetting bounds) must satisfy lo <= hi; got {a!r}")
        return (lo, hi)
    return _unit(a, "a (forgetting factor)")


def _unit(v, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not np.isfinite(float(v)) \
            or not 0.0 <= float(v) < 1.0:
        raise ParameterError(f"{name} must be a real number in [0, 1); got {v!r}")
    return float(v)


def _forgetting_values(a) -> tuple[float, ...]:
    if isinstance(a, tuple):
        lo, hi = a
        return (lo,) if lo == hi else (lo, hi)
    return (a,)


def _resolve_forgetting(law_a, a, q: int):
    """The forgetting used on a trial of ``q`` lifted inputs: the law's constant ``law_a``
    when ``a`` is None, else ``a`` (a float, or per-sample factors ``(N,)``, N dividing q)
    within the law's value or range ``law_a``."""
    lo, hi = law_a if isinstance(law_a, tuple) else (law_a, law_a)
    if a is None:
        if isinstance(law_a, tuple):
            raise ParameterError(
                f"this law has a variable forgetting factor in [{lo:g}, {hi:g}]: pass a (a "
                f"number or per-sample factors (N,)) within those bounds")
        return law_a
    value: float | np.ndarray
    if np.ndim(a) == 0:
        value = _unit(a, "a (forgetting factor)")
        values = np.array([value])
    else:
        value = as_finite_array(a, "a (per-sample forgetting factors)", ndim=1)
        if value.size == 0 or q % value.size:
            raise ShapeError(f"a (per-sample forgetting factors) must have shape (N,) with "
                             f"N dividing {q}; found shape {value.shape}")
        values = value
    tol = 1e-12
    if np.any(values < lo - tol) or np.any(values > hi + tol):
        raise ParameterError(f"a must lie within this law's forgetting range [{lo:g}, {hi:g}]; "
                             f"got values in [{values.min():g}, {values.max():g}]")
    return value


class _LiftedFacts:
    """What the lifted form of a law says about its size and forgetting, whether its matrices
    are arrays (:class:`LiftedLaw`) or operators (:class:`LawOperators`)."""

    L1: object
    a: float | tuple[float, float]

    @property
    def shape(self) -> tuple[int, int]:
        """``(N*n_u, N*n_y)``, the shape of L1 (the transpose of G's)."""
        return self.L1.shape  # type: ignore[attr-defined]

    @property
    def variable_forgetting(self) -> bool:
        """True when ``a`` is a range (a variable factor): ``operator`` then needs ``a``."""
        return isinstance(self.a, tuple)

    def forgetting_values(self) -> tuple[float, ...]:
        """The distinct forgetting values a sup over the factor is taken at: ``(a,)``, or the
        ends ``(lo, hi)`` of a variable factor's range (as
        :meth:`~ilc_analysis.laws._forgetting.VariableForgetting.values`)."""
        return _forgetting_values(self.a)


@dataclass(frozen=True, eq=False)
class LiftedLaw(_LiftedFacts):
    r"""The lifted form of a learning law on one trial (module docstring).

    .. math::

        u_{i+1} = Q\,[(1-a)u_i + a u_0 + L_1 e_i] + L_2 e_{i+1},\qquad
        T = (I + L_2G)^{-1} Q\,((1-a)I - L_1G).

    Built by :meth:`LearningLaw.lifted`. Dense arrays are read-only; sparse ones stay sparse.
    """

    L1: np.ndarray | scipy.sparse.sparray
    """previous-trial learning matrix ``(N*n_u, N*n_y)``, dense or sparse (finite; stored as a
    read-only ndarray or a CSR array); may be non-causal"""
    L2: np.ndarray | scipy.sparse.sparray | None = None
    """current-trial feedback ``(N*n_u, N*n_y)`` (causal), or None (no feedback in the trial)"""
    Q: np.ndarray | scipy.sparse.sparray | None = None
    """lifted Q-filter ``(N*n_u, N*n_u)``, or None (identity)"""
    a: float | tuple[float, float] = 0.0
    """forgetting factor in [0, 1), or bounds ``(lo, hi)`` of a variable factor"""
    description: str = ""
    """what this is (law, parameters, what it was lifted on)"""
    parts: dict = field(default_factory=dict)
    """law-specific extras (e.g. the norm-optimal ``L_u``), plain values or arrays; ``'offset'``
    ``(N*n_u,)``: a constant :math:`c` the law adds to every update (after Q, before the
    current-trial feedback: u_{i+1} = S [Q(...) + c + L2 r]), e.g. the free response
    of the time-reversal law's experiments"""

    def __post_init__(self) -> None:
        if self.L1 is None:
            raise ParameterError("L1 (previous-trial learning matrix) is required; use a zero "
                                 "matrix for a law without previous-trial learning")
        shape = tuple(np.shape(self.L1)) if not scipy.sparse.issparse(self.L1) else self.L1.shape
        if len(shape) != 2:
            raise ShapeError(f"L1 must have shape (N*n_u, N*n_y); found shape {shape}")
        q, p = shape
        object.__setattr__(self, "L1", _matrix(self.L1, "L1", (q, p)))
        if self.L2 is not None:
            object.__setattr__(self, "L2", _matrix(self.L2, "L2", (q, p)))
        if self.Q is not None:
            object.__setattr__(self, "Q", _matrix(self.Q, "Q (lifted Q-filter)", (q, q)))
        object.__setattr__(self, "a", _forgetting_value(self.a))
        if not isinstance(self.description, str):
            raise ParameterError(f"description must be a string; got {self.description!r}")

    def _resolve_a(self, a):
        """The forgetting used: a float, or per-sample factors ``(N,)`` within the bounds."""
        return _resolve_forgetting(self.a, a, self.shape[0])

    def _forgetting_matrix(self, a):
        """:math:`A` as accepted by :func:`learning_operator`: a float or a sparse diagonal."""
        if np.ndim(a) == 0:
            return float(a)
        return forgetting_matrix(a, self.shape[0] // a.size)

    # the one place T is built -------------------------------------------------------------------
    def operator(self, G, a=None) -> np.ndarray:
        r"""The trial-to-trial operator :math:`T = S\,Q\,((1-a)I - L_1G)`, dense.

        Delegates to :func:`ilc_analysis.lifting.learning_operator`, which builds
        :math:`(I + L_2G)^{-1}Q(I - A - L_1G)` (the one place T is built).

        Parameters
        ----------
        G : ndarray or LiftedSystem
            The plant the law runs on, ``(N*n_y, N*n_u)`` (it need not be the law's model).
        a : float or array_like (N,), optional
            The forgetting factor; required for a variable factor (within its bounds),
            defaults to the law's constant ``a``.

        Raises
        ------
        ShapeError
            G not ``(N*n_y, N*n_u)`` for this law.
        ParameterError
            A non-causal L2, or ``a`` missing / outside the law's range.
        """
        Gm = G.G if isinstance(G, LiftedSystem) else as_finite_array(G, "G", ndim=2)
        if Gm.shape != self.shape[::-1]:
            raise ShapeError(f"G must have shape {self.shape[::-1]} (N*n_y, N*n_u) for this law; "
                             f"found shape {Gm.shape}")
        A = self._forgetting_matrix(self._resolve_a(a))
        return learning_operator(Gm, self.L1, self.L2, A, Q=self.Q)

    def next_input(self, G, u_i, r, u0=None, a=None) -> np.ndarray:
        r"""One trial of the lifted law on a linear plant :math:`e = r - Gu`, lifted vectors.

        .. math::

            u_{i+1} = S\,\big[Q\big((1-a)u_i + a u_0 + L_1(r - Gu_i)\big) + c + L_2 r\big],

        the affine map whose linear part is :meth:`operator` (c: ``parts['offset']``, else 0).

        Parameters
        ----------
        G : ndarray or LiftedSystem
            The plant the law runs on, ``(N*n_y, N*n_u)`` (it need not be the law's model).
        u_i : array_like (N*n_u,)
            The lifted input of trial i.
        r : array_like (N*n_y,)
            :math:`r = y_d - d`, the reference minus the plant's free response on the window.
        u0 : array_like (N*n_u,), optional
            The input the forgetting pulls towards; default zero.
        a : float or array_like (N,), optional
            The forgetting factor, as for :meth:`operator`.

        Returns
        -------
        ndarray (N*n_u,)
            The lifted input :math:`u_{i+1}`.

        Raises
        ------
        ShapeError
            G, ``u_i``, ``r`` or ``u0`` of the wrong shape for this law.
        ParameterError
            A non-finite vector, or ``a`` missing / outside the law's range.
        """
        Gm = G.G if isinstance(G, LiftedSystem) else as_finite_array(G, "G", ndim=2)
        q, p = self.shape
        if Gm.shape != (p, q):
            raise ShapeError(f"G must have shape {(p, q)} (N*n_y, N*n_u) for this law; found "
                             f"shape {Gm.shape}")
        u_i = as_finite_array(u_i, "u_i", shape=(q,))
        r = as_finite_array(r, "r", shape=(p,))
        u0 = np.zeros(q) if u0 is None else as_finite_array(u0, "u0", shape=(q,))
        a = self._resolve_a(a)
        a_full = a if np.ndim(a) == 0 else np.repeat(a, q // a.size)
        v = (1.0 - a_full) * u_i + a_full * u0 + self.L1 @ (r - Gm @ u_i)
        if self.Q is not None:
            v = self.Q @ v
        offset = self.parts.get("offset")
        if offset is not None:
            v = v + np.asarray(offset, dtype=float)
        if self.L2 is None:
            return np.asarray(v)
        loop = np.eye(q) + np.asarray(self.L2 @ Gm)
        return scipy.linalg.solve_triangular(loop, v + self.L2 @ r, lower=True,
                                             unit_diagonal=True, check_finite=False)

    def __repr__(self) -> str:
        q, p = self.shape
        extras = [f"L2 {'yes' if self.L2 is not None else 'none'}",
                  f"Q {'yes' if self.Q is not None else 'none'}", f"a={self.a}"]
        return f"<LiftedLaw {self.description!r}: L1 {q}x{p}, {', '.join(extras)}>"


# ---------------------------------------------------------------------------------------------
# the lifted form as operators
# ---------------------------------------------------------------------------------------------
def _law_operator(op, name: str, shape: tuple[int, int], block: tuple[int, int]):
    if not isinstance(op, LiftedOperator):
        raise ParameterError(f"{name} must be a LiftedOperator (ilc_analysis.lifting); got "
                             f"{type(op).__name__}")
    if op.shape != shape or op.block != block:
        raise ShapeError(f"{name} must have shape {shape} with blocks {block}; found shape "
                         f"{op.shape} with blocks {op.block}")
    return op


@dataclass(frozen=True, eq=False)
class LawOperators(_LiftedFacts):
    r"""The lifted form of a learning law as operators (:class:`LiftedLaw` without matrices).

    .. math::

        u_{i+1} = S\,\big[Q\,[(1-a)u_i + a u_0 + L_1 e_i] + c + L_2 r\big],\qquad
        T = S\,Q\,\big((1-a)I - L_1G\big),\qquad S = (I + L_2G)^{-1},

    with L1, L2 ``(N*n_u, N*n_y)`` (blocks ``(n_u, n_y)``; L2 causal), Q ``(N*n_u, N*n_u)``
    (blocks ``(n_u, n_u)``) :class:`~ilc_analysis.lifting.LiftedOperator` s and the constant
    offset c. Built by :meth:`LearningLaw.lifted_operators`; :meth:`operator` is the one place
    T is built as an operator (:meth:`LiftedLaw.operator` the dense one).
    """

    L1: LiftedOperator
    """previous-trial learning operator ``(N*n_u, N*n_y)``, blocks ``(n_u, n_y)``"""
    L2: LiftedOperator | None = None
    """current-trial feedback (block lower-triangular: causal), or None"""
    Q: LiftedOperator | None = None
    """lifted Q-filter ``(N*n_u, N*n_u)``, or None (identity)"""
    a: float | tuple[float, float] = 0.0
    """forgetting factor in [0, 1), or bounds ``(lo, hi)`` of a variable factor"""
    offset: np.ndarray | None = None
    """constant c ``(N*n_u,)`` every update adds (``LiftedLaw.parts['offset']``), or None"""
    description: str = ""
    """what this is (law, parameters, what it was lifted on)"""
    closed_form: LiftedOperator | None = None
    r"""T in closed form on the plant ``closed_form_plant`` (the law's model is that plant:
    norm-optimal ILC with the exact model has :math:`T = (G^\top W_eG + W_\Delta + W_u)^{-1}
    W_\Delta`), the same map as the composition, with the structure (symmetry, proven bounds)
    the composition loses; None: none"""
    closed_form_plant: LiftedOperator | None = None
    """the plant operator (the object itself) :attr:`closed_form` is T on"""

    def __post_init__(self) -> None:
        if (self.closed_form is None) != (self.closed_form_plant is None):
            raise ParameterError("closed_form and closed_form_plant go together")
        if not isinstance(self.L1, LiftedOperator):
            raise ParameterError(f"L1 must be a LiftedOperator (ilc_analysis.lifting); got "
                                 f"{type(self.L1).__name__}")
        q, p = self.L1.shape
        n_u, n_y = self.L1.block
        if self.L2 is not None:
            _law_operator(self.L2, "L2", (q, p), (n_u, n_y))
            if not self.L2.lower_triangular:
                raise ParameterError(f"L2 must be causal (block lower-triangular): u(k) may use "
                                     f"the current-trial error up to sample k only; "
                                     f"{self.L2.describe()} is not known to be")
        if self.Q is not None:
            _law_operator(self.Q, "Q (lifted Q-filter)", (q, q), (n_u, n_u))
        object.__setattr__(self, "a", _forgetting_value(self.a))
        if self.offset is not None:
            offset = np.array(as_finite_array(self.offset, "offset", shape=(q,)))
            offset.setflags(write=False)
            object.__setattr__(self, "offset", offset)
        if not isinstance(self.description, str):
            raise ParameterError(f"description must be a string; got {self.description!r}")

    @classmethod
    def from_lifted(cls, lifted_law: LiftedLaw, n_u: int, n_y: int) -> LawOperators:
        """A law's :class:`LiftedLaw` matrices wrapped as
        :class:`~ilc_analysis.lifting.MatrixOperator` s (dense stay dense, sparse sparse).

        Parameters
        ----------
        lifted_law : LiftedLaw
            The matrices.
        n_u, n_y : int
            Inputs and outputs per sample (the blocks ``(n_u, n_y)`` of L1, L2).

        Returns
        -------
        LawOperators
        """
        if not isinstance(lifted_law, LiftedLaw):
            raise ParameterError(f"lifted_law must be a LiftedLaw; got "
                                 f"{type(lifted_law).__name__}")
        block = (n_u, n_y)
        L2 = lifted_law.L2
        return cls(MatrixOperator(lifted_law.L1, block, "L1"),
                   None if L2 is None else MatrixOperator(L2, block, "L2"),
                   None if lifted_law.Q is None else MatrixOperator(lifted_law.Q, (n_u, n_u),
                                                                    "Q"),
                   lifted_law.a, lifted_law.parts.get("offset"), lifted_law.description)

    @property
    def block(self) -> tuple[int, int]:
        """``(n_u, n_y)``."""
        return self.L1.block

    # the one place T is built as an operator ------------------------------------------------
    def operator(self, G: LiftedOperator, a=None) -> LiftedOperator:
        r"""The trial-to-trial operator :math:`T = S\,Q\,((1-a)I - L_1G)` as a
        :class:`~ilc_analysis.lifting.LiftedOperator`, never a matrix.

        :math:`S = (I + L_2G)^{-1}` is
        :func:`ilc_analysis.lifting._ltv_operator.closed_loop_inverse` (omitted without L2);
        a per-sample forgetting factor enters as the diagonal :math:`I - A`
        (:func:`~ilc_analysis.lifting._operators.forgetting_matrix`).

        Parameters
        ----------
        G : LiftedOperator
            The plant the law runs on, ``(N*n_y, N*n_u)`` with blocks ``(n_y, n_u)`` (it need
            not be the law's model).
        a : float or array_like (N,), optional
            The forgetting factor; required for a variable factor (within its bounds),
            defaults to the law's constant ``a``.

        Returns
        -------
        LiftedOperator
            T, ``(N*n_u, N*n_u)`` with blocks ``(n_u, n_u)``.

        Raises
        ------
        ParameterError
            G not a LiftedOperator, or ``a`` missing / outside the law's range.
        ShapeError
            G not ``(N*n_y, N*n_u)`` with blocks ``(n_y, n_u)`` for this law.
        """
        q, p = self.shape
        n_u, n_y = self.block
        G = _law_operator(G, "G", (p, q), (n_y, n_u))
        a = _resolve_forgetting(self.a, a, q)
        if self.closed_form is not None and G is self.closed_form_plant and np.ndim(a) == 0 \
                and float(a) == 0.0 and self.L2 is None:
            return self.closed_form
        L1G = self.L1 @ G
        if np.ndim(a) == 0:
            T = (1.0 - float(a)) * IdentityOperator(q, n_u) - L1G
        else:
            keep = scipy.sparse.eye_array(q, format="csr") - forgetting_matrix(a, q // a.size)
            T = MatrixOperator(keep, (n_u, n_u), "(I - A)") - L1G
        if self.Q is not None:
            T = self.Q @ T
        if self.L2 is not None:
            from ..lifting._ltv_operator import closed_loop_inverse

            T = closed_loop_inverse(self.L2, G) @ T
        return T

    def sq_operator(self, G: LiftedOperator) -> LiftedOperator:
        r""":math:`SQ`, the rate at which T changes with the forgetting factor:
        :math:`T(a) - T(a') = (a' - a)\,SQ` (:meth:`operator` without learning).

        Parameters
        ----------
        G : LiftedOperator
            The plant the law runs on (as for :meth:`operator`).

        Returns
        -------
        LiftedOperator
            ``(N*n_u, N*n_u)`` with blocks ``(n_u, n_u)``.
        """
        q, p = self.shape
        n_u, n_y = self.block
        G = _law_operator(G, "G", (p, q), (n_y, n_u))
        out: LiftedOperator = IdentityOperator(q, n_u) if self.Q is None else self.Q
        if self.L2 is not None:
            from ..lifting._ltv_operator import closed_loop_inverse

            out = closed_loop_inverse(self.L2, G) @ out
        return out

    def __repr__(self) -> str:
        q, p = self.shape
        extras = [f"L2 {'yes' if self.L2 is not None else 'none'}",
                  f"Q {'yes' if self.Q is not None else 'none'}", f"a={self.a}"]
        return f"<LawOperators {self.description!r}: L1 {q}x{p}, {', '.join(extras)}>"


# ---------------------------------------------------------------------------------------------
# the frequency response
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LawResponse:
    r"""A law's frequency response on the grid ``omega`` [rad/s] (module docstring).

    Arrays are complex with the frequency first: ``L`` and ``L2`` ``(n_w, n_u, n_y)`` (acting on
    the error at the plant's time, the shift folded in), ``Q`` ``(n_w, n_u, n_u)``.
    """

    omega: np.ndarray = field(repr=False)
    """angular frequencies [rad/s]"""
    L: np.ndarray = field(repr=False)
    r"""previous-trial learning filter :math:`L(e^{j\omega T_s})`"""
    Q: np.ndarray | None = field(default=None, repr=False)
    """Q-filter response, or None (identity)"""
    L2: np.ndarray | None = field(default=None, repr=False)
    """current-trial feedback response, or None"""
    a: float | tuple[float, float] = 0.0
    """forgetting factor (or its bounds)"""
    ts: float = 1.0
    """sample time [s]"""

    def operator(self, P, a=None) -> np.ndarray:
        r""":math:`T(e^{j\theta}) = S\,Q\,((1-a)I - LP)`, :math:`S = (I + L_2P)^{-1}`, at every
        frequency of the grid.

        Parameters
        ----------
        P : array_like (n_w, n_y, n_u), complex
            The plant's frequency response on this grid (:func:`plant_response`).
        a : float, optional
            The forgetting factor in [0, 1); required when the law's forgetting is variable
            (given as bounds), defaults to the law's constant ``a``.

        Returns
        -------
        ndarray (n_w, n_u, n_u), complex
            :math:`T(e^{j\omega T_s})` per frequency.

        Raises
        ------
        ShapeError
            ``P`` not ``(n_w, n_y, n_u)`` for this response.
        ParameterError
            ``a`` missing for a variable factor, or not a number in [0, 1).
        """
        P = np.asarray(P)
        n_w, n_u, n_y = self.L.shape
        if P.shape != (n_w, n_y, n_u):
            raise ShapeError(f"P must have shape {(n_w, n_y, n_u)} (frequencies, outputs, "
                             f"inputs); found shape {P.shape}")
        if a is None:
            if isinstance(self.a, tuple):
                raise ParameterError(f"variable forgetting in {self.a}: pass a")
            a = self.a
        a = _unit(a, "a (forgetting factor)")
        eye = np.eye(n_u)
        T = (1.0 - a) * eye - self.L @ P
        if self.Q is not None:
            T = self.Q @ T
        if self.L2 is not None:
            T = np.linalg.solve(eye + self.L2 @ P, T)
        return T


def as_lti_plant(plant, name: str = "plant") -> DiscretePlant:
    """A linear :class:`DiscretePlant` from a DiscretePlant or a discrete python-control LTI."""
    if isinstance(plant, control.LTI) and not isinstance(plant, control.StateSpace):
        plant = control.ss(plant)
    if isinstance(plant, control.StateSpace):
        if not plant.isdtime(strict=True) or plant.dt is True:
            raise ParameterError(f"{name} must be discrete-time with a numeric sample time; got "
                                 f"dt = {plant.dt!r}")
        plant = DiscretePlant.from_statespace(plant)
    if not isinstance(plant, DiscretePlant):
        raise ParameterError(f"{name} must be a DiscretePlant or a discrete-time python-control "
                             f"system; got {type(plant).__name__}")
    if plant.matrices is None:
        raise ParameterError(f"{name} ({plant.name}) is nonlinear: a frequency response needs an "
                             f"LTI plant; linearise it first (or use the lifted analysis)")
    return plant


def check_omega(omega, ts: float) -> np.ndarray:
    """Angular frequencies [rad/s]: finite, 1-D, in [0, π/ts]."""
    omega = as_finite_array(omega, "omega (rad/s)", ndim=1)
    if omega.size == 0 or np.any(omega < 0) or np.any(omega * ts > np.pi * (1 + 1e-12)):
        raise ParameterError(f"omega must be non-empty with values in [0, pi/ts] = "
                             f"[0, {np.pi / ts:g}] rad/s")
    return omega


def plant_response(plant, omega) -> np.ndarray:
    r""":math:`P(e^{j\omega T_s}) = C(zI - A_d)^{-1}B_d + D`, ``(n_w, n_y, n_u)`` complex.

    Parameters
    ----------
    plant : DiscretePlant (linear) or discrete-time python-control system
        The LTI plant (its sample time :math:`T_s` is used).
    omega : array_like (n_w,)
        Angular frequencies [rad/s] in :math:`[0, \pi/T_s]`.

    Returns
    -------
    ndarray (n_w, n_y, n_u), complex

    Raises
    ------
    ParameterError
        A nonlinear or continuous-time plant, ``omega`` empty or outside
        :math:`[0, \pi/T_s]`, or a plant pole on the unit circle at a frequency of the grid.
    """
    dp = as_lti_plant(plant)
    Ad, Bd, C, D, _ = dp.matrices
    omega = check_omega(omega, dp.ts)
    z = np.exp(1j * omega * dp.ts)
    n_x = Ad.shape[0]
    if n_x and (not np.any(np.triu(Ad)) or not np.any(np.tril(Ad))):
        return _nilpotent_response(Ad, Bd, C, D, z)
    # the batched solve holds one n_x x n_x matrix per frequency: in chunks of bounded memory
    chunk = max(1, RESPONSE_CHUNK_BYTES // (16 * max(n_x, 1) ** 2))
    out = np.empty((z.size, *D.shape), dtype=complex)
    for start in range(0, z.size, chunk):
        zc = z[start:start + chunk]
        try:
            X = np.linalg.solve(zc[:, None, None] * np.eye(n_x) - Ad,
                                np.broadcast_to(Bd, (zc.size, *Bd.shape)))
        except np.linalg.LinAlgError as exc:
            raise ParameterError("the plant has a pole on the unit circle at a frequency of "
                                 "omega; move the grid off it") from exc
        out[start:start + chunk] = C @ X + D
    return out


#: Memory the batched solve of :func:`plant_response` may hold at once (one chunk of
#: frequencies): a 600-state model on 2 000 frequencies needed 11 GiB in one solve.
RESPONSE_CHUNK_BYTES = 1 << 27


def _nilpotent_response(Ad, Bd, C, D, z) -> np.ndarray:
    r"""The response of a model whose :math:`A_d` is strictly triangular (nilpotent,
    :math:`A_d^{n_x} = 0`; e.g. the shift register of an identified FIR model): the finite sum

    .. math::

        P(z) = D + \sum_{k=1}^{n_x} C A_d^{k-1} B_d\, z^{-k},

    exact, in :math:`O(n_x^2 n_u)` per Markov parameter instead of a solve per frequency."""
    n_x = Ad.shape[0]
    markov = np.empty((n_x, *D.shape))
    V = np.array(Bd, dtype=float)
    for k in range(n_x):
        markov[k] = C @ V
        V = Ad @ V
    powers = z[:, None] ** -np.arange(1, n_x + 1)[None, :]
    flat = powers @ markov.reshape(n_x, -1)
    return flat.reshape(z.size, *D.shape) + D


# ---------------------------------------------------------------------------------------------
# shared argument checks
# ---------------------------------------------------------------------------------------------
def check_lifted_system(lifted_system, name: str = "lifted_system") -> LiftedSystem:
    """``lifted_system`` must be a :class:`~ilc_analysis.lifting.LiftedSystem`."""
    if not isinstance(lifted_system, LiftedSystem):
        raise ParameterError(f"{name} must be a LiftedSystem (ilc_analysis.lifting.lift); got "
                             f"{type(lifted_system).__name__}")
    return lifted_system


def lifted_model_is_plant(model: LiftedSystem, lifted_plant) -> bool:
    r"""Whether a law's dense lifted model is the lifted plant's own G, entry for entry: an
    LTI lifting whose matrix is exactly the block lower-triangular Toeplitz matrix of the
    plant operator's blocks (the same trial). A law may then use the plant's operator (and
    its state-space realisation) for its model: the same linear map, never formed.

    Parameters
    ----------
    model : LiftedSystem
        The law's model.
    lifted_plant : LiftedPlant
        The plant the law runs on.
    """
    from ..lifting._block_convolution import toeplitz_from_sparse

    G = getattr(lifted_plant, "G", None)
    if not isinstance(model, LiftedSystem) or not isinstance(G, LiftedOperator) \
            or model.kind != "lti" or getattr(lifted_plant, "kind", None) != "lti" \
            or (model.N, model.n_u, model.n_y, model.shift) != (
                lifted_plant.N, lifted_plant.n_u, lifted_plant.n_y, lifted_plant.shift):
        return False
    blocks = G.toeplitz_blocks()
    if blocks is None:
        return False
    mine = toeplitz_from_sparse(np.asarray(model.G), model.N, model.n_y, model.n_u, rtol=0.0)
    return mine is not None and bool(np.array_equal(mine, blocks))


def check_lifted_plant(lifted_plant, name: str = "lifted_plant"):
    """``lifted_plant`` must be a lifted plant (``LiftedPlant`` of
    ``ilc_analysis.lifting.lift_operator``): its ``G`` a
    :class:`~ilc_analysis.lifting.LiftedOperator` ``(N*n_y, N*n_u)`` with blocks
    ``(n_y, n_u)``, and its trial facts ``N, n_u, n_y, shift, ts`` and ``dense_system()``.

    Returns
    -------
    The lifted plant.

    Raises
    ------
    ParameterError
        Not a lifted plant.
    ShapeError
        Its G does not have the shape its N, n_u, n_y say.
    """
    missing = [k for k in ("N", "n_u", "n_y", "shift", "ts", "dense_system")
               if not hasattr(lifted_plant, k)]
    G = getattr(lifted_plant, "G", None)
    if missing or not isinstance(G, LiftedOperator):
        raise ParameterError(f"{name} must be a LiftedPlant (ilc_analysis.lifting.lift_operator: "
                             f"G as a LiftedOperator, N, n_u, n_y, shift, ts); got "
                             f"{type(lifted_plant).__name__}")
    N, n_u, n_y = lifted_plant.N, lifted_plant.n_u, lifted_plant.n_y
    if G.shape != (N * n_y, N * n_u) or G.block != (n_y, n_u):
        raise ShapeError(f"{name}.G must have shape {(N * n_y, N * n_u)} with blocks "
                         f"{(n_y, n_u)} (N={N}, n_u={n_u}, n_y={n_y}); found shape {G.shape} "
                         f"with blocks {G.block}")
    return lifted_plant


def check_trial_signals(u_i, e_i, n_u: int | None = None,
                        n_y: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``u_i`` ``(N, n_u)`` and ``e_i`` ``(N, n_y)``, finite, same N."""
    u = as_finite_array(u_i, "u_i (input of the last trial, (N, n_u))", shape=(None, n_u))
    e = as_finite_array(e_i, "e_i (error of the last trial on the window, (N, n_y))",
                        shape=(u.shape[0], n_y))
    if u.shape[0] == 0:
        raise ShapeError("u_i must have at least one sample; found shape (0, ...)")
    return u, e


def check_ts_match(ts, expected: float | None, what: str) -> float:
    """A sample time equal (to :data:`TS_RTOL`) to ``expected`` (if not None)."""
    from .._validation import positive

    ts = positive(ts, "ts (sample time)")
    if expected is not None and abs(ts - expected) > TS_RTOL * expected:
        raise ParameterError(f"{what} has sample time {expected:g} s; the trial has ts = {ts:g} s")
    return ts


# ---------------------------------------------------------------------------------------------
# the interface
# ---------------------------------------------------------------------------------------------
class LearningLaw(abc.ABC):
    r"""What every learning law gives (module docstring).

    * :meth:`lifted` — its :class:`LiftedLaw` on a trial (:math:`L_1, L_2, Q, a`), from which
      :meth:`LiftedLaw.operator` builds T;
    * :meth:`frequency_response` — :math:`L, Q, L_2` on a grid when the law and plant are LTI
      (else :class:`ParameterError`);
    * :meth:`update` — the between-trial update on measured data: the next trial's feed-forward
      ``(N, n_u)`` from the last trial's applied input ``u_i`` ``(N, n_u)`` and error on the
      window ``e_i`` ``(N, n_y)`` (a current-trial part :math:`L_2` acts during the next trial on
      top of it);
    * :meth:`describe` — the parameters as plain values (for a design file);
    * :meth:`check` — raise unless the law fits a lifted trial.
    """

    #: label used in results and reports
    name: str = "learning law"

    @abc.abstractmethod
    def lifted(self, lifted_system: LiftedSystem) -> LiftedLaw:
        """The law's lifted form on ``lifted_system`` (checked with :meth:`check`).

        Parameters
        ----------
        lifted_system : LiftedSystem
            The lifted trial (:func:`ilc_analysis.lifting.lift`) the law runs on: its G,
            N, shift, dimensions and sample time.

        Returns
        -------
        LiftedLaw
            :math:`L_1, L_2, Q, a` on that trial.

        Raises
        ------
        ParameterError, ShapeError
            The law does not fit the trial (:meth:`check`).
        """

    def lifted_operators(self, lifted_plant) -> LawOperators:
        """The law's lifted form as operators on ``lifted_plant`` (:class:`LawOperators`).

        This default lifts the law on ``lifted_plant.dense_system()`` (:meth:`lifted`) and wraps
        its matrices (:meth:`LawOperators.from_lifted`): it forms G and the law's matrices,
        fine at moderate N. Laws override it with operator forms that never form an N x N
        matrix.

        Parameters
        ----------
        lifted_plant : LiftedPlant
            The lifted trial (``ilc_analysis.lifting.lift_operator``): G as an operator, the
            trial's N, shift, dimensions and sample time.

        Returns
        -------
        LawOperators

        Raises
        ------
        ParameterError, ShapeError
            Not a lifted plant, or the law does not fit the trial (:meth:`check`).
        """
        lp = check_lifted_plant(lifted_plant)
        ls = lp.dense_system()
        return LawOperators.from_lifted(self.lifted(ls), ls.n_u, ls.n_y)

    @abc.abstractmethod
    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        """Next trial's feed-forward ``(N, n_u)`` from the measured trial.

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window, :math:`e_i(j) = y_d(j+s) - y_i(j+s)`.
        ts : float
            Sample time [s] (> 0; must match the law's filters or model where it has one).

        Returns
        -------
        ndarray (N, n_u)
            The next trial's feed-forward (a current-trial part acts on top of it).

        Raises
        ------
        ParameterError, ShapeError
            Non-finite signals, shapes that do not fit the law, or a sample time that does
            not match.
        """

    @abc.abstractmethod
    def describe(self) -> dict:
        """The law's kind and parameters as plain (TOML-safe) values."""

    def check(self, lifted_system: LiftedSystem) -> None:
        """Raise :class:`ParameterError` / :class:`ShapeError` unless the law fits.

        Parameters
        ----------
        lifted_system : LiftedSystem
            The lifted trial to check the law against (N, shift, dimensions, sample time).

        Raises
        ------
        ParameterError
            Not a LiftedSystem, or a sample time / parameter that does not fit the trial.
        ShapeError
            Dimensions (N, n_u, n_y, shift) that do not fit the trial.
        """
        check_lifted_system(lifted_system)

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r""":class:`LawResponse` on ``omega`` [rad/s] for an LTI ``plant``; laws without one raise
        :class:`ParameterError`.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete-time python-control system
            The LTI plant the law runs on (for a model-based law: the system behind its
            model).
        omega : array_like (n_w,)
            Angular frequencies [rad/s] in :math:`[0, \pi/T_s]`.
        shift : int, optional
            The output shift s of the lifted error (default: the plant's sampled relative
            degree).

        Returns
        -------
        LawResponse
            :math:`L, Q, L_2` on the grid, the error taken at the plant's own time.

        Raises
        ------
        ParameterError
            The law has no frequency response (not an LTI filter), or the plant or grid does
            not fit it.
        """
        raise ParameterError(f"{self.name}: no frequency response (the law is not an LTI "
                             f"filter); use the lifted analysis (lifted(...).operator)")

    def experiments_per_iteration(self, n_u: int = 1, n_y: int = 1) -> int:
        """Plant runs per learning iteration (1: the trial itself).

        Parameters
        ----------
        n_u, n_y : int
            Number of learned inputs and of outputs (laws that measure with extra experiments
            need one per input-output pair); default 1.

        Returns
        -------
        int
        """
        return 1

    def model_text(self) -> str:
        """Which model the law's lifted form is built from, in one phrase (the analysis'
        ``details['judged']['law_model']``): the law's own model, never the plant it runs on.

        Returns
        -------
        str
            :data:`NO_SEPARATE_MODEL` unless the law has a model of its own.
        """
        return NO_SEPARATE_MODEL

    def operator(self, lifted_system: LiftedSystem, a=None) -> np.ndarray:
        """Shortcut: ``self.lifted(lifted_system).operator(lifted_system, a)``.

        Parameters
        ----------
        lifted_system : LiftedSystem
            The lifted trial: the law is lifted on it and T built with its G.
        a : float or array_like (N,), optional
            The forgetting factor (:meth:`LiftedLaw.operator`); required for a variable one.

        Returns
        -------
        ndarray (N*n_u, N*n_u)
            The trial-to-trial operator T.
        """
        return self.lifted(lifted_system).operator(lifted_system, a)


def lift_model(model: DiscretePlant, lifted_system: LiftedSystem, *, x0=None, w=None,
               t0: float = 0.0, shift: int | None = None) -> LiftedSystem:
    r"""A law's model plant lifted on the trial the law runs on: :math:`\hat G` of
    :math:`L_1 = L_1(\hat G)`, never the plant's G.

    :func:`ilc_analysis.lifting.lift` of ``model`` with the trial's N, along the trial's
    nominal input (``lifted_system.u_nominal``; zero input for an LTI trial) and from the
    law's own initial state, known disturbance, t0 and shift (the trial the law's update
    takes its Jacobian or adjoint along). For an LTI model the result does not depend on x0,
    w or the nominal input; for a nonlinear one it is the model's Jacobian along that trial
    (a local model).

    Parameters
    ----------
    model : DiscretePlant
        The law's model (linear or nonlinear).
    lifted_system : LiftedSystem
        The trial the law is lifted on (its N, sample time and nominal input).
    x0, w, t0, shift
        The law's trial: initial state ``(n_x,)``, known state disturbance ``(N, n_x)``, time
        of sample 0 and output shift (default: the model's sampled relative degree at
        ``(x0, 0, t0)``, as :class:`~ilc_analysis.lifting.TrialMap`).

    Returns
    -------
    LiftedSystem
        The lifted model, ``(N*n_y, N*n_u)``.

    Raises
    ------
    ParameterError, ShapeError
        The model's sample time or dimensions do not fit the trial, or ``x0``, ``w`` do not
        fit the model (as :func:`~ilc_analysis.lifting.lift`).
    """
    from ..lifting import lift

    ls = check_lifted_system(lifted_system)
    x0, shift = _model_trial(model, ls, x0, t0, shift)
    return lift(model, ls.N, x0=x0, u_nominal=ls.u_nominal, w=w, t0=t0, shift=shift)


def lift_model_operator(model: DiscretePlant, lifted_plant, *, x0=None, w=None,
                        t0: float = 0.0, shift: int | None = None):
    r"""A law's model plant lifted on the trial ``lifted_plant`` as an operator: as
    :func:`lift_model`, with ``ilc_analysis.lifting.lift_operator`` (G never formed).

    Parameters
    ----------
    model : DiscretePlant
        The law's model (linear or nonlinear).
    lifted_plant : LiftedPlant
        The trial the law is lifted on (its N, sample time and nominal input).
    x0, w, t0, shift
        The law's trial, as for :func:`lift_model`.

    Returns
    -------
    LiftedPlant
        The lifted model; its ``G`` is :math:`\hat G` as a LiftedOperator.

    Raises
    ------
    ParameterError, ShapeError
        As :func:`lift_model`.
    """
    from ..lifting._lift_operator import lift_operator

    lp = check_lifted_plant(lifted_plant)
    x0, shift = _model_trial(model, lp, x0, t0, shift)
    return lift_operator(model, lp.N, x0=x0, u_nominal=lp.u_nominal, w=w, t0=t0, shift=shift)


def _model_trial(model: DiscretePlant, trial, x0, t0: float, shift):
    """The law's model checked against the trial (sample time, dimensions) and its trial's
    ``x0`` (validated) and shift (default: the model's sampled relative degree at (x0, 0, t0))."""
    from .._validation import as_vector
    from ..lifting import sampled_shift

    check_ts_match(trial.ts, model.ts, "the law's model")
    if (model.n_u, model.n_y) != (trial.n_u, trial.n_y):
        raise ShapeError(f"the law's model has {model.n_u} inputs and {model.n_y} outputs; the "
                         f"trial {trial.n_u} and {trial.n_y}")
    if x0 is not None:
        x0 = as_vector(x0, "x0 (the law's initial state)", model.n_x)
    if shift is None:
        shift = sampled_shift(model, x=x0, t=t0)
    return x0, shift


def shift_of(plant: DiscretePlant, shift) -> int:
    """The sampled relative degree of ``plant`` unless ``shift`` is given."""
    from ..lifting import sampled_shift
    from ..lifting._validation import check_shift

    return sampled_shift(plant) if shift is None else check_shift(shift)


def check_same_trial(model: LiftedSystem | SimpleNamespace, lifted_system,
                     what: str = "the law's model") -> None:
    """Raise unless ``lifted_system`` is a trial of the same shape as ``model`` (N, n_u, n_y,
    shift, ts): a model-based law's lifted matrices are built on its own model. ``model`` is a
    LiftedSystem or a record of those five attributes (a law's trial, not lifted);
    ``lifted_system`` a LiftedSystem or a lifted plant (:func:`check_lifted_plant`)."""
    ls = (check_lifted_plant(lifted_system, "lifted_system")
          if isinstance(getattr(lifted_system, "G", None), LiftedOperator)
          else check_lifted_system(lifted_system))
    mine = (model.N, model.n_u, model.n_y, model.shift)
    theirs = (ls.N, ls.n_u, ls.n_y, ls.shift)
    if mine != theirs:
        raise ShapeError(f"{what} is a trial with (N, n_u, n_y, shift) = {mine}; the lifted "
                         f"system has {theirs}")
    check_ts_match(ls.ts, model.ts, what)


def as_problem(problem):
    """``problem`` if it is an :class:`~ilc_analysis.problem.ILCProblem`, else ParameterError.

    Parameters
    ----------
    problem : ILCProblem
        The problem a law or a simulation runs on.

    Raises
    ------
    ParameterError
        ``problem`` is not an :class:`~ilc_analysis.problem.ILCProblem`.
    """
    if not is_problem(problem):
        raise ParameterError(f"problem must be an ILCProblem (ilc_analysis.problem); got "
                             f"{type(problem).__name__}")
    return problem
