r"""Pitch-bounded learning on the paper's circle: constrained norm-optimal ILC against the
unconstrained laws (issue "constrained and nonlinear optimisation-based ILC").

The paper motivates its variable forgetting factor by a smaller pitch angle; a constrained
learner can bound it instead. On the paper's problem (the balanced robot lifted along the
circle's realisable input :math:`u_d`, the paper's disturbances and first input
:math:`u_0`), :class:`~ilc_analysis.laws.ConstrainedNormOptimalLaw` learns with

.. math::

    |\theta(k)| \le \theta_{\max}\ (k \ge 1), \qquad |u(k)| \le u_{\max}

predicted through the stage model (the robot's Jacobians along :math:`u_d`) from the measured
states of each trial, with the bound backed off by the largest prediction error of
:math:`\theta` seen so far (model mismatch and disturbances). Beside it the unconstrained
norm-optimal law with the same weights (:math:`Q = 1`, :math:`R = r\,\sigma_{\max}(G)^2`).
Every simulated trial is checked (not the prediction): its largest |pitch| and |torque|.
The first trial is the scenario's :math:`u_0` for every law (the operator's input, not the
law's choice); the bound is claimed for the trials the law chooses, 2..K, and trial 1 is
reported as it is. A bound that makes the reference unreachable stops the run at that trial
and the result names the binding constraint (:class:`~ilc_analysis.laws.InfeasibleTrialError`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ParameterError

__all__ = ["PitchBoundedRow", "PitchBoundedStudy", "pitch_bounded_study"]

#: the study's default bounds: 0.06 rad (3.4 deg) of pitch, below the pitch the unconstrained
#: laws reach (so that the bound binds), and the scenario's first torque command, 0.1 N m, as
#: the largest command (u is the learned correction on each wheel)
DEFAULT_THETA_MAX = 0.06
DEFAULT_TORQUE_MAX = 0.1
#: R = factor * sigma_max(G)^2 (Q = 1): a fast learner (the reproduce norm-optimal design uses
#: 1e-2 with an input weight; this one has none)
DEFAULT_R_FACTOR = 1e-3


@dataclass(frozen=True)
class PitchBoundedRow:
    """One law's simulated run (every trial checked)."""

    law: str
    trials: int
    final_max_error: float
    final_rms_error: float
    max_pitch_first: float
    """|theta| of trial 1 (the scenario's u0, the same for every law)"""
    max_pitch_learned: float
    """largest |theta| over the trials the law chose (2..K); NaN if it ran one trial"""
    max_torque_learned: float
    pitch_within: bool | None
    """every chosen trial within theta_max (None: the law has no pitch bound)"""
    torque_within: bool | None
    stopped: str = ""
    """why the run stopped early (infeasible: the binding constraint; diverged: where)"""


@dataclass
class PitchBoundedStudy:
    """The study's numbers and its report section (:meth:`markdown`).

    Parameters
    ----------
    theta_max : float
        The pitch bound [rad].
    torque_max : float
        The input bound [N m].
    r_factor : float
        The norm-optimal weight rule's factor.
    iterations : int
        Trials per law.
    rows : list of PitchBoundedRow
        One row per law.
    certificates : list
        The constrained law's per-trial certificates.
    """

    theta_max: float
    torque_max: float
    r_factor: float
    iterations: int
    rows: list[PitchBoundedRow]
    certificates: list = field(default_factory=list)
    """the constrained law's per-trial certificates (``TrialCertificate.as_dict()``)"""

    def row(self, law: str) -> PitchBoundedRow:
        """The row of one law.

        Parameters
        ----------
        law : str
            The law's label, as in ``rows``.

        Returns
        -------
        PitchBoundedRow

        Raises
        ------
        ParameterError
            If no row has that label.
        """
        for r in self.rows:
            if r.law == law:
                return r
        raise ParameterError(f"no law {law!r} in the study; have {[r.law for r in self.rows]}")

    def markdown(self) -> str:
        """The report section "Pitch-bounded learning"."""
        con = self.rows[0]
        lines = [
            "## Pitch-bounded learning",
            "",
            f"Constrained norm-optimal ILC (`ConstrainedNormOptimalLaw`, stage form, HPIPM) on "
            f"the paper's problem with |theta| <= {self.theta_max:g} rad and |u| <= "
            f"{self.torque_max:g} N m, against the unconstrained norm-optimal law with the same "
            f"weights (Q = 1, R = {self.r_factor:g} sigma_max(G)^2), {self.iterations} trials, "
            f"the scenario's disturbances. Pitch and torque are those of the simulated trials. "
            f"Trial 1 is the scenario's u0 for both laws (not chosen by a law).",
            "",
            "| law | trials | max abs e, last | rms e, last | max abs pitch, trial 1 (rad) | "
            "max abs pitch, trials 2.. (rad) | max abs torque, trials 2.. (N m) | pitch bound "
            "held | torque bound held | stopped |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in self.rows:
            lines.append(
                f"| {r.law} | {r.trials} | {r.final_max_error:.4g} | {r.final_rms_error:.4g} | "
                f"{r.max_pitch_first:.4g} | {r.max_pitch_learned:.6g} | "
                f"{r.max_torque_learned:.4g} | {_yes(r.pitch_within)} | "
                f"{_yes(r.torque_within)} | {r.stopped or '-'} |")
        lines.append("")
        if con.stopped:
            lines.append(f"The constrained law stopped: {con.stopped}.")
        else:
            held = ("Every trial the constrained law chose held the bounds"
                    if con.pitch_within and con.torque_within else
                    "NOT every trial the constrained law chose held the bounds")
            lines.append(f"{held} in simulation (largest |pitch| {con.max_pitch_learned:.6g} "
                         f"rad against {self.theta_max:g}; largest |u| "
                         f"{con.max_torque_learned:.4g} against {self.torque_max:g}).")
        if self.certificates:
            back = [c["back_off"].get("theta", 0.0) for c in self.certificates]
            lines.append(f"The bound was backed off by the largest prediction error of theta "
                         f"seen so far: up to {max(back):.3g} rad (model: the robot linearised "
                         f"along u_d; the plant: the nonlinear robot with disturbances).")
        for other in self.rows[1:]:
            if other.trials and con.trials:
                lines.append(
                    f"Final max |e|: constrained {con.final_max_error:.4g} vs {other.law} "
                    f"{other.final_max_error:.4g} (largest pitch over trials 2..: "
                    f"{con.max_pitch_learned:.4g} vs {other.max_pitch_learned:.4g} rad).")
        lines.append("")
        return "\n".join(lines)


def _yes(flag: bool | None) -> str:
    return "-" if flag is None else ("yes" if flag else "NO")


def pitch_bounded_study(scenario=None, *, theta_max: float = DEFAULT_THETA_MAX,
                        torque_max: float = DEFAULT_TORQUE_MAX,
                        r_factor: float = DEFAULT_R_FACTOR, iterations: int | None = None,
                        problem=None) -> PitchBoundedStudy:
    r"""Run the study (module docstring).

    Parameters
    ----------
    scenario : PaperScenario, optional
        Default: the packaged paper scenario.
    theta_max : float
        Pitch bound [rad], > 0.
    torque_max : float
        Torque-command bound [N m], > 0 (must admit the scenario's u0).
    r_factor : float
        :math:`R = r\,\sigma_{\max}(G)^2` for both laws, > 0.
    iterations : int, optional
        Trials (default: the scenario's).
    problem : ILCProblem, optional
        The paper problem if already built (default: from the scenario, lifted along u_d,
        with its disturbances).
    """
    from ..laws import ConstrainedNormOptimalLaw, NormOptimalLaw
    from ..simulation import simulate
    from ._config import paper_scenario
    from ._paper_problem import scenario_disturbances, scenario_problem
    from ._robot import fall_bounds

    for value, name in ((theta_max, "theta_max"), (torque_max, "torque_max"),
                        (r_factor, "r_factor")):
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                np.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a finite number > 0; got {value!r}")
    sc = paper_scenario() if scenario is None else scenario
    if problem is None:
        problem = scenario_problem(sc, disturbances=scenario_disturbances(sc, seed=0))[0]
    K = sc.iterations if iterations is None else int(iterations)
    sigma2 = float(np.linalg.norm(problem.lifted.G, 2)) ** 2
    R = r_factor * sigma2
    theta = problem.dplant.state_names.index("theta")
    constrained = ConstrainedNormOptimalLaw(
        problem, 1.0, R, state_bounds={"theta": (-theta_max, theta_max)},
        input_bounds=(-torque_max, torque_max), name="constrained norm-optimal")
    unconstrained = NormOptimalLaw(problem.lifted, R, 1.0, name="norm-optimal (same weights)")
    rows = []
    fall = fall_bounds(sc.fall_angle)     # a fall ends a run, as in reproduce
    for law, bounded in ((_stop_at_infeasible(constrained), True), (unconstrained, False)):
        res = simulate(problem, law, K, bounds=fall)
        stopped = ""
        error = getattr(law, "error", None)
        if error is not None:
            last = error.certificate.trial + 1          # trials up to the failed update
            stopped = f"infeasible after trial {last}: {error.certificate.binding}"
            res_ds = res.dataset.isel(iteration=slice(0, last))
        else:
            res_ds = res.dataset
        if res.divergence is not None:
            stopped = f"diverged: {res.divergence}"
        rows.append(_row(law.name, res_ds, theta, bounded, theta_max, torque_max, stopped))
    return PitchBoundedStudy(theta_max, torque_max, r_factor, K, rows,
                             [c.as_dict() for c in constrained.history])


def _row(name, ds, theta, bounded, theta_max, torque_max, stopped) -> PitchBoundedRow:
    x = ds["x"].values
    u = ds["u"].values
    e = ds["e"].values
    n = x.shape[0]                                      # completed trials (0: fell in trial 1)
    nan = float("nan")
    pitch = np.max(np.abs(x[:, 1:, theta]), axis=1)    # k >= 1 (x(0) is the initial state)
    torque = np.max(np.abs(u), axis=(1, 2))
    learned_pitch = float(np.max(pitch[1:])) if n > 1 else nan
    learned_torque = float(np.max(torque[1:])) if n > 1 else nan
    return PitchBoundedRow(
        law=name, trials=n, final_max_error=float(np.max(np.abs(e[-1]))) if n else nan,
        final_rms_error=float(np.sqrt(np.mean(e[-1] ** 2))) if n else nan,
        max_pitch_first=float(pitch[0]) if n else nan,
        max_pitch_learned=learned_pitch, max_torque_learned=learned_torque,
        pitch_within=(bool(learned_pitch <= theta_max) if bounded and n > 1 else None),
        torque_within=(bool(learned_torque <= torque_max) if bounded and n > 1 else None),
        stopped=stopped)


def _stop_at_infeasible(law):
    """``law`` (a constrained law) that, instead of raising, records its first infeasible update
    and repeats the last input from then on (the study keeps only the trials before the
    stop)."""
    from ..laws import InfeasibleTrialError, LearningLaw

    class StopAtInfeasible(LearningLaw):
        name = law.name
        error = None
        uses_states = law.uses_states

        def lifted(self, lifted_system):
            return law.lifted(lifted_system)

        def check(self, lifted_system):
            law.check(lifted_system)

        def describe(self):
            return law.describe()

        def update(self, u_i, e_i, ts, *, states=None):
            if self.error is None:
                try:
                    return law.update(u_i, e_i, ts, states=states)
                except InfeasibleTrialError as exc:
                    self.error = exc
            return np.array(u_i, dtype=float)

    return StopAtInfeasible()
