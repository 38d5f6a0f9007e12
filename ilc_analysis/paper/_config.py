r"""The paper's Section 5 scenario as a named, documented, validated configuration.

The paper gives the reference :math:`P_d(t) = [\cos\pi t,\ \sin\pi t,\ \pi t + \pi/2]^T`, the
disturbances :math:`\omega_i(t) = \nu_i(t) = 0.01\sin(40\pi t)`, :math:`\delta = 0.85`,
:math:`\Lambda = 6`, :math:`u_0 = [0.1, 0.1]^T` and 40 iterations. Everything else is a choice
the toolkit makes explicitly; each field's docstring says which and why (docs/theory.md §3, §10).
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from .._validation import (
    MAX_ITERATIONS,
    MAX_SUBSTEPS,
    MAX_TRIAL_SAMPLES,
    as_vector,
    in_interval,
    nonnegative,
    positive,
    positive_int,
    read_toml_file,
    table,
)
from ..exceptions import ParameterError, ShapeError
from ..laws._forgetting import FixedForgetting, VariableForgetting, check_delta, check_Lambda
from ..model import Plant, RobotParameters, balanced_mobile_robot
from ..model._robots import ROBOT_MODELS, robot_model
from ._circle import (
    CIRCLE_INITIAL_STATE,
    CIRCLE_SPEED,
    CIRCLE_YAW_RATE,
    CircleNominal,
    circle_nominal,
    circle_reference,
)
from ._disturbances import PAPER_AMPLITUDE, PAPER_FREQUENCY

__all__ = ["PaperScenario", "load_scenario", "paper_scenario", "circle_reference"]

_SYNTHESIS_METHODS = ("lifted", "paper", "frequency")
_INNER_LOOPS = ("nominal", "rest")


def _choice(value, name: str, choices: tuple[str, ...]) -> str:
    """``value`` must be one of the strings ``choices``."""
    if not isinstance(value, str) or value not in choices:
        raise ParameterError(f"{name} must be one of {list(choices)}; got {value!r}")
    return value


@dataclass(frozen=True)
class PaperScenario:
    """Configuration of the paper's Section 5 experiment. Frozen; validated on construction."""

    name: str = "dong2019_section5"
    """label used in reports and file names"""
    model: str = "mobile_balanced"
    """robot model (choice). The paper's planar model cannot produce a planar path with
    heading (docs/theory.md §3), so the mobile model is used; it is open-loop unstable and the
    paper's learning terms act on (X, Y, psi) only, which cannot stabilise the pitch, so an
    inner LQR balance loop is closed first and u is the torque command to it"""
    inner_loop: str = "nominal"
    """what the inner balance loop regulates (choice, mobile_balanced only): 'nominal' balances
    about the reference's steady motion (speed pi m/s, yaw rate pi rad/s, friction-cancelling
    torques), so u is a torque correction; 'rest' balances about standstill, so u must carry
    the whole motion. With 'rest' the command the circle needs is about 1 N m away from u0 and
    every law measured (norm-optimal included) makes the robot fall within three trials"""
    horizon: float = 2.0
    """trial length T [s] (choice): one lap of the circle, whose period is 2 s"""
    ts: float = 0.01
    """sample time [s] (choice): 100 Hz keeps the 20 Hz disturbance below Nyquist and the
    lifted synthesis (N = 200) within a minute"""
    iterations: int = 40
    """number of learning trials (paper)"""
    u0: tuple[float, ...] = (0.1, 0.1)
    """initial input u_0 (paper), N m torque commands to the left and right wheels"""
    delta: float = 0.85
    """δ of eq (12) (paper)"""
    Lambda: float = 6.0
    """Λ of eq (12) (paper)"""
    fixed_forgetting: float = 0.15
    """constant factor of the traditional law (choice): 1 - δ, i.e. eq (12) with Λ = 0, the
    value the variable factor takes at zero error"""
    disturbance_amplitude: float = PAPER_AMPLITUDE
    """amplitude of ω_i and ν_i on every channel (paper)"""
    disturbance_frequency: float = PAPER_FREQUENCY
    """frequency of ω_i and ν_i [Hz] (paper: 40π rad/s)"""
    fall_angle: float = 1.0
    """|θ| above this [rad] counts as a fall: the run is reported as diverged (choice)"""
    synthesis_method: str = "lifted"
    """how the learning gains are obtained (choice): the paper gives none"""
    gains_time_varying: bool = True
    """synthesise time-varying gains (choice): along the circle the error frame rotates"""
    gain_knot_spacing: int = 0
    """time-varying gains linear between knots every this many samples (choice; 0 = free per
    sample). Knots every 5 samples would make the gains blind to 20 Hz, the paper's
    disturbance frequency (interpolation has zeros at multiples of 1/(5 Ts)), so they could not
    multiply ν down into the Q-filter's band. At the scenario's lead it does not matter
    (measured: 10.22x with knots every 5 samples against 10.32x per sample, disturbed), so the
    simpler per-sample gains are kept"""
    lead: int = 60
    """samples of anticipation of the open-loop term (choice): the input at t learns from the
    error at t + lead Ts. A torque moves the robot's position over the rest of the lap (the
    balanced, turning robot integrates it), so a PD gain on the error at the same instant
    cannot over-correct where the error lives. 60 (0.6 s) is the lead with the smallest
    model-predicted converged error among 0, 15, 30, 45, 60, 80, 100 (``scan_leads`` on the
    lifted model with the scenario's other choices; predicted max |e_inf| / max |e_1| = 0.153,
    0.123, 0.099, 0.081, 0.065, 0.114, 0.226; re-measure with ``ilc-analysis lead-scan``, about
    20 s). It is chosen on the model, not on the simulation"""
    q_cutoff: float = 0.5
    """cut-off [Hz] of the zero-phase DCT Q-filter on the learned input (choice; 0 = none).
    The sampled lifted operator has singular values near zero, so without filtering (or
    forgetting) no gains make it a contraction; the filter restricts learning to the bandwidth
    where the model is reliable (measured: certificate 0.696 at 0.5 Hz, 0.901 at 1 Hz). The scan
    of every lead above with 0.25, 0.5 and 1 Hz (``ilc-analysis lead-scan --q-cutoffs 0.25 0.5
    1``) predicts the smallest floor for 0.5 Hz with lead 60: max |e_inf| / max |e_1| = 0.065,
    against 0.088 at 0.25 Hz (its best lead, 80) and 0.092 at 1 Hz (lead 45)"""
    gain_bound_psi: float = 2.0
    """bound on every entry of the synthesised Psi1 (choice). Unbounded, the synthesis returns
    gains of order 1e5 whose certified contraction is towards a fixed point that amplifies the
    non-repeating part of the error (measured: max |e| about 3000 predicted for trial 2)"""
    gain_bound_phi: float = 0.5
    """bound on every entry of the synthesised Phi1 (choice, same reason as gain_bound_psi);
    looser bounds (6 and 1.5) kept a linear certificate but the nonlinear error grew 12-fold"""
    overshoot: float = 0.5
    """aim of the synthesis' mean-square term, T = -overshoot Q instead of T = 0 (choice). With
    forgetting a the converged error is at least a/(1 + ||E||) of the first trial's
    (forgetting_floor_bound): deadbeat learning (0) leaves a = 1 - delta = 15 % of it at best.
    0.5 is half-way between deadbeat and the monotone limit 1, and equals 10 a - 1, the least
    over-correction for which the bound allows the paper's 10x"""
    substeps: int = 4
    """RK4 sub-steps per sample of the nonlinear simulation (choice)"""
    params: RobotParameters = field(default_factory=RobotParameters)
    """robot parameters (Table 1 unless overridden)"""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ParameterError(f"name must be a non-empty string; got {self.name!r}")
        _choice(self.model, "model", tuple(sorted(ROBOT_MODELS)))
        positive(self.horizon, "horizon")
        positive(self.ts, "ts")
        if self.ts > self.horizon:
            raise ParameterError(f"ts ({self.ts}) must not exceed horizon ({self.horizon})")
        n = self.horizon / self.ts
        if n > MAX_TRIAL_SAMPLES + 0.5:
            raise ParameterError(f"horizon/ts = {n:.6g} samples per trial; at most "
                                 f"{MAX_TRIAL_SAMPLES} (MAX_TRIAL_SAMPLES)")
        _ = self.N      # raises unless horizon/ts is an integer number of samples
        positive_int(self.iterations, "iterations", maximum=MAX_ITERATIONS)
        object.__setattr__(self, "u0", tuple(as_vector(self.u0, "u0").tolist()))
        check_delta(self.delta)
        check_Lambda(self.Lambda)
        in_interval(self.fixed_forgetting, "fixed_forgetting", 0, 1)
        nonnegative(self.disturbance_amplitude, "disturbance_amplitude")
        nonnegative(self.disturbance_frequency, "disturbance_frequency")
        positive(self.fall_angle, "fall_angle")
        _choice(self.synthesis_method, "synthesis_method", _SYNTHESIS_METHODS)
        if not isinstance(self.gains_time_varying, bool):
            raise ParameterError("gains_time_varying must be true or false; "
                                 f"got {self.gains_time_varying!r}")
        positive_int(self.lead, "lead", minimum=0)
        positive_int(self.gain_knot_spacing, "gain_knot_spacing", minimum=0)
        if self.gain_knot_spacing and not self.gains_time_varying:
            raise ParameterError("gain_knot_spacing needs gains_time_varying = true (0 = free "
                                 f"per sample); got {self.gain_knot_spacing}")
        _choice(self.inner_loop, "inner_loop", _INNER_LOOPS)
        nonnegative(self.q_cutoff, "q_cutoff")
        positive(self.gain_bound_psi, "gain_bound_psi")
        positive(self.gain_bound_phi, "gain_bound_phi")
        in_interval(self.overshoot, "overshoot", 0, 1)
        if self.q_cutoff >= 0.5 / self.ts:
            raise ParameterError(f"q_cutoff ({self.q_cutoff} Hz) must be below the Nyquist "
                                 f"frequency {0.5 / self.ts} Hz")
        positive_int(self.substeps, "substeps", maximum=MAX_SUBSTEPS)
        if not isinstance(self.params, RobotParameters):
            raise ParameterError(f"params must be a RobotParameters; got "
                                 f"{type(self.params).__name__}")

    # derived quantities ---------------------------------------------------------------------
    @property
    def N(self) -> int:
        """Samples per trial, T / ts (must be an integer)."""
        n = self.horizon / self.ts
        if abs(n - round(n)) > 1e-9 * n:
            raise ParameterError(f"horizon/ts = {n} must be an integer number of samples")
        return int(round(n))

    def plant(self) -> Plant:
        """The continuous plant of the scenario (with the chosen inner loop)."""
        if self.model == "mobile_balanced" and self.inner_loop == "nominal":
            return balanced_mobile_robot(self.params, speed=CIRCLE_SPEED,
                                         yaw_rate=CIRCLE_YAW_RATE)
        return robot_model(self.model, self.params)

    @classmethod
    def field_doc(cls, name: str) -> str:
        """The documentation of field ``name`` (one line), as the report quotes it.

        Parameters
        ----------
        name : str
            A field of :class:`PaperScenario` (e.g. ``"ts"``).

        Raises
        ------
        ParameterError
            If the class has no documented field ``name``.
        """
        import inspect

        source = inspect.getsource(cls)
        try:
            block = source.split(f"    {name}:", 1)[1].split('"""', 2)[1]
        except IndexError as exc:
            raise ParameterError(f"unknown scenario field {name!r}") from exc
        return " ".join(block.split())

    def initial_state(self) -> np.ndarray:
        r"""Initial state matching the reference (Assumption 2, eq 14).

        For the mobile models: :math:`X = 1, Y = 0, \psi = \pi/2, v = \pi, \theta = 0,
        \dot\theta = 0, \dot\psi = \pi` — on the circle at its speed and yaw rate, upright.
        Starting from rest would violate Assumption 2 (docs/theory.md §10).
        """
        if self.model == "planar":
            return np.zeros(4)
        return CIRCLE_INITIAL_STATE.copy()

    def nominal(self, plant: Plant | None = None, N: int | None = None,
                shift: int = 1) -> CircleNominal | None:
        """The trajectory this scenario's learning is lifted along, or None for rest.

        For the mobile models the paper's circle from :meth:`initial_state` with the constant
        input that sustains it (:func:`~ilc_analysis.paper._circle.circle_nominal`; its
        ``x0``, ``u`` and ``u_nominal`` feed :func:`ilc_analysis.lifting.lift`); for the
        planar model, which has no circle, None (lift at rest).

        Parameters
        ----------
        plant : Plant, optional
            The plant to sustain the circle on (default :meth:`plant`; pass a plant with
            perturbed parameters for robust synthesis).
        N : int, optional
            Trial length (default :attr:`N`).
        shift : int
            Output-window shift of ``y_d``.
        """
        if self.model == "planar":
            return None
        return circle_nominal(self.plant() if plant is None else plant,
                              self.N if N is None else N, self.ts, shift)

    def sample_times(self, shift: int) -> np.ndarray:
        """Times of the lifted output window, (k + shift) ts for k = 0..N-1.

        Parameters
        ----------
        shift : int
            Shift s of the output window (sampled relative degree).

        Returns
        -------
        ndarray, shape (N,)
            Times [s] from the trial's start.
        """
        return (np.arange(self.N) + shift) * self.ts

    def reference(self, shift: int) -> np.ndarray:
        """P_d on the lifted output window, shape (N, 3).

        Parameters
        ----------
        shift : int
            Shift s of the output window (sampled relative degree): P_d is evaluated at
            :meth:`sample_times`.
        """
        return circle_reference(self.sample_times(shift))

    def disturbance(self, t) -> np.ndarray:
        r"""The paper's disturbance 0.01 sin(40 π t) (per channel, same on every channel).

        Parameters
        ----------
        t : array_like
            Times [s], any shape.

        Returns
        -------
        ndarray
            :math:`A \sin(2 \pi f t)` with the scenario's ``disturbance_amplitude`` A and
            ``disturbance_frequency`` f, shaped like ``t``.
        """
        t = np.asarray(t, dtype=float)
        return self.disturbance_amplitude * np.sin(2 * np.pi * self.disturbance_frequency * t)

    def proposed_forgetting(self) -> VariableForgetting:
        """The paper's variable forgetting factor (eq 12)."""
        return VariableForgetting(delta=self.delta, Lambda=self.Lambda)

    def fixed_forgetting_law(self) -> FixedForgetting:
        """The traditional law's constant forgetting factor."""
        return FixedForgetting(self.fixed_forgetting)

    def replace(self, **changes) -> PaperScenario:
        """A copy with some fields changed (validated)."""
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise ParameterError(f"unknown scenario field(s) {unknown}; known: {sorted(names)}")
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["u0"] = list(self.u0)
        d["params"] = self.params.as_dict()
        return d


def load_scenario(path: str | Path | None = None) -> PaperScenario:
    """Load a scenario from TOML (default: the packaged ``paper.toml``). Unknown keys are errors.

    The ``[params]`` table overrides robot parameters by name (Table 1 otherwise). Every value
    is validated as in :class:`PaperScenario` (a boolean or a string where a number is
    expected is an error, not 1.0).

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The scenario's TOML file; None (default) loads the packaged ``paper.toml``.

    Returns
    -------
    PaperScenario

    Raises
    ------
    ParameterError
        The file is missing, not a regular file (a directory, a FIFO: refused before it is
        opened), too large, not UTF-8, not TOML, nested too deeply
        (:func:`~ilc_analysis._validation.read_toml_file`), or a key is unknown or its value
        of the wrong form; the message names the file and the key.
    """
    if path is None:
        data = tomllib.loads(resources.files(__package__).joinpath("paper.toml").read_text())
        source = "scenario file 'paper.toml'"
    else:
        source = f"scenario file {str(path)!r}"
        data = read_toml_file(path, "scenario file")
    params = table(data.pop("params", {}), "params", source)
    names = {f.name for f in dataclasses.fields(PaperScenario)} - {"params"}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ParameterError(f"{source}: unknown key(s) {unknown}; "
                             f"allowed: {sorted(names | {'params'})}")
    try:
        return PaperScenario(**data, params=RobotParameters().replace(**params))
    except (ParameterError, ShapeError) as exc:
        raise type(exc)(f"{source}: {exc}") from exc


def paper_scenario() -> PaperScenario:
    """The packaged paper scenario (``paper.toml``)."""
    return load_scenario(None)
