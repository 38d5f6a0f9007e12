r"""A :class:`~ilc_analysis.laws.LearningLaw` on an ILC problem, as the engine's (private) law.

The engine (:func:`~ilc_analysis.simulation.simulate`) runs a trial with a current-trial
feedback compiled into it and computes the next trial's feed-forward between trials. A
:class:`~ilc_analysis.laws.LearningLaw` on an :class:`~ilc_analysis.problem.ILCProblem` maps
onto that as follows (:class:`ProblemLaw`):

* :class:`~ilc_analysis.laws.PDLaw` (eq 11): the current-trial gains :math:`\Psi_2, \Phi_2`
  act inside the trial, the between-trial part
  :math:`Q[a u_0 + (1-a)u_i + \Psi_1 e_i + \Phi_1\Delta e_i/T_s]` (with the forgetting factor
  it used) between trials; :math:`u_0` is the law's own ``u0`` (zero by
  default): the input the forgetting pulls towards;
* every other law: no feedback inside the trial (:math:`\Psi_2 = \Phi_2 = 0`), the next
  feed-forward is ``law.update(u_i, e_i, ts)``, and the recorded forgetting factor is zero;
  a law that runs extra experiments per iteration (:meth:`LearningLaw.experiments_per_iteration`
  > 1, e.g. :class:`~ilc_analysis.laws.TimeReversalLaw`) gets ``experiment=`` (a callable
  input ``(N, n_u)`` -> measured output window ``(N, n_y)`` running the plant);
* the first trial's feed-forward is ``problem.initial_input()`` for every law.
"""

from __future__ import annotations

import abc
import json
from typing import Any

import numpy as np

from ..exceptions import ParameterError, ShapeError
from ..laws import LearningLaw, PDLaw
from ..laws._base import as_problem
from ..problem._problem import is_problem
from ..problem._trial_spec import is_trial_spec

__all__ = ["ProblemLaw", "problem_law", "as_problem", "as_trial", "is_problem"]


def as_trial(problem):
    """``problem`` if it is an :class:`~ilc_analysis.problem.ILCProblem` or a model-free
    :class:`~ilc_analysis.problem.TrialSpec`, else ParameterError.

    Parameters
    ----------
    problem : ILCProblem or TrialSpec
        The trial a learner runs on.

    Raises
    ------
    ParameterError
        Anything else.
    """
    if is_trial_spec(problem):
        return problem
    if not is_problem(problem):
        raise ParameterError(f"problem must be an ILCProblem or a TrialSpec "
                             f"(ilc_analysis.problem); got {type(problem).__name__}")
    return problem


class _EngineLaw(abc.ABC):
    """What the engine (:func:`~ilc_analysis.simulation.simulate`) needs from a law (private:
    the public laws are :mod:`ilc_analysis.laws`; ``ILCLaw`` is the old name of this protocol).

    Subclasses provide the current-trial feedback gains (compiled into the trial), the first
    trial's feed-forward and the between-trial update.
    """

    name: str = "ilc"

    @abc.abstractmethod
    def check_dimensions(self, N: int, n_u: int, n_y: int, ts: float, shift: int) -> None:
        """Raise :class:`ShapeError`/:class:`ParameterError` unless the law fits the plant.

        Parameters
        ----------
        N : int
            Number of samples of the lifted window (trial length).
        n_u : int
            Number of plant inputs.
        n_y : int
            Number of plant outputs.
        ts : float
            Sample time [s].
        shift : int
            Shift s of the lifted error :math:`e(j) = y_d(j) - y(j+s)` (sampled relative
            degree).

        Raises
        ------
        ShapeError
            If the gains, ``u0`` or the lifted model do not fit ``N``, ``n_u``, ``n_y``.
        ParameterError
            If the law was set up for another ``shift``.
        """

    @abc.abstractmethod
    def feedback_gains(self, N: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
        r"""Current-trial gains :math:`(\Psi_2, \Phi_2)`, each ``(N, n_u, n_y)``.

        Parameters
        ----------
        N : int
            Number of samples of the lifted window.
        n_u : int
            Number of plant inputs.
        n_y : int
            Number of plant outputs.

        Returns
        -------
        tuple of ndarray
            :math:`(\Psi_2(k), \Phi_2(k))` per sample k, each of shape ``(N, n_u, n_y)``
            (zeros for a law without current-trial feedback).
        """

    @abc.abstractmethod
    def initial_feedforward(self, N: int, n_u: int) -> np.ndarray:
        """The feed-forward of the first trial, ``(N, n_u)``.

        Parameters
        ----------
        N : int
            Number of samples of the lifted window.
        n_u : int
            Number of plant inputs.

        Returns
        -------
        ndarray, shape (N, n_u)
            :math:`u_0` held over the window (or per sample).
        """

    @abc.abstractmethod
    def next_feedforward(self, u, e, ts: float, out: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray | None]:
        """Between trials: the feed-forward of trial i+1 from the record of trial i.

        Parameters
        ----------
        u : ndarray, shape (N, n_u)
            The input applied in trial i (feed-forward plus current-trial feedback).
        e : array_like, shape (N, n_y)
            The lifted error of trial i, :math:`e_i(j) = y_d(j) - y_i(j+s)`.
        ts : float
            Sample time [s] (difference quotients, Q-filter).
        out : ndarray, shape (N, n_u), optional
            Where the law may write :math:`f_{i+1}` (the run's row for the next trial's
            input; not overlapping ``u`` or ``e``).

        Returns
        -------
        f_next : ndarray, shape (N, n_u)
            The feed-forward :math:`f_{i+1}` (``out`` when the law wrote it there).
        a : ndarray, shape (N,), or None
            The forgetting factor :math:`a(i, k)` used; None for a law without forgetting.
        """

    def describe(self) -> dict:
        """Plain (netCDF-attribute-safe) description of the law."""
        return {"law": self.name}


class _PDEngineLaw(_EngineLaw):
    """A :class:`~ilc_analysis.laws.PDLaw` as the engine's law: its current-trial gains inside
    the trial, :meth:`~ilc_analysis.laws.PDLaw.between_trials` between trials, its ``u0`` as
    the first trial's feed-forward (the plant form ``simulate(dplant, law, y_d, ...)``).

    Parameters
    ----------
    law : PDLaw
        The law of eq (11).
    """

    def __init__(self, law: PDLaw) -> None:
        if not isinstance(law, PDLaw):
            raise ParameterError(f"law must be a PDLaw; got {type(law).__name__}")
        self.law = law
        self.name = law.name

    def check_dimensions(self, N: int, n_u: int, n_y: int, ts: float, shift: int) -> None:
        self.law.check_trial(N, n_u, n_y)

    def feedback_gains(self, N: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
        return self.law.feedback_gains(N)

    def initial_feedforward(self, N: int, n_u: int) -> np.ndarray:
        return self.law.u0_trial(N, n_u)

    def next_feedforward(self, u, e, ts: float, out: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray | None]:
        return self.law._next_feedforward(u, e, ts, out)

    def describe(self) -> dict:
        out = {"law": self.law.name, "lead": self.law.gains.lead,
               "time_varying_gains": int(self.law.gains.time_varying),
               "forgetting": type(self.law.forgetting).__name__}
        out.update({f"forgetting_{k}": v for k, v in self.law.forgetting.as_dict().items()})
        if not self.law.gains.time_varying:
            for k in ("Phi1", "Phi2", "Psi1", "Psi2"):
                out[k] = np.asarray(getattr(self.law.gains, k)).ravel()
        if self.law.q_filter is not None:
            out.update({f"q_filter_{k}": v for k, v in self.law.q_filter.as_dict().items()})
        return out


def engine_law(law) -> _EngineLaw:
    """``law`` for the plant form of the engine: an engine law as it is, a
    :class:`~ilc_analysis.laws.PDLaw` through :class:`_PDEngineLaw`.

    Raises
    ------
    ParameterError
        Any other object.
    """
    if isinstance(law, _EngineLaw):
        return law
    if isinstance(law, PDLaw):
        return _PDEngineLaw(law)
    raise ParameterError(f"law must be a PDLaw (ilc_analysis.laws) for simulate(dplant, law, y_d, "
                         f"iterations, x0); got {type(law).__name__} (any LearningLaw runs with "
                         f"simulate(problem, law, iterations))")


def _plain(value):
    """JSON-safe form of a law description (arrays as lists)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return repr(value)


def law_description_json(law: LearningLaw) -> str:
    """``law.describe()`` as canonical JSON (sorted keys): for attributes and fingerprints."""
    return json.dumps(_plain(law.describe()), sort_keys=True, separators=(",", ":"))


class ProblemLaw(_EngineLaw):
    """``law`` on ``problem`` as the engine's law (module docstring).

    Parameters
    ----------
    law : LearningLaw
        The learning law (a :class:`~ilc_analysis.laws.PDLaw` runs as eq 11 with its
        current-trial feedback inside the trial; any other law between trials only).
    problem : ILCProblem or TrialSpec
        The problem it runs on: window length, dimensions, sample time, shift and the first
        trial's input ``problem.initial_input()``. A :class:`~ilc_analysis.problem.TrialSpec`
        (no plant model) takes only a law that checks its trial without the lifted model
        (a :class:`~ilc_analysis.laws.PDLaw`, or a law with a ``check_problem`` method, e.g.
        :class:`~ilc_analysis.laws.QLLaw`).

    Raises
    ------
    ParameterError
        If ``law`` is not a :class:`~ilc_analysis.laws.LearningLaw`, ``problem`` is neither an
        :class:`~ilc_analysis.problem.ILCProblem` nor a
        :class:`~ilc_analysis.problem.TrialSpec`, the law needs a plant model the trial does
        not have, or the law does not fit the problem.
    ShapeError
        If the gains or ``problem.initial_input()`` do not fit the problem's dimensions.

    Attributes
    ----------
    law : LearningLaw
        The wrapped law.
    extra_experiments : int
        Plant runs per iteration besides the trial (``law.experiments_per_iteration - 1``).
    """

    def __init__(self, law: LearningLaw, problem) -> None:
        if not isinstance(law, LearningLaw):
            raise ParameterError(
                f"law must be a LearningLaw (ilc_analysis.laws: PDLaw, QLLaw, GradientLaw, "
                f"NormOptimalLaw, TimeReversalLaw) to run on an ILCProblem; got "
                f"{type(law).__name__}")
        problem = as_trial(problem)
        N, n_u, n_y = problem.N, problem.n_u, problem.n_y
        if is_trial_spec(problem) and not isinstance(law, PDLaw) \
                and not callable(getattr(law, "check_problem", None)):
            raise ParameterError(f"{law.name} is set up on the lifted plant model; the trial "
                                 f"{problem.name!r} has no model (a TrialSpec): only a law that "
                                 f"needs no model runs on it (a PDLaw, or a QLLaw with its "
                                 f"filters)")
        if isinstance(law, PDLaw):
            # what PDLaw.check does, without forcing the lifting (not needed to run eq 11)
            self._pd: PDLaw | None = law
            law.check_trial(N, n_u, n_y)
        else:
            self._pd = None
            check_problem = getattr(law, "check_problem", None)
            if callable(check_problem):       # the trial's shape, without lifting the problem
                check_problem(problem)
            else:
                law.check(problem.lifted)
        self.law = law
        self.name = law.name
        self._dims = (N, n_u, n_y)
        self._initial = np.array(problem.initial_input(), dtype=float)
        if self._initial.shape != (N, n_u):
            raise ShapeError(f"problem.initial_input() must have shape {(N, n_u)}; found "
                             f"{self._initial.shape}")
        self.extra_experiments = int(law.experiments_per_iteration(problem.n_u, problem.n_y)) - 1
        if self.extra_experiments < 0:
            raise ParameterError(f"{law.name}: experiments_per_iteration must be >= 1")

    @property
    def experiments_per_iteration(self) -> int:
        """Plant runs per iteration: the trial and the law's extra experiments."""
        return 1 + self.extra_experiments

    @property
    def uses_states(self) -> bool:
        """Whether the update needs the trial's measured states (``states=`` of
        :meth:`next_feedforward`; e.g. a constrained law with state bounds)."""
        return self._pd is None and bool(getattr(self.law, "uses_states", False))

    def check_dimensions(self, N: int, n_u: int, n_y: int, ts: float, shift: int) -> None:
        if (N, n_u, n_y) != self._dims:
            raise ShapeError(f"the law was set up on a problem with (N, n_u, n_y) = "
                             f"{self._dims}; the simulation has {(N, n_u, n_y)}")
        if self._pd is not None:
            self._pd.check_trial(N, n_u, n_y)

    def feedback_gains(self, N: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
        if self._pd is not None:
            return self._pd.feedback_gains(N)
        z = np.zeros((N, n_u, n_y))
        return z, z.copy()

    def initial_feedforward(self, N: int, n_u: int) -> np.ndarray:
        return self._initial.copy()

    def next_feedforward(self, u, e, ts: float, out: np.ndarray | None = None,
                         experiment=None, states=None) -> tuple[np.ndarray, np.ndarray | None]:
        """``(f_{i+1}, a_i)``: the next trial's feed-forward and the forgetting factor used.

        Parameters
        ----------
        u : ndarray, shape (N, n_u)
            The input applied in trial i.
        e : array_like, shape (N, n_y)
            The lifted error of trial i.
        ts : float
            Sample time [s].
        out : ndarray, shape (N, n_u), optional
            Where a :class:`~ilc_analysis.laws.PDLaw` writes :math:`f_{i+1}` (the run's row
            for the next trial's input; not overlapping ``u`` or ``e``); other laws return a
            new array.
        experiment : callable, optional
            Input ``(N, n_u)`` -> measured output window ``(N, n_y)``, running the plant;
            required iff the law runs extra experiments per iteration, ignored otherwise.
        states : ndarray, shape (N + s, n_x), optional
            The trial's states x(0..N+s-1); required by a law whose ``uses_states`` is true
            (e.g. a constrained law with state bounds), ignored otherwise.

        Returns
        -------
        f_next : ndarray, shape (N, n_u)
            The feed-forward :math:`f_{i+1}`.
        a : ndarray, shape (N,), or None
            The forgetting factor used (None for every law but a PDLaw with forgetting).

        Raises
        ------
        ParameterError
            If the law needs ``states`` or ``experiment`` and it is None.
        """
        if self._pd is not None:
            return self._pd._next_feedforward(u, e, ts, out)
        # the laws that take states= or experiment= extend LearningLaw.update's signature
        law: Any = self.law
        if getattr(law, "uses_states", False):
            if states is None:
                raise ParameterError(f"{self.name} needs the trial's measured states (it has "
                                     f"state bounds): pass states=")
            ff = law.update(u, e, ts, states=states)
        elif self.extra_experiments:
            if experiment is None:
                raise ParameterError(f"{self.name} runs {self.extra_experiments} extra "
                                     f"experiment(s) per iteration: pass experiment (a callable "
                                     f"input (N, n_u) -> output window (N, n_y))")
            ff = law.update(u, e, ts, experiment=experiment)
        else:
            ff = law.update(u, e, ts)
        return np.asarray(ff, dtype=float), None

    def describe(self) -> dict:
        kind = self.law.describe().get("law", type(self.law).__name__)
        return {"law": self.name, "law_kind": str(kind),
                "law_parameters": law_description_json(self.law),
                "experiments_per_iteration": self.experiments_per_iteration}


def problem_law(law, problem) -> ProblemLaw:
    """:class:`ProblemLaw` of ``law`` on ``problem`` (validated).

    Parameters
    ----------
    law : LearningLaw or ProblemLaw
        The law; a :class:`ProblemLaw` is returned as it is.
    problem : ILCProblem
        The problem the law runs on.

    Returns
    -------
    ProblemLaw

    Raises
    ------
    ParameterError, ShapeError
        As :class:`ProblemLaw`.
    """
    return law if isinstance(law, ProblemLaw) else ProblemLaw(law, problem)
