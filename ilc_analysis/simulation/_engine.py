r"""Trial-by-trial learning simulation.

For i = 1, 2, ...: run trial i as one compiled CasADi function (the current-trial feedback
acts inside it, sample by sample; :mod:`~ilc_analysis.simulation._trial`), check that it stayed
admissible (:mod:`~ilc_analysis.simulation._divergence`), record it, and compute the next
trial's feed-forward from it with the law's between-trial update (vectorised numpy;
:mod:`~ilc_analysis.simulation._law_adapter`).

The public entry point is ``simulate(problem, law, iterations)``: any
:class:`~ilc_analysis.laws.LearningLaw` on an :class:`~ilc_analysis.problem.ILCProblem` (the law
mapped by :mod:`~ilc_analysis.simulation._law_adapter`, extra experiments run and counted).
Privately, :func:`simulate_problem` is that form and :func:`simulate_plant` runs a
:class:`~ilc_analysis.laws.PDLaw` on a bare :class:`~ilc_analysis.model.DiscretePlant` with a
reference and an initial state (the engine under both; used by the paper pipeline and the
engine's tests). Each plant run is made by
:class:`~ilc_analysis.simulation._machine.SimulatedMachine`.

Index convention (:mod:`ilc_analysis.laws`): ``y_d`` is given on the lifted output window,
:math:`y_d(j)` at time :math:`t_0 + (j+s)T_s`, j = 0..N-1 (use :func:`window_times`); the
lifted input is :math:`u(0..N-1)` at :math:`t_0 + jT_s`.
"""

from __future__ import annotations

import functools
import json
import math
import re
import warnings

import casadi as ca
import numpy as np
import pandas as pd
import xarray as xr
from xarray.indexes import PandasIndex

from .._arrays import long_matmul, narrow_reduce
from .._progress import tracked
from .._validation import (
    MAX_ITERATIONS,
    MAX_TRIAL_SAMPLES,
    as_finite_array,
    as_vector,
    check_allocation,
    positive_int,
    real,
)
from ..exceptions import (
    DivergenceError,
    ILCDeprecationWarning,
    InternalError,
    ParameterError,
    ShapeError,
)
from ..lifting import sampled_shift
from ..model import DiscretePlant
from ..problem._disturbances import NO_DISTURBANCES, Disturbances
from ._divergence import DivergenceBounds, first_violation
from ._law_adapter import ProblemLaw, _EngineLaw, engine_law, is_problem, problem_law
from ._machine import SimulatedMachine
from ._results import DEFAULT_UNITS, DivergenceInfo, ILCResult
from ._store import RunStore
from ._trial import TrialRecord, window_times

__all__ = ["simulate", "simulate_problem", "simulate_plant", "ON_DIVERGENCE"]

ON_DIVERGENCE = ("stop", "raise")


def _units(names, units) -> list[str]:
    return [units.get(n, DEFAULT_UNITS.get(n, "-")) for n in names]


def _common_unit(names, units) -> dict:
    """``{"units": u}`` when every channel of ``names`` has the one declared unit u (a CF
    ``units`` attribute of a variable over those channels), else nothing (the per-channel
    units are the ``*_units`` coordinates)."""
    found = set(_units(names, units))
    return {"units": found.pop()} if len(found) == 1 and "-" not in found else {}


def _variable_name(name: str, taken) -> str:
    """A CF-valid netCDF variable name for a plant's signal ``name`` (a letter, then letters,
    digits and ``_``), distinct from ``taken``."""
    key = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9_]", "_", name)).strip("_")
    if not key[:1].isalpha():
        key = f"signal_{key}".rstrip("_")
    while key in taken:
        key = f"signal_{key}"
    return key


def _record_width(dplant: DiscretePlant) -> int:
    """Values :func:`simulate` keeps per trial sample: x, u, u_ff, y, e, a and the signals."""
    return dplant.n_x + 2 * dplant.n_u + 2 * dplant.n_y + 1 + len(dplant.signal_names)


def _validate(dplant, law, y_d, iterations, x0, N, shift, t0, disturbances, bounds,
              on_divergence, units):
    if not isinstance(dplant, DiscretePlant):
        raise ParameterError(f"dplant must be a DiscretePlant (see ilc_analysis.model."
                             f"discretize), or an ILCProblem for simulate(problem, law, "
                             f"iterations); got {type(dplant).__name__}")
    if not isinstance(law, _EngineLaw):
        raise InternalError(f"the engine got {type(law).__name__}, not an engine law "
                            f"(simulate_plant and simulate_problem convert every law)")
    iterations = positive_int(iterations, "iterations", maximum=MAX_ITERATIONS)
    x0 = as_vector(x0, "x0", dplant.n_x)
    if N is not None:
        N = positive_int(N, "N", maximum=MAX_TRIAL_SAMPLES)
    y_d = as_finite_array(y_d, "y_d (reference on the lifted window)", shape=(N, dplant.n_y))
    N = positive_int(y_d.shape[0], "N (samples per trial: rows of y_d)",
                     maximum=MAX_TRIAL_SAMPLES)
    if N < 2:
        raise ParameterError(f"the trial needs N >= 2 samples; y_d has {N}")
    width = _record_width(dplant)
    check_allocation(iterations * N * width,
                     f"iterations = {iterations} and N = {N}: the simulation record "
                     f"(iterations x N x {width} values)")
    t0 = real(t0, "t0")
    disturbances = NO_DISTURBANCES if disturbances is None else disturbances
    if not isinstance(disturbances, Disturbances):
        raise ParameterError(f"disturbances must be a Disturbances or None; got "
                             f"{type(disturbances).__name__}")
    disturbances.check_dimensions(dplant.n_x, dplant.n_y)
    bounds = DivergenceBounds() if bounds is None else bounds
    if not isinstance(bounds, DivergenceBounds):
        raise ParameterError(f"bounds must be a DivergenceBounds or None; got "
                             f"{type(bounds).__name__}")
    if on_divergence not in ON_DIVERGENCE:
        raise ParameterError(f"on_divergence must be one of {ON_DIVERGENCE}; "
                             f"got {on_divergence!r}")
    if units is not None and not isinstance(units, dict):
        raise ParameterError(f"units must be a dict {{channel name: unit}}; got {units!r}")
    if shift is None:
        shift = sampled_shift(dplant, x=x0, t=t0)
    else:
        shift = positive_int(shift, "shift", minimum=0)
    # shift 0 (direct feedthrough) runs for a law without a current-trial term; the machine
    # refuses one with it (an algebraic loop)
    law.check_dimensions(N, dplant.n_u, dplant.n_y, dplant.ts, shift)
    return iterations, x0, y_d, N, shift, t0, disturbances, bounds, dict(units or {})


def simulate(system, law, *args, **options) -> ILCResult:
    r"""Simulate ``iterations`` trials of the learning law ``law`` on the ILC problem.

    ``simulate(problem, law, iterations, *, disturbances=None, bounds=None,
    on_divergence='stop', jit=None, units=None, entropy=None)``. Trial i runs the plant
    ``problem.dplant`` from ``problem.x0`` with the feed-forward :math:`f_i` (the first one
    ``problem.initial_input()``) and, for a :class:`~ilc_analysis.laws.PDLaw`, its current-trial
    feedback :math:`\Psi_2 e_i(k-s) + \Phi_2 \Delta e_i(k-s)/T_s` inside the trial; between
    trials the law computes :math:`f_{i+1}` from :math:`(u_i, e_i)`, with
    :math:`e_i(j) = y_d(j) - y_i(j+s)` on the lifted window.

    Parameters
    ----------
    system : ILCProblem
        The problem: plant, reference, initial state, shift, t0, known disturbance, default
        disturbances and the first trial's input.
    law : LearningLaw
        Any :class:`~ilc_analysis.laws.LearningLaw` set up for the problem.
    *args
        ``iterations``: number of trials (1 to
        :data:`~ilc_analysis._validation.MAX_ITERATIONS`).
    **options
        ``disturbances`` (replaces ``problem.disturbances``), ``bounds``
        (:class:`DivergenceBounds`), ``on_divergence`` (``'stop'`` or ``'raise'``), ``jit``,
        ``units``, ``entropy`` (root seed of the noise streams).

    Returns
    -------
    ILCResult
        The trials as an ``xarray.Dataset`` (inputs, outputs, errors, states, forgetting
        factors, per-iteration metrics, plant runs per iteration) and the divergence, if any.

    Raises
    ------
    ParameterError, ShapeError
        If ``system`` is not an ILCProblem, ``law`` not a LearningLaw fitting it, or bad options
        (a DiscretePlant as ``system`` is the deprecated plant form: it still runs for one
        release and warns :class:`~ilc_analysis.exceptions.ILCDeprecationWarning`).
    DivergenceError
        Only with ``on_divergence='raise'``.

    Notes
    -----
    The data set's trial arrays are views of one block of memory (32 MB for 40 trials of
    20 000 samples of a SISO plant with one state). Once a result and every array taken from
    it are gone, its block is kept for the next run to reuse (at most two blocks, 256 MiB in
    all, :func:`~ilc_analysis._arrays.recycled_empty`): a sweep that keeps only metrics does
    not ask the system for fresh memory on every run. A law without current-trial feedback
    applies its feed-forward as it is: the data set's ``u`` and ``u_ff`` are then one array
    (equal by definition, kept once); copy the data set (``dataset.copy(deep=True)``) before
    writing into either in place.
    """
    if isinstance(system, DiscretePlant):
        warnings.warn("simulate(dplant, law, y_d, iterations, x0) is deprecated and will be "
                      "removed in the next minor release: use simulate(problem, law, iterations) "
                      "with an ILCProblem (ilc_analysis.problem)", ILCDeprecationWarning,
                      stacklevel=2)
        return simulate_plant(system, law, *args, **options)
    if is_problem(system):
        return simulate_problem(system, law, *args, **options)
    raise ParameterError(f"dplant must be a DiscretePlant (see ilc_analysis.model.discretize), "
                         f"or an ILCProblem for simulate(problem, law, iterations); got "
                         f"{type(system).__name__}")


def simulate_problem(problem, law, iterations: int, *,
                     disturbances: Disturbances | None = None,
                     bounds: DivergenceBounds | None = None, on_divergence: str = "stop",
                     jit: bool | None = None, units: dict | None = None,
                     entropy: int | None = None) -> ILCResult:
    r"""Simulate ``iterations`` trials of the learning law ``law`` on the ILC problem ``problem``.

    The plant run is ``problem.dplant`` (the composite closed loop when learning at a loop)
    with the problem's reference, initial state, shift, t0, known state disturbance
    ``problem.w`` (applied on the input samples k = 0..N-1, zero after, exactly as
    :func:`ilc_analysis.lifting.lift` puts it into d;
    :func:`~ilc_analysis.simulation._machine.known_disturbance`) and disturbances. The first
    trial's input is ``problem.initial_input()``. The law acts as described in
    :mod:`~ilc_analysis.simulation._law_adapter`: PDLaw's current-trial part
    :math:`\Psi_2, \Phi_2` inside the trial, every other law's between-trial update
    ``law.update(u_i, e_i, ts)``.

    A law with extra experiments per iteration (:class:`~ilc_analysis.laws.TimeReversalLaw`)
    runs them on the same simulated plant after each trial (open loop, the same initial state
    and known disturbance, the realisation ``Disturbances.realise(i, ..., experiment=k)``: the
    same sinusoids, independent noise); the data set's ``experiments`` holds the plant runs of
    each iteration (the trial and the experiments that computed the next input) and the
    attribute ``experiments_total`` their sum.

    Parameters
    ----------
    problem : ILCProblem
        The problem: plant, reference, initial state, shift, t0, known disturbance, default
        disturbances and the first trial's input.
    law : LearningLaw
        Set up for ``problem`` (model-based laws on ``problem.lifted``).
    iterations : int
        Number of trials (1 to :data:`~ilc_analysis._validation.MAX_ITERATIONS`).
    disturbances : Disturbances, optional
        Replaces ``problem.disturbances`` for this run.
    bounds, on_divergence, jit, units
        As for :func:`simulate_plant`.
    entropy : int, optional
        Root seed of the noise streams (default: the disturbances' seed, or fresh entropy,
        recorded in the attribute ``seed``).

    Returns
    -------
    ILCResult
        As :func:`simulate_plant`, plus ``experiments`` (per iteration) and the attributes
        ``problem`` (its name), ``first_trial`` (:attr:`ILCProblem.first_trial
        <ilc_analysis.problem.ILCProblem.first_trial>`: what trial 1 ran, the baseline of
        the run's reduction factors), ``experiments_per_iteration``, ``experiments_total`` and,
        for a law that certifies its updates (``law.history``, e.g. the constrained and
        nonlinear norm-optimal laws), ``certificates`` (JSON; :attr:`ILCResult.certificates`):
        one per update of this run (the QP's predicted cost decrease, the constraint
        satisfaction of the predicted and of the measured trial).

    Raises
    ------
    ParameterError, ShapeError
        ``law`` not a LearningLaw or not fitting the problem, bad options.
    DivergenceError
        Only with ``on_divergence='raise'``.
    """
    adapter = problem_law(law, problem)
    history = getattr(adapter.law, "history", None)
    first = len(history) if isinstance(history, list) else None
    if disturbances is None:
        disturbances = problem.disturbances
    result = _run(problem.dplant, adapter, problem.reference, iterations, problem.x0,
                  N=problem.N, shift=problem.shift, t0=problem.t0, disturbances=disturbances,
                  bounds=bounds, on_divergence=on_divergence, jit=jit, units=units,
                  w=problem.w, entropy=entropy)
    result.dataset.attrs["problem"] = str(getattr(problem, "name", "") or "")
    result.dataset.attrs["first_trial"] = problem.first_trial      # the reductions' baseline
    if first is not None:           # the law's per-trial certificates of this run
        if not isinstance(history, list):
            raise InternalError("first is set only for a list history")
        certs = [c.as_dict() for c in history[first:] if hasattr(c, "as_dict")]
        if certs:
            result.dataset.attrs["certificates"] = json.dumps(certs, default=float)
    return result


def simulate_plant(dplant: DiscretePlant, law, y_d, iterations: int, x0, *,
                   N: int | None = None, shift: int | None = None, t0: float = 0.0,
                   disturbances: Disturbances | None = None,
                   bounds: DivergenceBounds | None = None, on_divergence: str = "stop",
                   jit: bool | None = None, units: dict | None = None, w=None) -> ILCResult:
    r"""Simulate ``iterations`` trials of learning control ``law`` on ``dplant``.

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant (linear or nonlinear); with direct feedthrough (shift 0) only a law
        without a current-trial term.
    law : PDLaw
        The PD law of eq (11) (:class:`~ilc_analysis.laws.PDLaw`; the deprecated
        ``OpenClosedLoopPDLaw`` still runs); its ``u0`` is the first trial's feed-forward
        (zero when None). Any other :class:`~ilc_analysis.laws.LearningLaw` runs
        on a problem: ``simulate(problem, law, iterations)``.
    y_d : array_like, shape (N, n_y)
        Reference on the lifted output window (times :func:`window_times`); finite; N at most
        :data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES`.
    iterations : int
        Number of trials, 1 to :data:`~ilc_analysis._validation.MAX_ITERATIONS`; the record of
        all trials must fit in :data:`~ilc_analysis._validation.MAX_ARRAY_BYTES`.
    x0 : array_like, shape (n_x,)
        Initial state of every trial (before reset errors); Assumption 2 asks
        :math:`x_i(0) = x_d(0)`.
    N : int, optional
        Expected trial length; if given, ``y_d`` must have N rows.
    shift : int, optional
        Sampled relative degree s; default :func:`ilc_analysis.lifting.sampled_shift` at
        ``x0`` (u = 0, t0).
    t0 : float
        Time of the first sample [s].
    disturbances : Disturbances, optional
        State/output disturbances, noise (seeded) and reset errors; none by default.
    bounds : DivergenceBounds, optional
        Admissible state region; default :class:`DivergenceBounds` () (every |x_j| <= 1e6 and
        finite). For a balancing robot use ``DivergenceBounds.fall_angle()``.
    on_divergence : {'stop', 'raise'}
        ``'stop'`` returns the completed iterations with :attr:`ILCResult.divergence` set;
        ``'raise'`` raises :class:`~ilc_analysis.exceptions.DivergenceError`.
    jit : bool or None
        A nonlinear plant's trial compiled to C (:func:`~ilc_analysis.simulation.compiled_trial`):
        None (default) where a C compiler is found (built once, kept on disk; a run of fewer
        than ``COMPILE_MIN_STEPS`` samples in all compiles only a step already on disk), True
        always, False never (CasADi's virtual machine). A linear plant runs by linear filtering
        (:class:`~ilc_analysis.simulation._linear_trial.LinearTrial`) either way, its modes
        solved by a small compiled kernel under the same rule (False: by BLAS).
    units : dict, optional
        Units of channels/states/signals/metrics for labels, over the plant's declared
        ``units`` (undeclared names are unitless ``"-"``).
    w : array_like (N, n_x), optional
        Known state disturbance on the input samples (zero after them, as in
        :func:`ilc_analysis.lifting.lift`), added to the disturbances' realisation.

    Returns
    -------
    ILCResult

    Raises
    ------
    ShapeError, ParameterError
        Bad input (wrong reference length or NaN, gains of the wrong shape, iterations < 1,
        sizes above the caps of :mod:`ilc_analysis._validation`, ...).
    DivergenceError
        Only with ``on_divergence='raise'``.
    """
    return _run(dplant, engine_law(law), y_d, iterations, x0, N=N, shift=shift, t0=t0,
                disturbances=disturbances, bounds=bounds, on_divergence=on_divergence, jit=jit,
                units=units, w=w)


class _ExperimentDiverged(Exception):
    """An extra experiment left the admissible region (internal: caught by :func:`_run`)."""

    def __init__(self, info: DivergenceInfo):
        super().__init__(str(info))
        self.info = info


def _experiment_runner(machine: SimulatedMachine, limits, dplant, iteration: int, counter):
    """``v (N, n_u) -> output window (N, n_y)``: the next extra experiment of ``iteration`` on
    ``machine`` (counted in ``counter[0]``); divergence raises :class:`_ExperimentDiverged`."""
    def experiment(v):
        counter[0] += 1
        k = counter[0]
        rec = machine.run(np.asarray(v, dtype=float), iteration, k)
        info = _check_trial(rec, limits, dplant, iteration, machine.t)
        if info is not None:
            raise _ExperimentDiverged(DivergenceInfo(
                iteration=iteration, time=info.time, sample=info.sample,
                reason=f"extra experiment {k} of iteration {iteration} (run to compute the "
                       f"next input): {info.reason}", state=info.state, partial=info.partial))
        return machine.output_window(rec)
    return experiment


def _run(dplant, law, y_d, iterations, x0, *, N, shift, t0, disturbances, bounds,
         on_divergence, jit, units, w, entropy=None) -> ILCResult:
    """The simulation loop shared by :func:`simulate_plant` and :func:`simulate_problem`."""
    (iterations, x0, y_d, N, shift, t0, disturbances, bounds,
     units) = _validate(dplant, law, y_d, iterations, x0, N, shift, t0, disturbances, bounds,
                        on_divergence, units)
    n_u, n_y = dplant.n_u, dplant.n_y
    ts = dplant.ts
    limits = bounds.limits(dplant.state_names)
    smallest = float(limits.min(initial=np.inf))
    extra = law.extra_experiments if isinstance(law, ProblemLaw) else 0
    machine = SimulatedMachine(dplant, y_d, x0, shift=shift, t0=t0, w=w,
                               disturbances=disturbances,
                               feedback=law.feedback_gains(N, n_u, n_y), entropy=entropy,
                               jit=jit, runs=iterations * (1 + extra))
    ff = as_finite_array(law.initial_feedforward(N, n_u), "the first trial's input",
                         shape=(N, n_u))
    t = machine.t
    entropy = machine.entropy
    # without current-trial feedback the input is the feed-forward: one array for both
    store = RunStore(iterations, N, shift, dplant, input_is_feedforward=not machine.has_feedback)
    uses_states = isinstance(law, ProblemLaw) and law.uses_states
    window = machine.window
    divergence = None
    done = 0
    store.feedforward[0] = ff
    for i in tracked(range(iterations), desc="trials", unit="trial"):
        f = store.feedforward[i]         # the data set's rows, written by the last update
        rec = machine.run_checked(f, i + 1, out=store.record(i))
        if not _admissible(rec, window, store.error_max[i], store.error_min[i], limits,
                           smallest):
            # the input is part of the screen (u = f + feedback): a non-finite update is
            # reported as such, before the trial it made
            if i and not np.isfinite(f).all():
                divergence = DivergenceInfo(
                    iteration=i + 1, time=float(t[0]), sample=0,
                    reason="the learning update produced a non-finite input", state=None,
                    partial=_partial(rec, dplant, t, 0))
                break
            divergence = _check_trial(rec, limits, dplant, i + 1, t)
            if divergence is not None:
                break
        store.experiments[i] = 1
        done = i + 1
        u, e = rec.u[:N], rec.e[window]  # the law reads the data set's rows, cannot write them
        u.flags.writeable = e.flags.writeable = False
        nxt = store.feedforward[i + 1] if i + 1 < iterations else None
        if extra:
            counter = [0]
            try:
                ff, a = law.next_feedforward(
                    u, e, ts, nxt,
                    experiment=_experiment_runner(machine, limits, dplant, i + 1, counter))
            except _ExperimentDiverged as exc:
                store.experiments[i] += counter[0]
                divergence = exc.info
                break
            store.experiments[i] += counter[0]
        elif uses_states:               # the law's own copy of the trial's states
            ff, a = law.next_feedforward(u, e, ts, nxt, states=rec.x.copy())
        else:
            ff, a = law.next_feedforward(u, e, ts, nxt)
        if a is not None and a.any():
            store.set_factor(i, a)
        if ff is not nxt:               # a law that returned a new array
            if ff.shape != (N, n_u):
                raise ShapeError(f"{law.name}: the learning update returned shape {ff.shape}; "
                                 f"the next input must be {(N, n_u)}")
            if nxt is not None:
                nxt[...] = ff
    ds = _dataset(store, done, dplant, law, y_d, shift, t0, N, disturbances, entropy,
                  bounds, units)
    if divergence is not None and on_divergence == "raise":
        raise DivergenceError(str(divergence))
    return ILCResult(dataset=ds, divergence=divergence)


def _admissible(rec: TrialRecord, window: slice, e_max: np.ndarray, e_min: np.ndarray,
                limits: np.ndarray, smallest: float) -> bool:
    r"""The cheap screen before :func:`_check_trial`: True only if every state is finite and
    within its bound, the error's extremes on the output window ``window`` are finite, and
    so are the largest and the smallest input, output before the window and signal; False
    sends the trial to the exact check.

    The error's largest and smallest value per channel are written into ``e_max`` and
    ``e_min`` ``(n_y,)`` first (the data set's ``max_abs_e``; taken here while the error is in
    the cache). A finite error :math:`e = y_d - y` on the window means a finite output there
    (:math:`y_d` is finite), so they screen the outputs too. The states are screened as one
    array first: when the largest :math:`|x|` is within the smallest bound ``smallest`` every
    state is within its own (two whole-array reductions, a few microseconds); otherwise per
    state (the largest and the smallest value of each). A NaN propagates through
    ``np.maximum``/``np.minimum`` and fails every comparison (and no extreme can overflow, so
    the screen needs no floating-point error state); the bounds are finite
    (:class:`DivergenceBounds`). Where the trial found a finite bound on every :math:`|x|` or
    every :math:`|u|` while computing them (``TrialRecord.bounds``: a linear trial's compiled
    kernel) the screen takes it instead of reading that array: a state bound within
    ``smallest`` passes the states, a finite input bound passes the inputs.
    """
    e = rec.e[window]
    if e.shape[1] == 1:             # one channel: one long loop each
        e_max[0] = top = np.maximum.reduce(e[:, 0])
        e_min[0] = bottom = np.minimum.reduce(e[:, 0])
        if not (math.isfinite(top) and math.isfinite(bottom)):
            return False
    else:
        e_max[...] = narrow_reduce(np.maximum, e, 0)
        e_min[...] = narrow_reduce(np.minimum, e, 0)
        if not (np.isfinite(e_max).all() and np.isfinite(e_min).all()):
            return False
    x_bound, u_bound = rec.bounds.tolist()      # the trial's own bounds (NaN: none)
    if not ((math.isfinite(u_bound) or _finite(rec.u))
            and (not window.start or _finite(rec.y[:window.start])) and _finite(rec.signals)):
        return False
    x = rec.x
    if not x.size or x_bound <= smallest:       # a NaN bound fails the comparison
        return True
    top = np.maximum.reduce(x, axis=None)
    bottom = np.minimum.reduce(x, axis=None)
    if top <= smallest and -bottom <= smallest:
        return True
    return bool((narrow_reduce(np.maximum, x, 0) <= limits).all()
                and (narrow_reduce(np.minimum, x, 0) >= -limits).all())


def _finite(a: np.ndarray) -> bool:
    """Whether every entry of ``a`` is finite: its largest and its smallest entry are (a NaN
    propagates through both); a few entries are asked one by one."""
    if a.size <= _FEW:
        return all(map(math.isfinite, a.flat))
    return (math.isfinite(np.maximum.reduce(a, axis=None))
            and math.isfinite(np.minimum.reduce(a, axis=None)))


#: arrays up to this size are screened entry by entry (:func:`_finite`): cheaper than two
#: reductions
_FEW = 8


def _check_trial(rec: TrialRecord, limits, dplant, iteration, t) -> DivergenceInfo | None:
    """The first inadmissible sample of a trial (state out of bounds, or anything non-finite)."""
    hit = first_violation(rec.x, limits)
    k_state = hit[0] if hit is not None else rec.x.shape[0]
    others = ~np.isfinite(np.concatenate([rec.u, rec.y, rec.signals], axis=1)).all(axis=1)
    k_other = int(np.flatnonzero(others)[0]) if others.any() else rec.x.shape[0]
    k = min(k_state, k_other)
    if k == rec.x.shape[0]:
        return None
    if hit is not None and k_state == k:
        j = hit[1]
        value = rec.x[k, j]
        name = dplant.state_names[j]
        reason = (f"state {name} is non-finite" if not np.isfinite(value) else
                  f"|{name}| = {abs(value):.6g} exceeds its bound {limits[j]:.6g}")
    else:
        name = None
        reason = "input, output or signal is non-finite"
    return DivergenceInfo(iteration=iteration, time=float(t[k]), sample=k, reason=reason,
                          state=name, partial=_partial(rec, dplant, t, k))


def _partial(rec: TrialRecord, dplant, t, k) -> xr.Dataset:
    """The samples of ``rec`` before sample ``k`` (copies: the record's arrays may be a run's
    reused buffers)."""
    return xr.Dataset(
        {"x": (("trial_time", "state"), rec.x[:k].copy()),
         "u": (("trial_time", "input"), rec.u[:k].copy()),
         "y": (("trial_time", "channel"), rec.y[:k].copy())},
        coords={"trial_time": t[:k], "state": list(dplant.state_names),
                "input": list(dplant.input_names), "channel": list(dplant.output_names)})


#: below this peak magnitude a sum of squares of up to MAX_ARRAY_BYTES values cannot overflow
_PLAIN_PEAK = 1e150


def _error_norms(e: np.ndarray, peak: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""``(rms_e, e_norm)`` of the errors ``e`` ``(n, N, n_y)`` with their peaks ``(n, n_y)``:
    :math:`\sqrt{\mathrm{mean}_j e_{ij}^2}` per channel and the 2-norm of each lifted error,
    from one sum of squares per channel; when a peak reaches :data:`_PLAIN_PEAK` the squares
    are taken of :math:`e/m` (m the peak) so that huge finite errors do not overflow."""
    n, N, n_y = e.shape
    if not N:
        return np.zeros((n, n_y)), np.zeros(n)
    if np.all(peak < _PLAIN_PEAK):
        squares = _sum_squares(e)
        return np.sqrt(squares / N), np.sqrt(squares.sum(axis=1))
    scale = np.where(peak > 0, peak, 1.0)
    scaled = _sum_squares(e / scale[:, None, :])
    rms = scale * np.sqrt(scaled / N)
    top = scale.max(axis=1)
    norm = top * np.sqrt((scaled * (scale / top[:, None]) ** 2).sum(axis=1))
    return rms, norm


def _sum_squares(e: np.ndarray) -> np.ndarray:
    r""":math:`\sum_j e_{ij}^2` per trial i and channel, ``(n, n_y)`` of ``e`` ``(n, N, n_y)``:
    channel by channel for a few channels (:func:`~ilc_analysis._arrays.narrow_reduce`), no
    temporary array."""
    n_y = e.shape[2]
    if n_y > 8:
        return np.einsum("ijk,ijk->ik", e, e)
    out = np.empty((e.shape[0], n_y))
    for c in range(n_y):
        out[:, c] = np.einsum("ij,ij->i", e[:, :, c], e[:, :, c])
    return out


@functools.lru_cache(maxsize=16)
def _trial_coordinates(dplant: DiscretePlant, N: int, shift: int, t0: float,
                       units: tuple[tuple[str, str], ...]) -> xr.Coordinates:
    """The coordinates of a run's data set but the iteration (time, input time, channels,
    inputs, states and their units), built once per trial: their indexes are immutable and
    shared; each data set gets a shallow copy (its own attributes)."""
    ts = dplant.ts
    units_map = dict(units)
    out_names, in_names = list(dplant.output_names), list(dplant.input_names)
    state_names = list(dplant.state_names)
    return xr.Coordinates({
        "time": ("time", window_times(N, ts, shift, t0),
                 {"units": "s", "long_name": "time of the lifted output window"}),
        "input_time": ("input_time", t0 + ts * np.arange(N),
                       {"units": "s", "long_name": "time of the lifted input"}),
        "channel": ("channel", out_names, {"long_name": "plant output"}),
        "input": ("input", in_names, {"long_name": "channel of the learned signal"}),
        "state": ("state", state_names, {"long_name": "state"}),
        "channel_units": ("channel", _units(out_names, units_map),
                          {"long_name": "unit of each plant output"}),
        "input_units": ("input", _units(in_names, units_map),
                        {"long_name": "unit of each channel of the learned signal"}),
        "state_units": ("state", _units(state_names, units_map),
                        {"long_name": "unit of each state"}),
    })


@functools.lru_cache(maxsize=16)
def _affine_metrics(dplant: DiscretePlant) -> tuple[np.ndarray, np.ndarray] | None:
    r"""``(J, m0)`` with :math:`m(x) = Jx + m_0` when the plant's declared metrics are affine
    in the state (a state, a weight vector, an affine expression: the robots' pitch), else
    None."""
    fn = dplant.metrics
    if not fn.is_a("SXFunction"):
        return None
    x = ca.SX.sym("x", dplant.n_x)
    m = fn(x)
    J = ca.jacobian(m, x)
    if ca.depends_on(J, x):
        return None
    J_value = np.asarray(ca.evalf(J), dtype=float).reshape(m.numel(), dplant.n_x)
    m0 = np.asarray(fn(np.zeros(dplant.n_x)), dtype=float).ravel()
    return J_value, m0


def _metric_values(dplant: DiscretePlant, xs: np.ndarray) -> np.ndarray:
    """The plant's declared metrics on the states ``xs`` ``(samples, n_x)``, ``(samples,
    n_m)``: one product for affine metrics, else the metrics function mapped over the
    samples."""
    affine = _affine_metrics(dplant)
    if affine is not None:
        J, m0 = affine
        return long_matmul(xs, J.T) + m0
    return np.asarray(dplant.metrics.map(xs.shape[0])(xs.T), dtype=float).T


def _dataset(store, n, dplant, law, y_d, shift, t0, N, disturbances, entropy, bounds,
             units) -> xr.Dataset:
    ts = dplant.ts
    units = {**dplant.units, **units}      # the caller's units over the plant's declared ones
    out_names, in_names = list(dplant.output_names), list(dplant.input_names)
    state_names = list(dplant.state_names)
    units_key = tuple(sorted(units.items()))
    reserved = {*_trial_coordinates(dplant, N, shift, t0, units_key).variables, "iteration"}
    e = store.window("e", n)
    max_abs_e = np.maximum(store.error_max[:n], -store.error_min[:n])
    rms_e, e_norm = _error_norms(e, max_abs_e)
    y_unit, u_unit = _common_unit(out_names, units), _common_unit(in_names, units)
    data = {
        "y": (("iteration", "time", "channel"), store.window("y", n),
              {"long_name": "measured output h(x) + nu", **y_unit}),
        "y_d": (("time", "channel"), y_d, {"long_name": "reference", **y_unit}),
        "e": (("iteration", "time", "channel"), e,
              {"long_name": "tracking error y_d - y", **y_unit}),
        "a": (("iteration", "time"), store.factor(n),
              {"long_name": "forgetting factor from this trial's error", "units": "1"}),
        "u": (("iteration", "input_time", "input"), store.window("u", n),
              {"long_name": "applied input", **u_unit}),
        "u_ff": (("iteration", "input_time", "input"), store.feedforward[:n],
                 {"long_name": "between-trial feed-forward part of the input", **u_unit}),
        "x": (("iteration", "time", "state"), store.window("x", n),
              {"long_name": "state", **_common_unit(state_names, units)}),
        "max_abs_e": (("iteration", "channel"), max_abs_e,
                      {"long_name": "max |e| over the trial", **y_unit}),
        "rms_e": (("iteration", "channel"), rms_e,
                  {"long_name": "RMS of e over the trial", **y_unit}),
        "experiments": (("iteration",), store.experiments[:n],
                        {"long_name": "plant runs of the iteration (the trial and the extra "
                                      "experiments that computed the next input)"}),
        "e_norm": (("iteration",), e_norm,
                   {"long_name": "2-norm of the lifted error", **y_unit}),
    }
    reserved |= set(data)
    for j, name in enumerate(dplant.signal_names):
        key = _variable_name(name, reserved | set(data))
        data[key] = (("iteration", "time"), store.window("signals", n)[:, :, j],
                     {"long_name": f"signal {name}", "signal": name,
                      "units": units.get(name, DEFAULT_UNITS.get(name, "-"))})
    # the plant's declared metrics m(x) (e.g. the robots' pitch): max_j |m(x_i(j))| per trial
    n_m, samples = len(dplant.metric_names), n * N
    metric = np.zeros((n_m, n, N))
    if n_m and samples:
        metric = _metric_values(dplant, store.window("x", n).reshape(samples, dplant.n_x))
        metric = metric.T.reshape(n_m, n, N)
    for k, name in enumerate(dplant.metric_names):
        key = f"max_abs_{name}"
        key = key if key not in reserved and key not in data else f"max_abs_metric_{name}"
        data[key] = (("iteration",), np.abs(metric[k]).max(axis=1, initial=0.0),
                     {"long_name": f"max |{name}| over the trial",
                      "units": units.get(name, "-"), "plant_metric": name})
    attrs = {"plant": dplant.name, "ts": ts, "shift": shift, "N": N, "t0": t0,
             "seed": str(entropy), "max_abs_state": bounds.max_abs_state,
             **{f"bound_{k}": v for k, v in bounds.state_limits.items()},
             **{f"disturbance_{k}": v for k, v in disturbances.as_dict().items()},
             "experiments_total": int(store.experiments[:n].sum()),
             **law.describe()}
    layout = tuple((key, dims, arr.shape, arr.dtype.str, tuple(sorted(var_attrs.items())))
                   for key, (dims, arr, var_attrs) in data.items())
    ds = _layout(dplant, N, shift, t0, units_key, n, layout).copy(
        deep=False, data={key: arr for key, (_, arr, _) in data.items()})
    ds.attrs = attrs
    return ds


@functools.lru_cache(maxsize=16)
def _layout(dplant: DiscretePlant, N: int, shift: int, t0: float,
            units: tuple[tuple[str, str], ...], n: int, layout: tuple) -> xr.Dataset:
    """An empty data set of a run's layout: its coordinates (:func:`_trial_coordinates` and
    the ``n`` iterations) and, per data variable of ``layout`` (name, dimensions, shape,
    dtype, attributes), a placeholder of no memory (a broadcast zero).

    Built once per layout, so a run's data set is this one with the run's arrays
    (``Dataset.copy(data=...)``: no merge, no alignment; its own attributes): xarray's
    constructor would check again, for every run, what the layout already fixes (about 1.5 ms
    of CPU per run, as much as 30 trials of the filtering at N = 2 000).
    """
    it = np.arange(1, n + 1, dtype=np.int32)
    trial = _trial_coordinates(dplant, N, shift, t0, units).copy(deep=False)
    coords = xr.Coordinates(
        {**trial.variables,
         "iteration": xr.Variable("iteration", it, {"long_name": "iteration (trial number)"})},
        indexes={**trial.xindexes,
                 "iteration": PandasIndex(pd.Index(it, name="iteration"), "iteration")})
    data = {key: (dims, np.broadcast_to(np.zeros((), dtype=dtype), shape), dict(var_attrs))
            for key, dims, shape, dtype, var_attrs in layout}
    return xr.Dataset(data, coords=coords)
