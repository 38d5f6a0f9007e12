r"""The ILC problem: one object holding everything a learning law is designed, analysed and run on.

An :class:`ILCProblem` fixes the plant, the sample time :math:`T_s`, the trial length N, the
output-window shift s, the reference :math:`y_d` on the window, the initial state, the nominal
trajectory the lifting is taken along, the disturbances, and where learning acts
(:class:`~ilc_analysis.problem.PlantInput`, :class:`~ilc_analysis.problem.LoopReference`,
:class:`~ilc_analysis.problem.LoopInput`). Index convention (:mod:`ilc_analysis.laws`): the learned
signal v(0..N-1) at times :math:`t_0 + kT_s`, the output window y(s..N-1+s) at
:math:`t_0 + (s + j)T_s`, and

.. math::

    y = G v + d,\qquad e = y_d - y,\qquad r = y_d - d,

with G, d the lifting of the sampled system the learned signal drives (``problem.dplant``)
along ``problem.u_nominal`` from ``problem.x0`` with the known state disturbance ``problem.w``.
Every derived object (sampled composite, shift, lifted system, LTI state space) is computed once
and cached: no later stage re-runs an earlier one.
"""

from __future__ import annotations

import html
import re
from functools import cached_property

import control
import numpy as np

from .._validation import (
    MAX_SHIFT,
    MAX_TRIAL_SAMPLES,
    as_finite_array,
    positive,
    positive_int,
    real,
)
from ..exceptions import ParameterError, ShapeError
from ..lifting import LiftedPlant, LiftedSystem, lift, lift_operator, sampled_shift
from ..model import DiscretePlant, Plant
from ._compose import as_model, compose
from ._disturbances import Disturbances
from ._learning_at import (
    LEARNING_AT_KINDS,
    LoopInput,
    LoopReference,
    PlantInput,
    _keys,
    controller_from_description,
)

__all__ = ["ILCProblem", "is_problem", "plant_name", "DEFAULT_PROBLEM_NAME",
           "FIRST_TRIAL_REFERENCE"]

#: ``u_initial`` of a plant whose input is the reference of its own feedback loop: the first
#: trial drives it with the reference (the loop alone, the honest baseline)
FIRST_TRIAL_REFERENCE = "reference"
#: the name of a problem whose plant has no name of its own (:func:`plant_name`)
DEFAULT_PROBLEM_NAME = "problem"
#: names given to a plant when its user named none: the toolkit's (``Plant``,
#: ``DiscretePlant``, a design file's matrices) and python-control's ``sys[k]``
_MADE_UP_NAMES = re.compile(r"plant|sys\[\d+\]")

_METHODS = ("auto", "zoh", "rk4", "cvodes")
_DISTURBANCE_FIELDS = ("state_amplitude", "state_frequency", "output_amplitude",
                       "output_frequency", "state_noise", "output_noise", "reset_error")


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


def plant_name(plant) -> str | None:
    """The name the user gave ``plant`` (a :class:`~ilc_analysis.model.Plant`,
    :class:`~ilc_analysis.model.DiscretePlant` or python-control system), or None when it has
    only a made-up one (``"plant"``, python-control's ``sys[3]``).

    Parameters
    ----------
    plant : Plant, DiscretePlant or control LTI system
        The plant as given to :class:`ILCProblem`.

    Examples
    --------
    >>> import control
    >>> plant_name(control.tf([1.0], [1.0, 1.0], name="servo")), plant_name(control.tf(1, [1, 1]))
    ('servo', None)
    """
    name = getattr(plant, "name", None)
    if not isinstance(name, str) or not name.strip() or _MADE_UP_NAMES.fullmatch(name):
        return None
    return name


def _is_reference_keyword(value) -> bool:
    """``u_initial`` is the keyword :data:`FIRST_TRIAL_REFERENCE` (any other string is an
    error naming the keyword)."""
    if not isinstance(value, str):
        return False
    if value != FIRST_TRIAL_REFERENCE:
        raise ParameterError(f"u_initial must be an array (N, n_u) or "
                             f"{FIRST_TRIAL_REFERENCE!r} (the plant's input is the reference of "
                             f"its own loop); got {value!r:.80}")
    return True


def _check_reference_first_trial(learning_at, n_u: int, n_y: int) -> None:
    """``u_initial="reference"`` needs a learned signal that is a reference for the outputs."""
    if isinstance(learning_at, LoopInput):
        raise ParameterError(f"u_initial={FIRST_TRIAL_REFERENCE!r}: learning at the loop's input "
                             "adds a feed-forward at the plant input, not a reference; its "
                             "first trial is the loop alone already (zero feed-forward)")
    if n_u != n_y:
        raise ParameterError(f"u_initial={FIRST_TRIAL_REFERENCE!r} drives the plant with its "
                             f"reference: it needs as many inputs as outputs; the plant has "
                             f"{n_u} input(s) and {n_y} output(s)")


def _disturbances(value, n_x: int, n_y: int):
    if value is None:
        return None
    if not isinstance(value, Disturbances):
        raise ParameterError("disturbances must be an ilc_analysis.problem.Disturbances or "
                             f"None; got {type(value).__name__}")
    value.check_dimensions(n_x, n_y)
    return value


class ILCProblem:
    r"""An ILC problem: plant, sampling, trial, reference, and where learning acts.

    Parameters
    ----------
    plant : Plant, DiscretePlant, control.StateSpace or control.TransferFunction
        A CasADi ODE plant, a sampled plant (its ``ts`` must equal ``ts``), or a python-control
        LTI system (continuous: sampled with a zero-order hold at ``ts``; discrete: ``dt`` must
        equal ``ts``).
    ts : float
        Sample time [s], > 0.
    N : int
        Trial length in samples, 1 to :data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES`.
    reference : array_like, shape (N, n_y)
        :math:`y_d` on the output window, at times :math:`t_0 + (s + j)T_s`, one column per
        plant output; finite.
    x0 : array_like, optional
        Initial state: the plant's ``(n_x,)`` (controller states start at zero) or the
        composite's (plant states then controller states). Default zero.
    shift : int, optional
        Output-window shift :math:`0 \\le s \\le` :data:`~ilc_analysis._validation.MAX_SHIFT`.
        Default: the sampled relative degree of ``dplant`` at
        ``(x0, u_nominal[0], t0)`` (:func:`~ilc_analysis.lifting.sampled_shift`).
    u_nominal : array_like, shape (N, n_u), optional
        Learned-signal trajectory the lifting is taken along and the first trial's input.
        Default: zeros (PlantInput, LoopInput), the loop's reference :attr:`loop_reference`
        (LoopReference: the first trial runs the plain servo loop; :math:`y_d` itself with the
        default ``reference_timing="ahead"``).
    u_initial : array_like, shape (N, n_u), or "reference", optional
        The first trial's learned signal when it is not the trajectory the lifting is taken
        along (the paper lifts along the realisable input :math:`u_d` but starts every run from
        the constant :math:`u_0`). Default: ``u_nominal``. ``"reference"`` declares a plant
        whose input is the reference of its own feedback loop (learning at the plant input,
        as many inputs as outputs): the first trial drives it with :math:`y_d` itself, the
        loop alone, and the lifting is taken along it unless ``u_nominal`` is given. The
        first trial is the baseline every reduction factor is counted from
        (:attr:`first_trial`).
    disturbances : ilc_analysis.simulation.Disturbances, optional
        Disturbances of the simulated trials (state disturbance of the composite, output
        disturbance of the plant outputs).
    learning_at : PlantInput, LoopReference or LoopInput
        Where the learned signal acts; default :class:`PlantInput`. A loop's
        ``reference_timing`` says which sample of :math:`y_d` its reference carries at input
        sample k (:attr:`loop_reference`).
    t0 : float
        Time of sample 0 [s].
    name : str, optional
        What outputs call the problem. Default: the plant's own name (:func:`plant_name`),
        else ``"problem"``.
    method : {'auto', 'zoh', 'rk4', 'cvodes'}
        Sampling of a continuous plant (or composite), see
        :func:`~ilc_analysis.model.discretize`.
    substeps : int
        RK4 sub-steps per sample.

    Attributes
    ----------
    dplant : DiscretePlant
        The sampled system the learned signal drives (plant, or the closed loop with state
        (plant states, ``ctrl_0``, ...)); inputs are the learned signal's channels, outputs the
        plant outputs.
    lifted : LiftedSystem
        :math:`y = Gv + d` along ``u_nominal`` (computed on first access, then cached).
    lifted_plant : LiftedPlant
        The same with G as an operator (never formed; computed on first access, then cached).

    Raises
    ------
    ParameterError
        Any parameter outside its valid form (named in the message): ts <= 0, N < 1, non-finite
        entries, unknown ``learning_at``, improper or mismatched controller, algebraic loop, a
        discrete controller with a nonlinear plant or a different dt.
    ShapeError
        ``reference``, ``x0``, ``u_nominal`` of the wrong shape (expected and found given).

    Examples
    --------
    >>> import control, numpy as np
    >>> from ilc_analysis.problem import ILCProblem, LoopReference, pid
    >>> P = control.tf([1.0], [1.0, 1.0])
    >>> pr = ILCProblem(P, ts=0.1, N=5, reference=np.ones((5, 1)),
    ...                 learning_at=LoopReference(pid(2.0)))
    >>> pr.n_u, pr.shift, pr.is_lti
    (1, 1, True)
    """

    def __init__(self, plant, ts, N, reference, *, x0=None, shift=None, u_nominal=None,
                 u_initial=None, disturbances=None, learning_at=None, t0=0.0,
                 name: str | None = None, method: str = "auto", substeps: int = 4):
        if learning_at is None:
            learning_at = PlantInput()
        if not isinstance(learning_at, PlantInput | LoopReference | LoopInput):
            raise ParameterError(
                "learning_at must be PlantInput(), LoopReference(controller) or "
                f"LoopInput(controller) (from ilc_analysis.problem); got {learning_at!r}")
        ts = positive(ts, "ts (sample time)")
        N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
        t0 = real(t0, "t0")
        if method not in _METHODS:
            raise ParameterError(f"method must be one of {_METHODS}; got {method!r}")
        substeps = positive_int(substeps, "substeps")
        if name is None:
            name = plant_name(plant) or DEFAULT_PROBLEM_NAME
        if not isinstance(name, str) or not name:
            raise ParameterError(f"name must be a non-empty string; got {name!r}")
        model = as_model(plant, ts)
        y_d = _frozen(as_finite_array(reference, "reference", shape=(N, model.n_y)))
        comp = compose(model, learning_at, ts=ts, N=N, y_d=y_d, method=method,
                       substeps=substeps, t0=t0)
        dp = comp.dplant
        self._x0 = _frozen(self._initial_state(x0, comp.plant_states, dp.n_x))
        if u_nominal is None:
            # the loop's reference starts at y_d(0) in either timing (the shift is found there)
            u_nom = y_d if isinstance(learning_at, LoopReference) else np.zeros((N, dp.n_u))
            self._u_nominal_given = False
        else:
            u_nom = as_finite_array(u_nominal, "u_nominal", shape=(N, dp.n_u))
            self._u_nominal_given = True
        self._first_trial_reference = _is_reference_keyword(u_initial)
        if self._first_trial_reference:
            _check_reference_first_trial(learning_at, dp.n_u, model.n_y)
            u_initial = None
            if not self._u_nominal_given:
                u_nom = y_d          # the loop alone, lifted along it (a loop: its timing below)
            elif isinstance(learning_at, PlantInput):
                u_initial = y_d
        self._u_initial = None if u_initial is None else _frozen(
            as_finite_array(u_initial, "u_initial", shape=(N, dp.n_u)))
        if shift is None:
            shift = sampled_shift(dp, x=self._x0, u=u_nom[0], t=t0)
        self._shift = positive_int(shift, "shift", minimum=0, maximum=MAX_SHIFT)
        self._loop_reference = None
        if isinstance(learning_at, LoopReference | LoopInput):
            loop_ref = _frozen(learning_at.loop_reference(y_d, self._shift))
            self._loop_reference = loop_ref
            if isinstance(learning_at, LoopReference) and not self._u_nominal_given:
                u_nom = loop_ref
            elif isinstance(learning_at, LoopReference) and self._first_trial_reference:
                self._u_initial = loop_ref
            elif isinstance(learning_at, LoopInput) and not np.array_equal(loop_ref, y_d):
                # the controller sees the delayed reference: compose with it
                comp = compose(model, learning_at, ts=ts, N=N, y_d=loop_ref, method=method,
                               substeps=substeps, t0=t0)
                dp = comp.dplant
        self._u_nominal = _frozen(u_nom)
        self._disturbances = _disturbances(disturbances, dp.n_x, dp.n_y)
        self._plant, self._ts, self._N, self._t0, self._name = plant, ts, N, t0, name
        self._reference = y_d
        self._learning_at = learning_at
        self._method, self._substeps = method, substeps
        self._dplant = dp
        self._w = None if comp.w is None else _frozen(comp.w)
        self._plant_states = comp.plant_states
        self._continuous = comp.continuous
        self._frozen = True

    @staticmethod
    def _initial_state(x0, n_plant: int, n_x: int) -> np.ndarray:
        if x0 is None:
            return np.zeros(n_x)
        if n_plant == n_x:
            return as_finite_array(x0, "x0", shape=(n_x,))
        arr = as_finite_array(x0, "x0", ndim=1)
        if arr.shape == (n_plant,):
            return np.concatenate([arr, np.zeros(n_x - n_plant)])
        if arr.shape != (n_x,):
            raise ShapeError(f"x0 must have shape ({n_plant},) (plant states; the controller "
                             f"starts at zero) or ({n_x},) (plant then controller states); "
                             f"found shape {arr.shape}")
        return arr

    def __setattr__(self, key, value):
        if getattr(self, "_frozen", False):
            raise AttributeError(f"ILCProblem is frozen; cannot set {key!r}")
        object.__setattr__(self, key, value)

    # the problem's data ---------------------------------------------------------------------
    @property
    def plant(self):
        """The plant as given (Plant, DiscretePlant or python-control LTI)."""
        return self._plant

    @property
    def name(self) -> str:
        return self._name

    @property
    def learning_at(self) -> PlantInput | LoopReference | LoopInput:
        return self._learning_at

    @property
    def ts(self) -> float:
        """Sample time [s]."""
        return self._ts

    @property
    def N(self) -> int:
        """Trial length in samples."""
        return self._N

    @property
    def t0(self) -> float:
        """Time of sample 0 [s]."""
        return self._t0

    @property
    def shift(self) -> int:
        """Output-window shift s (resolved)."""
        return self._shift

    @property
    def dplant(self) -> DiscretePlant:
        """The sampled system the learned signal drives (composite loop when learning at a
        loop)."""
        return self._dplant

    @property
    def continuous_composite(self) -> Plant | None:
        """The continuous closed loop (CasADi Plant) before sampling, when one was built."""
        return self._continuous

    @property
    def n_u(self) -> int:
        """Channels of the learned signal."""
        return self._dplant.n_u

    @property
    def n_y(self) -> int:
        """Plant outputs."""
        return self._dplant.n_y

    @property
    def n_x(self) -> int:
        """States of ``dplant`` (plant states first, then controller states)."""
        return self._dplant.n_x

    @property
    def plant_states(self) -> int:
        """Number of plant states (the first ``plant_states`` entries of the state)."""
        return self._plant_states

    @property
    def input_names(self) -> tuple[str, ...]:
        """Names of the learned signal's channels."""
        return self._dplant.input_names

    @property
    def output_names(self) -> tuple[str, ...]:
        return self._dplant.output_names

    @property
    def x0(self) -> np.ndarray:
        """Initial state of ``dplant`` ``(n_x,)``, read-only."""
        return self._x0

    @property
    def reference(self) -> np.ndarray:
        """:math:`y_d` on the output window ``(N, n_y)``, read-only."""
        return self._reference

    @property
    def loop_reference(self) -> np.ndarray | None:
        r"""The reference r(k) the loop receives at input samples k = 0..N-1 ``(N, n_y)``,
        read-only, or None (learning at the plant input): :math:`y_d` itself with
        ``reference_timing="ahead"``, :math:`y_d(\max(k - s, 0))` with ``"same-sample"``
        (:meth:`~ilc_analysis.problem.LoopReference.loop_reference`)."""
        return self._loop_reference

    @property
    def w(self) -> np.ndarray | None:
        r"""Known state disturbance ``(N, n_x)`` of ``dplant``, held over sample k and applied
        as ``dplant.step(x, v, w, t)`` applies it (zero after the trial), or None.

        Set for :class:`LoopInput` with an LTI plant: :math:`w(k) = E_r\, y_d(k)`, the loop's
        reference entering the composite. The lifting uses it in d; a simulation of the problem
        must add it to any other state disturbance.
        """
        return self._w

    @property
    def u_nominal(self) -> np.ndarray:
        """The learned-signal trajectory ``(N, n_u)`` the lifting is taken along, read-only."""
        return self._u_nominal

    @property
    def u_initial(self) -> np.ndarray | None:
        """The first trial's learned signal when given apart from ``u_nominal`` (else None)."""
        return self._u_initial

    @property
    def first_trial(self) -> str:
        """What the first trial runs, in words: the baseline every reduction factor is counted
        from (``"1270× below trial 1 (zero input)"``).

        * learning at a loop's reference, by default: the loop alone, its reference
          :math:`r = y_d` (:attr:`loop_reference`) with no learned correction;
        * learning at a loop's input, by default: the loop alone, no learned feed-forward;
        * learning at the plant input, by default: zero input (the plant's free response
          from ``x0``); with ``u_initial="reference"`` (a plant whose input is the reference
          of its own loop): the reference itself, the plant's own loop alone;
        * a first input or nominal given as numbers: that input.
        """
        if self._u_initial is not None and not self._first_trial_reference:
            return "the given first input"
        if self._first_trial_reference and isinstance(self._learning_at, PlantInput):
            return "the plant's own loop alone (input = y_d)"
        if self._u_nominal_given and not self._first_trial_reference:
            return "the given nominal input"
        if isinstance(self._learning_at, LoopReference):
            return "the loop alone (reference = y_d)"
        if isinstance(self._learning_at, LoopInput):
            return "the loop alone (no feed-forward)"
        return "zero input"

    @property
    def disturbances(self):
        """The simulation's :class:`~ilc_analysis.simulation.Disturbances`, or None."""
        return self._disturbances

    @property
    def input_times(self) -> np.ndarray:
        """Times of the learned-signal samples v(0..N-1) [s]."""
        return self._t0 + self._ts * np.arange(self._N)

    @property
    def output_times(self) -> np.ndarray:
        """Times of the output window y(s..N-1+s) [s] (where ``reference`` applies)."""
        return self._t0 + self._ts * (self._shift + np.arange(self._N))

    # derived, cached ------------------------------------------------------------------------
    @cached_property
    def lifted(self) -> LiftedSystem:
        r""":math:`y = G v + d`: ``lift(dplant, N, x0, u_nominal, w, t0, shift)``, computed once."""
        return lift(self._dplant, self._N, x0=self._x0, u_nominal=self._u_nominal, w=self._w,
                    t0=self._t0, shift=self._shift)

    @cached_property
    def lifted_plant(self) -> LiftedPlant:
        r""":math:`y = G v + d` with G an operator (never formed): ``lift_operator`` with the
        arguments of :attr:`lifted`, computed once; O(N) memory, any N."""
        return lift_operator(self._dplant, self._N, x0=self._x0, u_nominal=self._u_nominal,
                             w=self._w, t0=self._t0, shift=self._shift)

    @property
    def is_lti(self) -> bool:
        """Whether ``dplant`` is linear time-invariant (its matrices are known)."""
        return self._dplant.matrices is not None

    @cached_property
    def lti_system(self) -> control.StateSpace:
        """The discrete python-control ``StateSpace`` of ``dplant`` (LTI problems only).

        Raises
        ------
        ParameterError
            When the problem is not LTI.
        """
        if not self.is_lti:
            raise ParameterError(f"problem {self._name!r} is not LTI ({self._dplant.name} is "
                                 "nonlinear or time-varying): it has no lti_system; use "
                                 "problem.lifted (the Jacobian along u_nominal)")
        return self._dplant.statespace()

    def initial_input(self) -> np.ndarray:
        """The first trial's learned signal ``(N, n_u)``: ``u_initial`` if given, else
        ``u_nominal``; a fresh copy."""
        return np.array(self._u_nominal if self._u_initial is None else self._u_initial)

    def error(self, y) -> np.ndarray:
        r""":math:`e = y_d - y` on the output window.

        Parameters
        ----------
        y : array_like, shape (N, n_y)
            Outputs y(s..N-1+s).

        Returns
        -------
        ndarray (N, n_y)
        """
        y = as_finite_array(y, "y (outputs on the window)", shape=(self._N, self.n_y))
        return self._reference - y

    @property
    def r(self) -> np.ndarray:
        r""":math:`r = y_d - d` (lifted, ``(N n_y,)``): the error of the trial v = 0 in the lifted
        model, so that :math:`e = r - G v`. From :attr:`lifted` when it was computed, else from
        :attr:`lifted_plant` (G is then never formed)."""
        d = self.lifted.d if "lifted" in self.__dict__ else self.lifted_plant.d
        return self._reference.reshape(-1) - d

    # description ------------------------------------------------------------------------------
    def describe(self) -> dict:
        """A TOML-safe plain dict of the problem without the plant (arrays as nested lists).

        Inverse: :meth:`from_description` (with the plant given separately). Keys: ``name``,
        ``ts``, ``N``, ``t0``, ``shift`` (resolved), ``x0``, ``reference``, ``learning_at``
        (``{"kind": ..., "controller": {"tf": {num, den, dt}} | {"ss": {A, B, C, D, dt}}}``),
        ``discretization`` (``{method, substeps}``), and when given ``u_nominal``,
        ``u_initial`` and ``disturbances``.
        """
        d = {"name": self._name, "ts": self._ts, "N": self._N, "t0": self._t0,
             "shift": self._shift, "x0": self._x0.tolist(),
             "reference": self._reference.tolist(),
             "learning_at": self._learning_at.describe(),
             "discretization": {"method": self._method, "substeps": self._substeps}}
        if self._u_nominal_given:
            d["u_nominal"] = self._u_nominal.tolist()
        if self._first_trial_reference:
            d["u_initial"] = FIRST_TRIAL_REFERENCE
        elif self._u_initial is not None:
            d["u_initial"] = self._u_initial.tolist()
        if self._disturbances is not None:
            dist = self._disturbances
            dd = {k: (np.asarray(getattr(dist, k)).tolist()) for k in _DISTURBANCE_FIELDS}
            if dist.seed is not None:
                dd["seed"] = int(dist.seed)
            d["disturbances"] = dd
        return d

    @classmethod
    def from_description(cls, d, *, plant) -> ILCProblem:
        """The problem of :meth:`describe`'s dict ``d`` on ``plant``.

        Parameters
        ----------
        d : dict
            What :meth:`describe` returned (e.g. read from a design file).
        plant : Plant or DiscretePlant or control.StateSpace
            The plant the description is about (not part of ``d``).

        Raises
        ------
        ParameterError
            Unknown or missing keys (named), or any value the constructor refuses.
        """
        allowed = ("name", "ts", "N", "t0", "shift", "x0", "reference", "learning_at",
                   "discretization", "u_nominal", "u_initial", "disturbances")
        _keys(d, allowed, ("ts", "N", "reference"), "problem description")
        la = d.get("learning_at", {"kind": "plant-input"})
        _keys(la, ("kind", "controller", "reference_timing", "reference_start"), ("kind",),
              "problem description.learning_at")
        kind = la["kind"]
        if kind not in LEARNING_AT_KINDS:
            raise ParameterError(f"problem description.learning_at.kind must be one of "
                                 f"{sorted(LEARNING_AT_KINDS)}; got {kind!r}")
        if kind == "plant-input":
            extra = [k for k in ("controller", "reference_timing", "reference_start") if k in la]
            if extra:
                raise ParameterError(f"problem description.learning_at: kind 'plant-input' "
                                     f"takes no {' and no '.join(extra)} (no loop is closed)")
            learning_at = PlantInput()
        else:
            if "controller" not in la:
                raise ParameterError(f"problem description.learning_at: kind {kind!r} needs a "
                                     "controller")
            controller = controller_from_description(
                la["controller"], "problem description.learning_at.controller")
            try:
                learning_at = LEARNING_AT_KINDS[kind](
                    controller, reference_timing=la.get("reference_timing", "ahead"),
                    reference_start=la.get("reference_start"))
            except ParameterError as exc:
                raise ParameterError(f"problem description.learning_at.{exc}") from exc
        disc = _keys(d.get("discretization", {}), ("method", "substeps"), (),
                     "problem description.discretization")
        dist = d.get("disturbances")
        if dist is not None:
            _keys(dist, (*_DISTURBANCE_FIELDS, "seed"), (), "problem description.disturbances")
            dist = Disturbances(**dist)
        return cls(plant, d["ts"], d["N"], d["reference"], x0=d.get("x0"),
                   shift=d.get("shift"), u_nominal=d.get("u_nominal"),
                   u_initial=d.get("u_initial"), disturbances=dist,
                   learning_at=learning_at, t0=d.get("t0", 0.0),
                   name=d.get("name"), method=disc.get("method", "auto"),
                   substeps=disc.get("substeps", 4))

    @classmethod
    def from_reference_plant_controller(cls, r, P, C, *, ts=None, location: str = "ref",
                                        x0=None, name: str | None = None, method: str = "auto",
                                        substeps: int = 4) -> ILCProblem:
        r"""The problem ``ILCProblem(; r, P, C)`` of IterativeLearningControl.jl, read directly.

        There a problem is the reference r, the plant P and the controller C, with
        :math:`G_r = PC/(1 + PC)` (``feedback(P*C)``) and :math:`G_u = P/(1 + PC)`
        (``feedback(P, C)``), trials from rest on the samples :math:`t = 0, T_s, \dots,
        (N-1)T_s` and

        .. math::

            y_k = G_r\,(r + a_k)\ \ (\texttt{location = :ref}),\qquad
            y_k = G_r\,r + G_u\,a_k\ \ (\texttt{:input}),\qquad e_k = r - y_k,

        every signal at the same sample. The conventions map as follows:

        * ``r`` of shape ``(n_y, N)`` (one row per output, the package's layout) is the
          reference, transposed: ``reference = r.T``, N its number of columns;
        * u = C (r - y), negative feedback: the loop of :class:`LoopReference` (``:ref``, the
          learned signal is :math:`v_k = r + a_k`, the first trial :math:`a = 0`) or
          :class:`LoopInput` (``:input``, :math:`v_k = a_k`), with
          ``reference_timing="same-sample"``;
        * ``shift = 0``: the output window is y(0..N-1), the samples of r, so the lifted
          :math:`G` is the package's lower-triangular Toeplitz matrix of the Markov parameters
          with :math:`h_0 = D` on its diagonal (``hankel_operator``); for a strictly proper
          loop its first row is zero (e(0) cannot be changed) and the last input sample
          changes nothing, as there;
        * ``ts``: the sample time of P (and C), which the package requires discrete (``c2d``).
          Continuous P and C are accepted here with ``ts`` given: the loop is then closed in
          continuous time and sampled, which is not ``feedback(c2d(P)*c2d(C))``.

        For the toolkit's own window (the shift from the relative degree, y_d on y(s..N-1+s))
        with the package's timing, build ``ILCProblem(P, ts, N, y_d,
        learning_at=LoopReference(C, reference_timing="same-sample"))``.

        Parameters
        ----------
        r : array_like, shape (n_y, N) or (N,)
            The reference on the samples 0..N-1, one row per plant output (a 1-D array for one
            output).
        P : control.StateSpace, control.TransferFunction, DiscretePlant or Plant
            The plant.
        C : control.StateSpace or control.TransferFunction
            The controller: proper, n_y inputs, n_u outputs.
        ts : float, optional
            Sample time [s]; default: the sample time of P, else of C (required when both are
            continuous).
        location : {'ref', 'input'}, optional
            Where the adjustment a enters (the package's ``location``, default ``'ref'``).
        x0, name, method, substeps :
            As for :class:`ILCProblem`.

        Returns
        -------
        ILCProblem

        Raises
        ------
        ParameterError
            ``location`` not ``'ref'``/``'input'``; no sample time; P and C sampled at
            different times; anything :class:`ILCProblem` refuses.
        ShapeError
            ``r`` not of shape ``(n_y, N)``.

        Examples
        --------
        >>> import control, numpy as np
        >>> P = control.c2d(control.tf([1.0], [1.0, 1.0]), 0.1)
        >>> C = control.tf([2.0], [1.0], 0.1)
        >>> pr = ILCProblem.from_reference_plant_controller(np.ones((1, 20)), P, C)
        >>> pr.shift, pr.N, pr.learning_at.reference_timing
        (0, 20, 'same-sample')
        """
        kinds = {"ref": LoopReference, "input": LoopInput}
        if location not in kinds:
            raise ParameterError(f"location must be 'ref' (the adjustment is added to the "
                                 f"reference) or 'input' (to the plant input); got "
                                 f"{location!r:.80}")
        if ts is None:
            dts = [float(dt) for dt in (getattr(P, "dt", None), getattr(P, "ts", None),
                                        getattr(C, "dt", None))
                   if isinstance(dt, int | float) and not isinstance(dt, bool) and dt > 0]
            if not dts:
                raise ParameterError("ts (sample time) is required: P and C are continuous "
                                     "(IterativeLearningControl.jl takes them discrete, e.g. "
                                     "c2d(P, ts))")
            ts = dts[0]
        ts = positive(ts, "ts (sample time)")
        n_y = as_model(P, ts).n_y
        r = as_finite_array(r, "r")
        if r.ndim == 1 and n_y == 1:
            r = r[None, :]
        if r.ndim != 2 or r.shape[0] != n_y:
            raise ShapeError(f"r must have shape (n_y, N) = ({n_y}, N): one row per plant "
                             f"output, one column per sample, as in IterativeLearningControl.jl;"
                             f" found shape {r.shape} (for one row per sample give r.T, or use "
                             "ILCProblem(P, ts, N, reference, ...))")
        learning_at = kinds[location](C, reference_timing="same-sample")
        return cls(P, ts, r.shape[1], r.T, x0=x0, shift=0, learning_at=learning_at, name=name,
                   method=method, substeps=substeps)

    # display --------------------------------------------------------------------------------
    def _rows(self) -> list[tuple[str, str]]:
        dp = self._dplant
        return [
            ("plant", f"{dp.name} ({'LTI' if self.is_lti else 'nonlinear / time-varying'}, "
                      f"sampled by {dp.method})"),
            ("learning at", repr(self._learning_at)),
            ("ts, N, shift", f"{self._ts:g} s, {self._N}, {self._shift}"),
            ("learned signal", f"{self.n_u}: {', '.join(self.input_names)}"),
            ("outputs", f"{self.n_y}: {', '.join(self.output_names)}"),
            ("states", f"{self.n_x} ({self._plant_states} plant)"),
            ("window", f"{self.output_times[0]:g} .. {self.output_times[-1]:g} s"),
            ("reference", f"max |y_d| = {np.max(np.abs(self._reference)):.4g}"),
            ("lifted along", "u_nominal given" if self._u_nominal_given else
             (("y_d (servo loop)" if self._learning_at.reference_timing == "ahead" else
               "y_d delayed by the shift (servo loop, same-sample reference)")
              if isinstance(self._learning_at, LoopReference) else "zero")),
            ("first trial", self.first_trial),
            ("known w", "none" if self._w is None else "loop reference"),
            ("disturbances", "none" if self._disturbances is None else "given"),
        ]

    def __repr__(self) -> str:
        return (f"<ILCProblem {self._name!r}: {self._dplant.name}, learning at "
                f"{self._learning_at.kind}, ts={self._ts:g} s, N={self._N}, "
                f"shift={self._shift}, {self.n_u} learned channel(s), {self.n_y} output(s), "
                f"{'LTI' if self.is_lti else 'nonlinear'}>")

    def _repr_html_(self) -> str:
        rows = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                       f"<td style='text-align:left'>{html.escape(v)}</td></tr>"
                       for k, v in self._rows())
        return f"<b>ILCProblem {html.escape(self._name)}</b><table>{rows}</table>"


def is_problem(obj) -> bool:
    """True when ``obj`` is an :class:`ILCProblem`."""
    return isinstance(obj, ILCProblem)
