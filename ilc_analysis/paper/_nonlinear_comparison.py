r"""Nonlinear against linearised norm-optimal ILC on the robot when the nominal is poor.

The robot's balance loop about rest (``mobile_balanced`` with the loop balancing about
standstill, :attr:`PaperScenario.inner_loop` = ``"rest"``) learns the paper's circle. Its
lifted model is taken along a poor nominal, :math:`u = 0` (the robot braking to rest from the
circle's initial state) instead of the input the circle needs (about 1 N m away). Two laws
with the same weights run the same number of simulated trials from the same first trial:

* **linearised**: :class:`~ilc_analysis.laws.NormOptimalLaw` on that fixed lifted model
  :math:`G`, :math:`u_{i+1} = u_i + (G^\top QG + R)^{-1}G^\top Q e_i`;
* **nonlinear**: :class:`~ilc_analysis.laws.NonlinearNormOptimalLaw` (Gauss-Newton on the
  trial map, re-linearised about every measured trial, with the model correction
  :math:`d_i = y_i - \hat y(u_i)`).

Weights: :math:`Q = I` on (X, Y, ψ), :math:`R = \rho\,\sigma_{\max}(G)^2 I` with
:math:`\rho = 10^{-2}` (the rule of the scenario's norm-optimal design,
:func:`~ilc_analysis.paper._designs.paper_run_laws`; not tuned here). A trial in which
:math:`|\theta|` exceeds the scenario's fall angle ends the law's run (it fell). No
disturbances: the comparison is of the laws, not of their noise sensitivity.

:func:`nonlinear_comparison` returns the numbers and :meth:`NonlinearComparison.markdown` a
paragraph for the report that states which law reached the lower final error, or why the
nonlinear law did not.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .._validation import positive, positive_int
from ._robot import PITCH_METRIC, fall_bounds

__all__ = ["NonlinearComparison", "LawRun", "nonlinear_comparison"]

#: R = RHO * sigma_max(G)^2: the scenario's norm-optimal weight rule
DEFAULT_RHO = 1e-2


@dataclass(frozen=True)
class LawRun:
    """One law's simulated run."""

    name: str
    rms: np.ndarray = field(repr=False)
    """RMS error over the window and all outputs, per completed trial"""
    max_pitch: np.ndarray = field(repr=False)
    """max |θ| per completed trial [rad]"""
    fell: str = ""
    """the divergence (trial, time, |θ|) when the robot fell; else empty"""

    @property
    def final(self) -> float:
        """RMS error of the last completed trial (NaN when it fell in the first)."""
        return float(self.rms[-1]) if self.rms.size else float("nan")


@dataclass(frozen=True)
class NonlinearComparison:
    """The comparison's numbers (module docstring).

    Parameters
    ----------
    N : int
        Samples per trial.
    trials : int
        Trials run per law.
    ts : float
        Sample time [s].
    weight_input_change : float
        The norm-optimal weight R on the input change (both laws).
    gauss_newton_steps : int
        Gauss-Newton steps per trial of the nonlinear law.
    linearized : LawRun
        The norm-optimal law on the fixed lifted model.
    nonlinear : LawRun
        The nonlinear norm-optimal law (Gauss-Newton on the trial map).
    certificates : tuple
        The nonlinear law's per-trial certificates.
    """

    N: int
    trials: int
    ts: float
    weight_input_change: float
    gauss_newton_steps: int
    linearized: LawRun
    nonlinear: LawRun
    certificates: tuple = field(repr=False, default=())
    """the nonlinear law's per-trial :class:`GaussNewtonCertificate`"""

    @property
    def nonlinear_wins(self) -> bool:
        """The nonlinear law did not fall and ended lower (or the linearised law fell)."""
        nl, lin = self.nonlinear, self.linearized
        if nl.fell:
            return False
        return bool(lin.fell) or nl.final < lin.final

    def markdown(self) -> str:
        """A paragraph and a per-trial table for the report."""
        lin, nl = self.linearized, self.nonlinear

        def run_text(r: LawRun) -> str:
            done = r.rms.size
            if r.fell:
                return (f"fell in trial {done + 1} ({r.fell}) after {done} completed trial(s)"
                        + (f", last RMS error {r.final:.3g}" if done else ""))
            return (f"RMS error {r.rms[0]:.3g} → {r.final:.3g} over {done} trials (max |θ| "
                    f"{np.max(r.max_pitch):.2f} rad)")

        head = (f"**Nonlinear vs linearised norm-optimal ILC on the balance loop about rest.** "
                f"The robot with its balance loop about standstill learns the paper's circle "
                f"over N = {self.N} samples ({self.N * self.ts:g} s), lifted along the poor "
                f"nominal u = 0. Both laws use Q = I and R = {self.weight_input_change:.3g} "
                f"(1e-2 σ_max(G)², not tuned) and start from the same first trial; no "
                f"disturbances. The linearised law (NormOptimalLaw on the fixed G): "
                f"{run_text(lin)}. The nonlinear law ({self.gauss_newton_steps} Gauss-Newton "
                f"steps per trial, re-linearised about each measured trial with model "
                f"correction): {run_text(nl)}. ")
        if self.nonlinear_wins:
            verdict = ("Nonlinear ILC reaches the lower final error"
                       + (": the linearised law's fixed G misjudges the motion the circle "
                          "needs and its update makes the robot fall."
                          if lin.fell else
                          f" ({nl.final:.3g} against {lin.final:.3g})."))
        elif nl.fell:
            verdict = (f"Nonlinear ILC does NOT reach a lower final error: it fell too "
                       f"({nl.fell}); re-linearising about the measured trial does not keep the "
                       f"pitch within the fall angle.")
        else:
            last = self.certificates[-1] if self.certificates else None
            why = "" if last is None else (
                f" Its last update predicted the model cost {last.cost_before:.3g} → "
                f"{last.cost_after:.3g} in {last.gn_steps} Gauss-Newton step(s).")
            verdict = (f"Nonlinear ILC does NOT reach a lower final error ({nl.final:.3g} "
                       f"against {lin.final:.3g}).{why}")
        n = max(lin.rms.size, nl.rms.size)
        rows = ["| trial | linearised RMS | nonlinear RMS |", "|---:|---:|---:|"]
        for k in range(n):
            cells = [f"{r.rms[k]:.4g}" if k < r.rms.size else ("fell" if k == r.rms.size
                                                                and r.fell else "")
                     for r in (lin, nl)]
            rows.append(f"| {k + 1} | {cells[0]} | {cells[1]} |")
        return head + verdict + "\n\n" + "\n".join(rows) + "\n"


def _run(problem, law, trials: int, bounds) -> LawRun:
    from ..simulation import simulate

    res = simulate(problem, law, trials, bounds=bounds)
    e = res.dataset["e"].values                      # (iteration, time, channel)
    n = e.shape[0]                                   # completed trials (0: fell in the first)
    rms = np.sqrt(np.mean(e ** 2, axis=(1, 2))) if n else np.zeros(0)
    pitch = (res.dataset[PITCH_METRIC].values.reshape(n, -1).max(axis=1)
             if PITCH_METRIC in res.dataset and n else np.full(n, np.nan))
    fell = "" if res.divergence is None else (f"|θ| {res.divergence.reason.split('= ')[-1]} "
                                              f"at t = {res.divergence.time:.3g} s"
                                              if res.divergence.state == "theta"
                                              else res.divergence.reason)
    return LawRun(law.name, rms, pitch, fell)


def nonlinear_comparison(scenario=None, *, N: int | None = None, trials: int = 10,
                         iterations: int = 3, rho: float = DEFAULT_RHO) -> NonlinearComparison:
    r"""Run the comparison (module docstring).

    Parameters
    ----------
    scenario : PaperScenario, optional
        Default: the packaged paper scenario; its ``inner_loop`` is set to ``"rest"``.
    N : int, optional
        Trial length (default the scenario's, 200 = one lap).
    trials : int
        Simulated trials per law (>= 2).
    iterations : int
        Gauss-Newton steps per trial of the nonlinear law.
    rho : float
        :math:`R = \rho\,\sigma_{\max}(G)^2`.

    Returns
    -------
    NonlinearComparison
    """
    from ..laws import NonlinearNormOptimalLaw, NormOptimalLaw
    from ._config import paper_scenario
    from ._paper_problem import scenario_problem

    sc = paper_scenario() if scenario is None else scenario
    sc = dataclasses.replace(sc, inner_loop="rest")
    N = sc.N if N is None else positive_int(N, "N (trial length)", minimum=2)
    trials = positive_int(trials, "trials", minimum=2)
    rho = positive(rho, "rho (R = rho sigma_max(G)^2)")
    problem, _, _ = scenario_problem(sc, N=N, u_nominal=np.zeros((N, 2)))
    G = problem.lifted.G
    R = rho * float(np.linalg.norm(G, 2)) ** 2
    bounds = fall_bounds(sc.fall_angle)
    linearised = NormOptimalLaw(problem.lifted, weight_input_change=R, weight_error=1.0,
                                name="linearised norm-optimal")
    nonlinear = NonlinearNormOptimalLaw(problem, 1.0, R, iterations=iterations,
                                        name="nonlinear norm-optimal")
    lin = _run(problem, linearised, trials, bounds)
    nl = _run(problem, nonlinear, trials, bounds)
    return NonlinearComparison(N=N, trials=trials, ts=sc.ts, weight_input_change=R,
                               gauss_newton_steps=iterations, linearized=lin, nonlinear=nl,
                               certificates=tuple(nonlinear.history))
