r"""Trial-by-trial learning simulation.

For i = 1, 2, ...: run trial i as one compiled CasADi function (the current-trial feedback
acts inside it, sample by sample; :mod:`~ilc_analysis.simulation.trial`), check that it stayed
admissible (:mod:`~ilc_analysis.simulation.divergence`), record it, and compute the next
trial's feed-forward from it with the law's between-trial update (vectorised numpy;
:mod:`~ilc_analysis.simulation.laws`).

Index convention (:mod:`ilc_analysis.law`): ``y_d`` is given on the lifted output window,
:math:`y_d(j)` at time :math:`t_0 + (j+s)T_s`, j = 0..N-1 (use :func:`window_times`); the
lifted input is :math:`u(0..N-1)` at :math:`t_0 + jT_s`.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .._validation import (
    MAX_ITERATIONS,
    MAX_TRIAL_SAMPLES,
    as_finite_array,
    as_vector,
    check_allocation,
    positive_int,
    real,
)
from ..exceptions import DivergenceError, ParameterError
from ..lifting import sampled_shift
from ..model import DiscretePlant
from .disturbances import NO_DISTURBANCES, Disturbances
from .divergence import DivergenceBounds, first_violation
from .laws import ILCLaw
from .results import DEFAULT_UNITS, DivergenceInfo, ILCResult
from .trial import TrialRecord, compiled_trial, window_times

__all__ = ["simulate", "ON_DIVERGENCE"]

ON_DIVERGENCE = ("stop", "raise")


def _units(names, units) -> list[str]:
    return [units.get(n, DEFAULT_UNITS.get(n, "-")) for n in names]


def _record_width(dplant: DiscretePlant) -> int:
    """Values :func:`simulate` keeps per trial sample: x, u, u_ff, y, e, a and the signals."""
    return dplant.n_x + 2 * dplant.n_u + 2 * dplant.n_y + 1 + len(dplant.signal_names)


def _validate(dplant, law, y_d, iterations, x0, N, shift, t0, disturbances, bounds,
              on_divergence, units):
    if not isinstance(dplant, DiscretePlant):
        raise ParameterError(f"dplant must be a DiscretePlant (see ilc_analysis.model."
                             f"discretize); got {type(dplant).__name__}")
    if not isinstance(law, ILCLaw):
        raise ParameterError(f"law must be an ILCLaw (OpenClosedLoopPDLaw, NormOptimalLaw, ...); "
                             f"got {type(law).__name__}")
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
        shift = positive_int(shift, "shift")
    if shift < 1:
        raise ParameterError("the plant has direct feedthrough (sampled relative degree 0); "
                             "the current-trial term would form an algebraic loop: only "
                             "strictly proper plants (shift >= 1) can be simulated")
    law.check_dimensions(N, dplant.n_u, dplant.n_y, dplant.ts, shift)
    return iterations, x0, y_d, N, shift, t0, disturbances, bounds, dict(units or {})


def simulate(dplant: DiscretePlant, law: ILCLaw, y_d, iterations: int, x0, *,
             N: int | None = None, shift: int | None = None, t0: float = 0.0,
             disturbances: Disturbances | None = None, bounds: DivergenceBounds | None = None,
             on_divergence: str = "stop", jit: bool = False,
             units: dict | None = None) -> ILCResult:
    r"""Simulate ``iterations`` trials of learning control ``law`` on ``dplant``.

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant (linear or nonlinear), strictly proper (shift >= 1).
    law : ILCLaw
        :class:`OpenClosedLoopPDLaw`, :class:`NormOptimalLaw`, ...
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
    jit : bool
        Compile the trial to C (CasADi JIT; needs a C compiler).
    units : dict, optional
        Units of channels/states/signals for labels (defaults: :data:`DEFAULT_UNITS`).

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
    (iterations, x0, y_d, N, shift, t0, disturbances, bounds,
     units) = _validate(dplant, law, y_d, iterations, x0, N, shift, t0, disturbances, bounds,
                        on_divergence, units)
    n_x, n_u, n_y = dplant.n_x, dplant.n_u, dplant.n_y
    ts = dplant.ts
    limits = bounds.limits(dplant.state_names)
    trial = compiled_trial(dplant, N, shift, bool(jit))
    psi2, phi2 = law.feedback_gains(N, n_u, n_y)
    ff = law.initial_feedforward(N, n_u)
    t = t0 + ts * np.arange(N + shift)
    entropy = disturbances.root_entropy()
    n_sig = len(dplant.signal_names)
    store = {"x": np.empty((iterations, N, n_x)), "u": np.empty((iterations, N, n_u)),
             "u_ff": np.empty((iterations, N, n_u)), "y": np.empty((iterations, N, n_y)),
             "e": np.empty((iterations, N, n_y)), "a": np.empty((iterations, N)),
             "signals": np.empty((iterations, N, n_sig))}
    window = slice(shift, N + shift)
    divergence = None
    done = 0
    for i in range(iterations):
        dist = disturbances.realise(i + 1, t, n_x, n_y, entropy)
        rec = trial.run(x0 + dist.reset, ff, y_d, psi2, phi2, dist.w, dist.nu, t)
        divergence = _check_trial(rec, limits, dplant, i + 1, t)
        if divergence is not None:
            break
        e = y_d - rec.y[window]
        store["x"][i], store["y"][i], store["e"][i] = rec.x[window], rec.y[window], e
        store["signals"][i] = rec.signals[window]
        store["u"][i], store["u_ff"][i] = rec.u[:N], ff
        ff, a = law.next_feedforward(rec.u[:N], e, ts)
        store["a"][i] = a
        done = i + 1
        if not np.all(np.isfinite(ff)):
            if i + 1 < iterations:
                divergence = DivergenceInfo(
                    iteration=i + 2, time=float(t[0]), sample=0,
                    reason="the learning update produced a non-finite input", state=None,
                    partial=_partial(rec, dplant, t, 0))
            break
    ds = _dataset(store, done, dplant, law, y_d, shift, t0, N, disturbances, entropy,
                  bounds, units)
    if divergence is not None and on_divergence == "raise":
        raise DivergenceError(str(divergence))
    return ILCResult(dataset=ds, divergence=divergence)


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
    return xr.Dataset(
        {"x": (("trial_time", "state"), rec.x[:k]), "u": (("trial_time", "input"), rec.u[:k]),
         "y": (("trial_time", "channel"), rec.y[:k])},
        coords={"trial_time": t[:k], "state": list(dplant.state_names),
                "input": list(dplant.input_names), "channel": list(dplant.output_names)})


def _scaled_rms(v: np.ndarray, axis: int) -> np.ndarray:
    r"""Root mean square along ``axis`` without overflow for huge finite values:
    :math:`m\sqrt{\mathrm{mean}((v/m)^2)}` with :math:`m = \max|v|`."""
    peak = np.abs(v).max(axis=axis, keepdims=True, initial=0.0)
    safe = np.where(peak > 0, peak, 1.0)
    return (peak * np.sqrt(np.mean((v / safe) ** 2, axis=axis, keepdims=True))).squeeze(axis) \
        if v.shape[axis] else np.zeros(np.delete(v.shape, axis))


def _dataset(store, n, dplant, law, y_d, shift, t0, N, disturbances, entropy, bounds,
             units) -> xr.Dataset:
    ts = dplant.ts
    it = np.arange(1, n + 1, dtype=np.int32)
    out_names, in_names = list(dplant.output_names), list(dplant.input_names)
    state_names = list(dplant.state_names)
    coords = {
        "iteration": ("iteration", it, {"long_name": "iteration (trial number)"}),
        "time": ("time", window_times(N, ts, shift, t0),
                 {"units": "s", "long_name": "time of the lifted output window"}),
        "input_time": ("input_time", t0 + ts * np.arange(N),
                       {"units": "s", "long_name": "time of the lifted input"}),
        "channel": ("channel", out_names), "input": ("input", in_names),
        "state": ("state", state_names),
        "channel_units": ("channel", _units(out_names, units)),
        "input_units": ("input", _units(in_names, units)),
        "state_units": ("state", _units(state_names, units)),
    }
    e = store["e"][:n]
    data = {
        "y": (("iteration", "time", "channel"), store["y"][:n],
              {"long_name": "measured output h(x) + nu"}),
        "y_d": (("time", "channel"), y_d, {"long_name": "reference"}),
        "e": (("iteration", "time", "channel"), e, {"long_name": "tracking error y_d - y"}),
        "a": (("iteration", "time"), store["a"][:n],
              {"long_name": "forgetting factor from this trial's error", "units": "1"}),
        "u": (("iteration", "input_time", "input"), store["u"][:n],
              {"long_name": "applied input"}),
        "u_ff": (("iteration", "input_time", "input"), store["u_ff"][:n],
                 {"long_name": "between-trial feed-forward part of the input"}),
        "x": (("iteration", "time", "state"), store["x"][:n], {"long_name": "state"}),
        "max_abs_e": (("iteration", "channel"), np.abs(e).max(axis=1, initial=0.0),
                      {"long_name": "max |e| over the trial"}),
        "rms_e": (("iteration", "channel"), _scaled_rms(e, axis=1),
                  {"long_name": "RMS of e over the trial"}),
        "e_norm": (("iteration",),
                   _scaled_rms(e.reshape(n, N * len(out_names)), axis=1) * np.sqrt(N * len(
                       out_names)), {"long_name": "2-norm of the lifted error"}),
    }
    reserved = set(data) | set(coords)
    for j, name in enumerate(dplant.signal_names):
        key = name if name not in reserved else f"signal_{name}"
        data[key] = (("iteration", "time"), store["signals"][:n, :, j],
                     {"long_name": f"signal {name}",
                      "units": units.get(name, DEFAULT_UNITS.get(name, "-"))})
    pitch = None
    if "pitch" in dplant.signal_names:
        pitch = store["signals"][:n, :, dplant.signal_names.index("pitch")]
    elif "theta" in state_names:
        pitch = store["x"][:n, :, state_names.index("theta")]
    if pitch is not None:
        data["max_abs_pitch"] = (("iteration",), np.abs(pitch).max(axis=1, initial=0.0),
                                 {"long_name": "max |pitch| over the trial", "units": "rad"})
    attrs = {"plant": dplant.name, "ts": ts, "shift": shift, "N": N, "t0": t0,
             "seed": str(entropy), "max_abs_state": bounds.max_abs_state,
             **{f"bound_{k}": v for k, v in bounds.state_limits.items()},
             **{f"disturbance_{k}": v for k, v in disturbances.as_dict().items()},
             **law.describe()}
    return xr.Dataset(data, coords=coords, attrs=attrs)
