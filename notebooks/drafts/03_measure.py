"""Every number of notebooks/drafts/03_nonlinear_failure.md (issue 25: why notebook 03's certified
gains fail on the nonlinear robot, and what to do about it).

Run from the repository root (about a minute):

    PYTHONPATH=$PWD MPLBACKEND=Agg python notebooks/drafts/03_measure.py

Written against the phase-1 names; after the issue-25 renames replace
  ilc_analysis.analysis.analyse      -> analyze
  ilc_analysis.synthesis.synthesize_lifted(...) -> synthesize(problem, method='lifted', ...)
  ilc_analysis.laws (PDGains, FixedForgetting)   -> ilc_analysis.laws
  ilc_analysis.simulation.OpenClosedLoopPDLaw    -> laws.PDLaw (simulate(problem, law, K))
The measurement itself does not depend on the names.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
from scipy.optimize import least_squares

from ilc_analysis.analysis import analyse
from ilc_analysis.laws import FixedForgetting, NonlinearNormOptimalLaw, NormOptimalLaw, PDLaw
from ilc_analysis.lifting import lift
from ilc_analysis.lifting._trial_map import TrialMap
from ilc_analysis.model import discretize, planar_robot
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import OpenClosedLoopPDLaw, QFilter, simulate
from ilc_analysis.simulation._divergence import FALL_ANGLE
from ilc_analysis.synthesis import lqr_pd_feedback, synthesize_lifted

# the local analyses warn about transient growth (that is what they are about); the numbers
# printed below carry the same information
warnings.simplefilter("ignore")
np.set_printoptions(precision=4, suppress=True, linewidth=120)
START = time.time()
K = 30                  # trials, as in the notebook
A = 0.15                # the notebook's forgetting factor


def section(title):
    print(f"\n=== {title} ({time.time() - START:.0f} s)")


# ------------------------------------------------------------------------------------------------
# The notebook's setup, verbatim (cells 1, 2, 4, 6)
# ------------------------------------------------------------------------------------------------
plant = planar_robot()
ts, N = 0.01, 60
feedback = lqr_pd_feedback(plant.linearize(), np.diag([10, 1, 10, 1]), np.eye(1))
dplant = discretize(plant, ts)                      # the nonlinear robot, sampled
dlin = discretize(plant.linearize(), ts)            # its linearisation at the upright
lifted = lift(dplant, N)                            # "at the upright, at rest"
certified = synthesize_lifted(lifted, feedback=feedback, lead=0, forgetting=A,
                              objective="mean", target=0.99)
t = np.arange(N) * ts
u_true = 0.4 * np.sin(np.pi * t / t[-1])[:, None]
y_d = lifted.predict(u_true).reshape(N, 2)
trial_map = TrialMap(dplant, N, shift=lifted.shift)  # the nonlinear trial y = F(u)


def pd(gains, q_filter=None):
    return PDLaw(gains, FixedForgetting(A), q_filter=q_filter)


def local(gains, u_nominal, reference=y_d, q_filter=None):
    """rho(T), ||T||_2, transient peak of T on the nonlinear robot linearised along u_nominal
    (the LOCAL verdict of analyse on the trajectory-lifted problem)."""
    problem = ILCProblem(dplant, ts, N, reference, shift=lifted.shift, u_nominal=u_nominal)
    an = analyse(problem, pd(gains, q_filter), horizon=100)
    return (an["spectral_radius"].value, an["norm_2"].value, an["transient_peak"].value, an)


def run(gains, reference, system=dplant, q_filter=None):
    law = OpenClosedLoopPDLaw(gains, FixedForgetting(A), u0=np.zeros(1), q_filter=q_filter)
    return simulate(system, law, reference, K, np.zeros(4))


def one_line(label, gains, reference, q_filter=None):
    nl, li = run(gains, reference, q_filter=q_filter), run(gains, reference, dlin, q_filter)
    d, dl = nl.dataset, li.dataset
    e, el = d.e_norm.values, dl.e_norm.values
    rho, n2, peak, _ = local(gains, d.u.values[-1], reference, q_filter)
    print(f"{label}: nonlinear ||e||_2 trial 1 {e[0]:.4f}, best {e.min():.4f} (trial "
          f"{e.argmin() + 1}), trial {K} {e[-1]:.4f} (x{e[-1] / e[0]:.3f}); linearised x"
          f"{el[-1] / el[0]:.3f}; max|pitch| {np.abs(d.y.values[:, :, 1]).max():.3f} rad; "
          f"||u_{K}||_2 {np.linalg.norm(d.u.values[-1]):.2f} (linearised "
          f"{np.linalg.norm(dl.u.values[-1]):.2f}); along trial {K}: rho {rho:.3f}, "
          f"||T||_2 {n2:.3f}, peak {peak:.2f}; diverged: {bool(nl.diverged)}")
    return nl, li


def l1_norm(gains):
    L1 = lifted.learning_operators(gains)[0]
    return np.linalg.norm(L1.toarray() if hasattr(L1, "toarray") else np.asarray(L1), 2)


# ------------------------------------------------------------------------------------------------
section("1. What the certificate covers")
print(certified.summary())
G0, G_lti = lifted.G, lift(dlin, N).G
print(f"lift(dplant, N) is the Jacobian along u = 0 from rest: max |G - G_LTI| = "
      f"{np.abs(G0 - G_lti).max():.1e} (max |G| = {np.abs(G0).max():.3f})")
rho0, n0, p0, an0 = local(certified.gains, np.zeros((N, 1)))
print(f"at rest: rho(T) = {rho0:.4f}, ||T||_2 = {n0:.4f}, transient peak {p0:.4f}")
print("analyse says:", an0.summary())

section("2. The failure, trial by trial")
nl0, li0 = run(certified.gains, y_d), run(certified.gains, y_d, dlin)
print(f"reference: max |x_d| = {np.abs(y_d[:, 0]).max():.4f} m, max |theta_d| = "
      f"{np.abs(y_d[:, 1]).max():.4f} rad (at t = {t[np.abs(y_d[:, 1]).argmax()] + ts:.2f} s)")
X1, Y1 = trial_map.trajectory(u_true)
print(f"the nonlinear robot under u_true pitches to {np.abs(Y1[:, 1]).max():.4f} rad; "
      f"||y_d - F(u_true)||_2 = {np.linalg.norm(y_d - Y1):.4f}")
print("trial | nonlinear: ||e||_2  max|e_x|  max|e_th|  max|pitch|  ||u||_2  max|u| "
      "| linearised: ||e||_2  ||u||_2")
for i in (0, 1, 2, 3, 4, 9, 19, 29):
    d, dl = nl0.dataset, li0.dataset
    print(f"{i + 1:5d} | {d.e_norm.values[i]:.4f}  {d.max_abs_e.values[i, 0]:.4f}  "
          f"{d.max_abs_e.values[i, 1]:.4f}  {np.abs(d.y.values[i, :, 1]).max():.3f}  "
          f"{np.linalg.norm(d.u.values[i]):6.2f}  {np.abs(d.u.values[i]).max():5.2f} | "
          f"{dl.e_norm.values[i]:.4f}  {np.linalg.norm(dl.u.values[i]):.2f}")
e_nl = nl0.dataset.e_norm.values
print(f"nonlinear: best trial {e_nl.argmin() + 1}; error grows in every trial from trial "
      f"{e_nl.argmin() + 2} on: {bool(np.all(np.diff(e_nl[e_nl.argmin():]) > 0))}; diverged: "
      f"{bool(nl0.diverged)} (fall angle {FALL_ANGLE:.3f} rad)")
e_li = li0.dataset.e_norm.values
print(f"linearised: largest increase of ||e||_2 between trials {np.diff(e_li).max():.1e} "
      f"(the notebook's 'monotone: False' is this rounding-level step)")
an_floor = analyse(ILCProblem(dlin, ts, N, y_d, shift=lifted.shift), pd(certified.gains))
print(f"analysis' error floor on the linearisation {an_floor['error_floor'].value:.4f}; "
      f"simulated trial {K}: {e_li[-1]:.4f}")

section("3. T along the trajectories the robot follows (LOCAL verdicts)")
print(f"along the reference input u_true: rho {local(certified.gains, u_true)[0]:.4f}, "
      f"||T||_2 {local(certified.gains, u_true)[1]:.3f}, peak "
      f"{local(certified.gains, u_true)[2]:.3f}")
for i in (0, 1, 2, 4, 9, 19, 29):
    rho, n2, peak, _ = local(certified.gains, nl0.dataset.u.values[i])
    print(f"along trial {i + 1:2d} (its applied input): rho {rho:.4f}, ||T||_2 {n2:.3f}, "
          f"peak {peak:.2f}")
G_ref = lift(dplant, N, u_nominal=u_true, shift=lifted.shift).G
L1 = lifted.learning_operators(certified.gains)[0]
L1 = L1.toarray() if hasattr(L1, "toarray") else np.asarray(L1)
print(f"sensitivity: ||G_0||_2 {np.linalg.norm(G0, 2):.3f}, ||G_ref - G_0||_2 "
      f"{np.linalg.norm(G_ref - G0, 2):.3f}; ||L1||_2 {np.linalg.norm(L1, 2):.0f}, "
      f"||L1 G_0||_2 {np.linalg.norm(L1 @ G0, 2):.1f}, ||L1 (G_ref - G_0)||_2 "
      f"{np.linalg.norm(L1 @ (G_ref - G0), 2):.2f}")

section("4. The same gains, smaller references (u_true scaled)")
for amp in (0.05, 0.1, 0.2, 0.3, 0.4):
    ref = lifted.predict(amp / 0.4 * u_true).reshape(N, 2)
    one_line(f"amplitude {amp} (max|theta_d| {np.abs(ref[:, 1]).max():.3f})",
             certified.gains, ref)

section("5. The cause: y_d is the linearisation's trajectory, not the robot's")
eye = np.eye(N)
for lam in (1e-3, 1e-4, 1e-5, 1e-6, 0.0):
    s = np.sqrt(lam)
    sol = least_squares(
        lambda u, s=s: np.concatenate([trial_map.outputs(u) - y_d.ravel(), s * u]),
        u_true.ravel(), method="lm",
        jac=lambda u, s=s: np.vstack([lift(dplant, N, u_nominal=u.reshape(N, 1),
                                           shift=lifted.shift).G, s * eye]))
    e = y_d.ravel() - trial_map.outputs(sol.x)
    print(f"min ||y_d - F(u)||^2 + {lam:g} ||u||^2 on the robot: ||e||_2 {np.linalg.norm(e):.4f} "
          f"with ||u||_2 {np.linalg.norm(sol.x):.2f} (||u_true||_2 {np.linalg.norm(u_true):.2f})")
_, _, _, an_ref = local(certified.gains, u_true)
print("analyse along u_true, notes:", an_ref.notes)
y_nl = trial_map.outputs(u_true).reshape(N, 2)         # the robot's own response: reachable
one_line("reference = the robot's response F(u_true)", certified.gains, y_nl)
y_par = (G0 @ np.linalg.lstsq(G0, y_nl.ravel(), rcond=None)[0]).reshape(N, 2)
y_perp = np.linalg.norm(y_nl - y_par)
print(f"on the linearisation F(u_true) has an unreachable part ||(I - G G^+) y||_2 = "
      f"{y_perp:.4f} ({y_perp / np.linalg.norm(y_nl):.2%}"
      f" of the reference); the linearisation (exactly linear: the parts superpose):")
for label, ref in (("F(u_true)", y_nl), ("its reachable part", y_par),
                   ("its unreachable part alone", y_nl - y_par)):
    d = run(certified.gains, ref, dlin).dataset
    print(f"  reference {label}: ||e||_2 trial 1 {d.e_norm.values[0]:.4f}, trial {K} "
          f"{d.e_norm.values[-1]:.4f}, ||u_{K}||_2 {np.linalg.norm(d.u.values[-1]):.2f}")

section("6. What to do")
ls_ref = lift(dplant, N, u_nominal=u_true, shift=lifted.shift)
for lead in (0, 1, 2, 3, 5, 10):
    r = synthesize_lifted(ls_ref, feedback=feedback, lead=lead, forgetting=A, objective="worst")
    print(f"time-invariant PD along the reference, lead {lead}: {r.status}: {r.message}")
r = synthesize_lifted([lifted, ls_ref], feedback=feedback, lead=0, forgetting=A,
                      objective="worst")
print(f"time-invariant PD robust over (rest, reference): {r.status}: {r.message}")
designs = {
    "time-varying (knots every 10 samples), along the reference, minimax": synthesize_lifted(
        ls_ref, feedback=feedback, lead=0, forgetting=A, objective="worst", time_varying=True,
        knot_spacing=10),
    "time-varying (knots every 10 samples), along the reference, mean s.t. < 0.99":
        synthesize_lifted(ls_ref, feedback=feedback, lead=0, forgetting=A, objective="mean",
                          target=0.99, time_varying=True, knot_spacing=10),
    "time-varying (knots every 10 samples), robust over (rest, reference), minimax":
        synthesize_lifted([lifted, ls_ref], feedback=feedback, lead=0, forgetting=A,
                          objective="worst", time_varying=True, knot_spacing=10),
}
print(f"(the notebook's gains: ||L1||_2 = {l1_norm(certified.gains):.0f})")
for name, r in designs.items():
    print(f"-- {name}: {r.status}: {r.message}; ||L1||_2 = {l1_norm(r.gains):.3g}")
    rest, ref = local(r.gains, np.zeros((N, 1))), local(r.gains, u_true)
    print(f"   ||T||_2 at rest {rest[1]:.3f}, along the reference {ref[1]:.3f}")
    one_line("   reference F(u_true)", r.gains, y_nl)
    one_line("   reference y_d", r.gains, y_d)
for fc in (20.0, 10.0, 5.0):
    q = QFilter.dct(cutoff=fc)
    rest = local(certified.gains, np.zeros((N, 1)), q_filter=q)
    print(f"Q-filter dct {fc:g} Hz on the certified gains: ||T||_2 at rest {rest[1]:.3f} "
          f"(rho {rest[0]:.3f})")
    one_line("   reference y_d", certified.gains, y_d, q_filter=q)
problem = ILCProblem(dplant, ts, N, y_d, shift=lifted.shift, name="robot, y_d")
s_max = np.linalg.norm(problem.lifted.G, 2)
for rho_w in (1e-2, 1e-3):
    for label, law in (
            ("norm-optimal on the linearisation at rest",
             NormOptimalLaw(problem.lifted, weight_input_change=rho_w * s_max**2)),
            ("nonlinear norm-optimal (Gauss-Newton per trial)",
             NonlinearNormOptimalLaw(problem, weight_error=1.0,
                                     weight_input_change=rho_w * s_max**2))):
        d = simulate(problem, law, K).dataset
        e = d.e_norm.values
        print(f"{label}, R = {rho_w:g} sigma_max^2: ||e||_2 trial 1 {e[0]:.4f}, trial {K} "
              f"{e[-1]:.4f}, ||u_{K}||_2 {np.linalg.norm(d.u.values[-1]):.2f}, max|pitch| "
              f"{np.abs(d.y.values[:, :, 1]).max():.3f}, ||e||_2 monotone "
              f"{bool(np.all(np.diff(e) <= 0))}")
print(f"\ndone in {time.time() - START:.0f} s")
