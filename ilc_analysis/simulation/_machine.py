r"""The simulated machine: one plant run at a time, exactly as :func:`simulate` runs it.

A learning run is a sequence of plant runs. Iteration i runs the trial (experiment 0) and, for
laws that measure something extra (time reversal), experiments 1..m on the same plant. Each run
is one call of the compiled trial (:class:`~ilc_analysis.simulation.CompiledTrial`) with

* initial state :math:`x_0 + \epsilon` (reset error of the run's realisation),
* state disturbance :math:`w(k) + \omega(k)`: the problem's **known** state disturbance
  :math:`w` (e.g. the loop reference when learning at a loop input), given for the lifted input
  samples k = 0..N-1 and zero for k >= N exactly as :func:`ilc_analysis.lifting.lift` puts it
  into d, plus the realised disturbance :math:`\omega` of
  :meth:`Disturbances.realise` (iteration i, experiment k),
* output disturbance :math:`\nu(k)` of the same realisation,
* the current-trial feedback (:math:`\Psi_2, \Phi_2`) inside the trial — for the trial
  (experiment 0) only; extra experiments apply their input open loop.

A linear plant runs by compiled linear filtering (:class:`~ilc_analysis.simulation.
_linear_trial.LinearTrial`), a nonlinear one as the compiled CasADi trial. Disturbances without
noise or reset error are the same in every run: they are realised once.

:func:`simulate` runs its plant through this class, and a user (or a test) driving a
:class:`~ilc_analysis.simulation._learner.Learner` can use it as a stand-in for the real machine
and get the same realisation.
"""

from __future__ import annotations

import functools

import numpy as np

from .._validation import as_finite_array, as_vector, positive_int, real
from ..exceptions import ParameterError, ShapeError
from ..model import DiscretePlant
from ..problem._disturbances import NO_DISTURBANCES, Disturbances
from ._linear_trial import LinearTrial
from ._trial import TrialRecord, compiled_trial

__all__ = ["SimulatedMachine", "known_disturbance"]


def known_disturbance(w, N: int, shift: int, n_x: int) -> np.ndarray:
    r"""The known state disturbance on the K = N + s trial samples, ``(K, n_x)``.

    ``w`` is given on the lifted input samples k = 0..N-1 (``(N, n_x)``, or None for zero); the
    samples k = N..N+s-1 are zero, as in :func:`ilc_analysis.lifting.lift` (its
    :math:`d_j = \dots + \sum_{k} C A^{s+j-1-k} E\,w(k)` reads w only for k < N).

    Parameters
    ----------
    w : array_like, shape (N, n_x), or None
        The known state disturbance on the input samples k = 0..N-1 (finite); None for zero.
    N : int
        Number of lifted input samples.
    shift : int
        Sampled relative degree s: the number of zero samples appended.
    n_x : int
        Number of states.

    Returns
    -------
    ndarray, shape (N + shift, n_x)

    Raises
    ------
    ShapeError, ParameterError
        If ``w`` does not have shape ``(N, n_x)`` or is not finite.
    """
    out = np.zeros((N + shift, n_x))
    if w is not None:
        out[:N] = as_finite_array(w, "w (known state disturbance on the input samples, (N, n_x))",
                                  shape=(N, n_x))
    return out


class SimulatedMachine:
    r"""The plant of a learning run, run one trial or extra experiment at a time (module docs).

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant the learned signal drives.
    y_d : array_like, shape (N, n_y)
        Reference on the output window (the current-trial feedback's error is
        :math:`y_d(k-s) - y(k)`).
    x0 : array_like, shape (n_x,)
        Initial state of every run (before reset errors).
    shift : int
        Sampled relative degree s >= 1.
    t0 : float
        Time of sample 0 [s].
    w : array_like (N, n_x), optional
        Known state disturbance on the input samples (:func:`known_disturbance`).
    disturbances : Disturbances, optional
        Realised per run (iteration, experiment); none by default.
    feedback : tuple (Psi2, Phi2) of arrays (N, n_u, n_y), optional
        Current-trial gains applied inside the trial (experiment 0); default zero.
    entropy : int, optional
        Root seed of the noise streams; default ``disturbances.root_entropy()`` (the seed, or
        fresh entropy). Use the ``seed`` attribute of a :func:`simulate` result to repeat it.
    jit : bool or None
        Compile a nonlinear plant's trial to C (:func:`compiled_trial`: None, the default,
        where a C compiler is found); a linear plant runs by linear filtering either way, its
        modes solved by the compiled first-order kernel or, with ``jit=False`` (or no
        compiler), by BLAS (:class:`~ilc_analysis.simulation._linear_trial.ModalRecursion`).
    runs : int, optional
        Plant runs the caller expects (trials and extra experiments): with ``jit=None`` a short
        run compiles only a step already on disk (:data:`~ilc_analysis.simulation._trial.
        COMPILE_MIN_STEPS`).
    """

    def __init__(self, dplant: DiscretePlant, y_d, x0, *, shift: int, t0: float = 0.0, w=None,
                 disturbances: Disturbances | None = None, feedback=None,
                 entropy: int | None = None, jit: bool | None = None,
                 runs: int | None = None) -> None:
        if not isinstance(dplant, DiscretePlant):
            raise ParameterError(f"dplant must be a DiscretePlant; got {type(dplant).__name__}")
        n_x, n_u, n_y = dplant.n_x, dplant.n_u, dplant.n_y
        self.y_d = as_finite_array(y_d, "y_d (reference on the lifted window)",
                                   shape=(None, n_y))
        self.N = positive_int(self.y_d.shape[0], "N (rows of y_d)")
        self.shift = positive_int(shift, "shift", minimum=0)
        self.t0 = real(t0, "t0")
        self.x0 = as_vector(x0, "x0", n_x)
        self.dplant = dplant
        self.w = known_disturbance(w, self.N, self.shift, n_x)
        self.disturbances = NO_DISTURBANCES if disturbances is None else disturbances
        if not isinstance(self.disturbances, Disturbances):
            raise ParameterError(f"disturbances must be a Disturbances or None; got "
                                 f"{type(self.disturbances).__name__}")
        self.disturbances.check_dimensions(n_x, n_y)
        if feedback is None:
            z = np.zeros((self.N, n_u, n_y))
            feedback = (z, z)
        psi2, phi2 = feedback
        self.psi2 = np.array(as_finite_array(psi2, "Psi2 (current-trial gains)",
                                             shape=(self.N, n_u, n_y)))
        self.phi2 = np.array(as_finite_array(phi2, "Phi2 (current-trial gains)",
                                             shape=(self.N, n_u, n_y)))
        for gains in (self.psi2, self.phi2):     # fixed for the machine's life (own copies)
            gains.setflags(write=False)
        self._zero_gains = np.zeros((self.N, n_u, n_y))
        if self.shift == 0 and self.has_feedback:
            raise ParameterError("shift 0 (direct feedthrough from the learned signal to the "
                                 "output) with current-trial gains Psi2, Phi2: the feedback of "
                                 "e(k) into u(k) would form an algebraic loop; a law with a "
                                 "current-trial term needs a strictly proper problem (shift >= "
                                 "1), a law without one runs at shift 0")
        if entropy is None:
            entropy = self.disturbances.root_entropy()
        elif isinstance(entropy, bool) or not isinstance(entropy, int | np.integer) \
                or entropy < 0:
            raise ParameterError(f"entropy must be a non-negative integer (a root seed) or None; "
                                 f"got {entropy!r}")
        self.entropy = int(entropy)
        self.t = self.t0 + dplant.ts * np.arange(self.N + self.shift)
        self.trial = (linear_trial(dplant, self.N, self.shift, jit) if dplant.matrices is not None
                      else compiled_trial(dplant, self.N, self.shift, jit,
                                          None if runs is None else runs * (self.N + self.shift)))
        self._random = self.disturbances.is_random
        self._fixed = None if self._random else self._realise(1, 0)

    @property
    def window(self) -> slice:
        """The output window's rows in a record: samples s .. N-1+s."""
        return slice(self.shift, self.N + self.shift)

    @property
    def has_feedback(self) -> bool:
        """Whether the trial applies a current-trial feedback (non-zero Ψ2 or Φ2)."""
        return bool(np.any(self.psi2) or np.any(self.phi2))

    @classmethod
    def from_problem(cls, problem, law=None, *, disturbances: Disturbances | None = None,
                     entropy: int | None = None,
                     jit: bool | None = None) -> SimulatedMachine:
        """The machine of ``problem`` (its dplant, reference, x0, shift, t0, w, disturbances);
        with ``law`` (a LearningLaw) the trial applies the law's current-trial feedback, as the
        real machine's loop would (PDLaw's Ψ2, Φ2).

        Parameters
        ----------
        problem : ILCProblem
            The problem whose plant, reference, initial state, shift, t0, known disturbance
            and disturbances the machine uses.
        law : LearningLaw, optional
            Its current-trial feedback (non-zero only for a PDLaw's Ψ2, Φ2) is applied inside
            each trial; default none (open loop).
        disturbances : Disturbances, optional
            Replaces ``problem.disturbances``.
        entropy : int, optional
            Root seed of the noise streams (as for the constructor).
        jit : bool or None, optional
            Compile a nonlinear plant's trial to C (default None: where a C compiler is
            found).

        Returns
        -------
        SimulatedMachine

        Raises
        ------
        ParameterError, ShapeError
            If ``problem`` is not an ILCProblem, or ``law`` does not fit it.
        """
        from ._law_adapter import as_problem, problem_law

        problem = as_problem(problem)
        feedback = None
        if law is not None:
            adapter = problem_law(law, problem)
            feedback = adapter.feedback_gains(problem.N, problem.n_u, problem.n_y)
        return cls(problem.dplant, problem.reference, problem.x0, shift=problem.shift,
                   t0=problem.t0, w=problem.w,
                   disturbances=problem.disturbances if disturbances is None else disturbances,
                   feedback=feedback, entropy=entropy, jit=jit)

    def run(self, ff, iteration: int, experiment: int = 0) -> TrialRecord:
        r"""Run one plant run and return its full record (samples k = 0..N+s-1).

        Parameters
        ----------
        ff : array_like, shape (N, n_u)
            The input (the feed-forward, for a trial with current-trial feedback).
        iteration : int
            The iteration (trial number, from 1): selects the disturbance realisation.
        experiment : int
            0 for the trial, k >= 1 for the k-th extra experiment of the iteration (open loop).
        """
        n_u = self.dplant.n_u
        ff = as_finite_array(ff, "ff (input of the run, (N, n_u))", shape=(self.N, n_u))
        iteration = positive_int(iteration, "iteration")
        if isinstance(experiment, bool) or not isinstance(experiment, int | np.integer) \
                or experiment < 0:
            raise ParameterError(f"experiment must be an integer >= 0; got {experiment!r}")
        return self.run_checked(ff, iteration, int(experiment))

    def run_checked(self, ff: np.ndarray, iteration: int, experiment: int = 0,
                    out: TrialRecord | None = None) -> TrialRecord:
        """:meth:`run` on arguments already validated: the engine's call.

        Parameters
        ----------
        ff : numpy.ndarray
            The trial's input on the window, finite floats of shape ``(N, n_u)``.
        iteration : int
            The trial number, ``>= 1`` (selects the disturbance realisation).
        experiment : int, optional
            ``0`` for the closed-loop run with the current-trial gains, ``>= 1`` for an
            identification experiment run with them switched off.
        out : TrialRecord, optional
            The arrays to write the record into (a run's store,
            :class:`~ilc_analysis.simulation._store.RunStore`, or
            :func:`~ilc_analysis.simulation._trial.new_record`), overwritten; default new
            arrays.

        Returns
        -------
        TrialRecord
            The full record of the run (``N + s`` samples; ``out`` when given).
        """
        x0, w, nu = self._fixed if self._fixed is not None else self._realise(iteration,
                                                                               experiment)
        if experiment == 0:
            psi2, phi2 = self.psi2, self.phi2
        else:
            psi2 = phi2 = self._zero_gains
        return self.trial.run(x0, ff, self.y_d, psi2, phi2, w, nu, self.t, out=out)

    def _realise(self, iteration: int, experiment: int):
        """(initial state, state disturbance, output disturbance) of one run (read-only: a
        realisation without noise serves every run, and a trial may keep facts about it)."""
        dist = self.disturbances.realise(iteration, self.t, self.dplant.n_x, self.dplant.n_y,
                                         self.entropy, experiment=experiment)
        parts = (self.x0 + dist.reset, self.w + dist.w, np.array(dist.nu, dtype=float))
        for part in parts:
            part.setflags(write=False)
        return parts

    def output_window(self, rec: TrialRecord) -> np.ndarray:
        """The measured output on the window, ``(N, n_y)``, of a record.

        Parameters
        ----------
        rec : TrialRecord
            The full record of one run of this machine (``N + s`` samples).

        Raises
        ------
        ShapeError
            If the record does not have ``N + s`` samples.
        """
        if rec.y.shape[0] != self.N + self.shift:
            raise ShapeError(f"the record must have {self.N + self.shift} samples; found "
                             f"{rec.y.shape[0]}")
        return rec.y[self.window]


@functools.lru_cache(maxsize=8)
def linear_trial(dplant: DiscretePlant, N: int, shift: int,
                 jit: bool | None = None) -> LinearTrial:
    """A cached :class:`~ilc_analysis.simulation._linear_trial.LinearTrial` (the Schur forms
    are computed once per plant, N, s, ``jit`` and current-trial gains)."""
    return LinearTrial(dplant, N, shift, jit)
