r"""``lift_operator``: the lifted trial :math:`y = Gu + d` with G as an operator, never a matrix.

The matrix-free counterpart of :func:`~ilc_analysis.lifting.lift` (same arguments, same G and
d, same index convention of :mod:`ilc_analysis.laws`), without the dense-memory cap: N up to
:data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES`.

* LTI plant (``dplant.matrices`` set): G is the block lower-triangular Toeplitz operator of the
  Markov parameters (``lti_plant_operator`` of :mod:`._toeplitz`), d the free response;
* nonlinear or time-varying plant: the per-sample Jacobians :math:`(A_k, B_k, C_k, D_k)` of
  one trial along ``u_nominal`` (:class:`~ilc_analysis.lifting.TrialMap`) make G an
  :class:`~ilc_analysis.lifting.LTVPlantOperator`, and
  :math:`d = y(u_{nom}) - G u_{nom}` (one trial and one product).

:meth:`LiftedPlant.dense_system` forms the :class:`~ilc_analysis.lifting.LiftedSystem` that
:func:`~ilc_analysis.lifting.lift` gives, under its memory cap.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validation import as_finite_array, check_lifted_size
from ..exceptions import InternalError, ParameterError, ShapeError
from ..model import DiscretePlant
from ._lifted_operator import LiftedOperator
from ._lifted_system import LiftedSystem, _names
from ._lti_lifting import _free_response, block_toeplitz, lti_markov_blocks
from ._ltv_operator import LTVPlantOperator
from ._toeplitz import lti_plant_operator
from ._trial_arguments import trial_arguments
from ._trial_map import TrialMap, _assemble

__all__ = ["LiftedPlant", "lift_operator"]


@dataclass(frozen=True, eq=False)
class LiftedPlant:
    r"""One trial in lifted form :math:`y = Gu + d` with G a
    :class:`~ilc_analysis.lifting.LiftedOperator` (module docstring). Frozen.

    Built by :func:`lift_operator`; arrays are read-only.
    """

    G: LiftedOperator
    """the lifted plant ``(N*n_y, N*n_u)``, blocks ``(n_y, n_u)``, applied by products"""
    d: np.ndarray
    """free response (initial state, disturbances, linearisation offset), ``(N*n_y,)``"""
    shift: int
    """sampled relative degree s >= 0: the output window is y(s) ... y(N-1+s)"""
    ts: float
    """sample time [s]"""
    N: int
    """trial length in samples"""
    n_u: int
    """number of inputs"""
    n_y: int
    """number of outputs"""
    t0: float = 0.0
    """time of sample 0 [s]"""
    kind: str = "lti"
    """``'lti'`` (Toeplitz of Markov parameters) or ``'ltv'`` (Jacobian along a nominal trial)"""
    u_nominal: np.ndarray | None = None
    """the nominal input ``(N, n_u)`` an ``'ltv'`` lifting was taken along, else None"""
    input_names: tuple[str, ...] = ()
    """input channel names (default u0, u1, ...)"""
    output_names: tuple[str, ...] = ()
    """output channel names (default y0, y1, ...)"""
    state_space: tuple[np.ndarray, ...] = field(default=())
    r"""per-sample ``(A, B, C, D)``, shapes ``(N+s, n_x, n_x)``, ``(N+s, n_x, n_u)``,
    ``(N+s, n_y, n_x)``, ``(N+s, n_y, n_u)`` (read-only broadcast views for an LTI plant):
    :math:`x(k+1) = A_kx(k) + B_ku(k)`, :math:`y(k) = C_kx(k) + D_ku(k)`, u(k) = 0 for k >= N"""

    def __post_init__(self) -> None:
        N, n_u, n_y = self.N, self.n_u, self.n_y
        if not isinstance(self.G, LiftedOperator):
            raise ParameterError(f"G must be a LiftedOperator; got {type(self.G).__name__}")
        if self.G.shape != (N * n_y, N * n_u) or self.G.block != (n_y, n_u):
            raise ShapeError(f"G must be {(N * n_y, N * n_u)} with blocks {(n_y, n_u)}; found "
                             f"{self.G.shape} with blocks {self.G.block}")
        d = np.array(as_finite_array(self.d, "d", shape=(N * n_y,)))
        d.setflags(write=False)
        object.__setattr__(self, "d", d)
        if self.kind not in ("lti", "ltv"):
            raise ParameterError(f"kind must be 'lti' or 'ltv'; got {self.kind!r}")
        if self.u_nominal is not None:
            un = np.array(as_finite_array(self.u_nominal, "u_nominal", shape=(N, n_u)))
            un.setflags(write=False)
            object.__setattr__(self, "u_nominal", un)
        object.__setattr__(self, "input_names", _names(self.input_names, n_u, "input_names",
                                                       "u"))
        object.__setattr__(self, "output_names", _names(self.output_names, n_y, "output_names",
                                                        "y"))
        if len(self.state_space) != 4:
            raise ShapeError("state_space must be the four per-sample arrays (A, B, C, D); "
                             f"found {len(self.state_space)}")
        n_x = np.shape(self.state_space[0])[-1]
        M = N + self.shift
        views = []
        for name, arr, shape in zip("ABCD", self.state_space,
                                    ((n_x, n_x), (n_x, n_u), (n_y, n_x), (n_y, n_u)),
                                    strict=True):
            if np.shape(arr) != (M, *shape):
                raise ShapeError(f"state_space {name} must have shape {(M, *shape)}; found "
                                 f"{np.shape(arr)}")
            v = np.asarray(arr, dtype=float).view()
            v.setflags(write=False)
            views.append(v)
        object.__setattr__(self, "state_space", tuple(views))

    @property
    def shape(self) -> tuple[int, int]:
        """``(N*n_y, N*n_u)``."""
        return self.G.shape

    def dense_system(self) -> LiftedSystem:
        """The :class:`~ilc_analysis.lifting.LiftedSystem` :func:`~ilc_analysis.lifting.lift`
        gives for the same arguments: G formed (the same blocks, by the same computation), d
        as here.

        Raises
        ------
        ParameterError
            A dense G above :data:`~ilc_analysis._validation.MAX_LIFTED_ENTRIES` (lift's
            message: estimated GiB and the largest N allowed).
        """
        check_lifted_size(self.N, self.n_y, self.n_u)
        A, B, C, D = self.state_space
        if self.kind == "lti":
            G = block_toeplitz(lti_markov_blocks(A[0], B[0], C[0], D[0], self.shift, self.N))
        else:
            G = _assemble(A, B, C, D, self.N, self.shift)
        return LiftedSystem(G=G, d=self.d, shift=self.shift, ts=self.ts, N=self.N, n_u=self.n_u,
                            n_y=self.n_y, input_names=self.input_names,
                            output_names=self.output_names, t0=self.t0, kind=self.kind,
                            u_nominal=self.u_nominal)

    def __repr__(self) -> str:
        return (f"<LiftedPlant {self.kind}: N={self.N}, ts={self.ts:g} s, shift={self.shift}, "
                f"inputs {list(self.input_names)}, outputs {list(self.output_names)}, "
                f"G {self.G.describe()}>")


def _overflow(dplant: DiscretePlant, N: int) -> ParameterError:
    return ParameterError(f"the trial of {dplant.name} overflows along the nominal input over "
                          f"N = {N} samples; shorten the trial, sample faster, or stabilise the "
                          "plant first (Plant.with_state_feedback)")


def lift_operator(dplant: DiscretePlant, N: int, *, x0=None, u_nominal=None, w=None,
                  t0: float = 0.0, shift: int | None = None) -> LiftedPlant:
    r"""The lifted trial :math:`y = Gu + d` of a sampled plant with G an operator.

    Same arguments, validation and results as :func:`~ilc_analysis.lifting.lift`, but G is
    never formed: memory and time O(N) (one trial and its per-sample Jacobians for a nonlinear
    plant), so N may go up to :data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES`.

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant.
    N : int
        Trial length in samples, 1 to :data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES`.
    x0 : array_like, optional
        Initial state ``(n_x,)`` (default zero).
    u_nominal : array_like, optional
        Nominal input ``(N, n_u)`` a nonlinear plant is lifted along (default zero; ignored
        for an LTI plant).
    w : array_like, optional
        Known state disturbance ``(N, n_x)`` held over each sample (enters d).
    t0 : float
        Time of sample 0 [s].
    shift : int, optional
        The output-window shift s; default :func:`~ilc_analysis.lifting.sampled_shift` at
        ``(x0, u_nominal[0], t0)``.

    Returns
    -------
    LiftedPlant

    Raises
    ------
    ParameterError
        N outside [1, MAX_TRIAL_SAMPLES], a non-DiscretePlant, a negative shift, or a trial
        that overflows.
    ShapeError
        ``x0``, ``u_nominal`` or ``w`` of the wrong shape.
    """
    dplant, N, x0, u_nom, w, t0, shift = trial_arguments(
        dplant, N, x0=x0, u_nominal=u_nominal, w=w, t0=t0, shift=shift, dense=False)
    common = {"shift": shift, "ts": dplant.ts, "N": N, "n_u": dplant.n_u, "n_y": dplant.n_y,
              "t0": t0, "input_names": dplant.input_names,
              "output_names": dplant.output_names}
    if dplant.matrices is not None:
        Ad, Bd, C, D, Ed = dplant.matrices
        d = _free_response(Ad, C, Ed, x0, w, shift, N)
        if not np.all(np.isfinite(d)):
            raise _overflow(dplant, N)
        toeplitz = lti_plant_operator(dplant, N, shift)    # refuses overflowing Markov blocks
        if toeplitz.state_space is None:
            raise InternalError("lti_plant_operator gives its state-space realisation")
        return LiftedPlant(G=toeplitz, d=d, kind="lti", state_space=toeplitz.state_space,
                           **common)
    tm = TrialMap(dplant, N, shift, x0=x0, w=w, t0=t0)
    mats, _, y_nom = tm._linearization(u_nom)
    if not (np.all(np.isfinite(y_nom)) and all(np.all(np.isfinite(m)) for m in mats)):
        raise _overflow(dplant, N)
    A, B, C, D = mats
    G = LTVPlantOperator(A, B, C, D, shift, N, description=f"LTV plant {dplant.name}")
    d = y_nom - G.matvec(u_nom.reshape(-1))
    if not np.all(np.isfinite(d)):
        raise _overflow(dplant, N)
    return LiftedPlant(G=G, d=d, kind="ltv", u_nominal=u_nom, state_space=mats, **common)
