"""``ilc-analysis check``: verdicts of the convergence conditions for a gain set.

``--scenario paper`` uses the paper's Section 5 settings (``ilc_analysis.scenarios``: trial
length, sample time, δ, Λ, disturbances) with the documented default gains of
:func:`paper_default_gains`, since the paper gives no gains. ``--gains FILE.toml`` reads a gains
file (:func:`ilc_analysis.law.load_gains`); its ``ts`` and ``[forgetting]`` are used when given.
"""

from __future__ import annotations

import argparse
import warnings

import control
import numpy as np

from ..conditions.report import analyse
from ..law import PDGains, VariableForgetting, load_gains
from ..model import balanced_mobile_robot, planar_robot
from .common import CLIError, check_trial_length, emit_json, load_input, params_from_args

__all__ = ["register", "run", "paper_default_gains", "CHECK_MODELS", "LEARNING_FRACTION"]

#: ``--model`` names. ``mobile`` is the mobile robot with its inner LQR balance loop (inputs are
#: torque commands), the paper scenario's model: learning terms on (X, Y, psi) alone cannot
#: stabilise the pitch of the bare mobile robot.
CHECK_MODELS = {"planar": planar_robot, "mobile": balanced_mobile_robot}
#: Default sample time and trial length when neither the scenario nor the gains file gives them.
DEFAULT_TS, DEFAULT_HORIZON = 0.01, 2.0
#: Open-loop (previous-trial) gains of the default set as a fraction of the current-trial ones.
LEARNING_FRACTION = 0.5
#: LQR weights of the default current-trial loops: planar on (x, x_dot, theta, theta_dot);
#: mobile (balanced) on (X, psi, v, theta, theta_dot, psi_dot), with the input weights.
PLANAR_LQR = ((10.0, 1.0, 10.0, 1.0), (1.0,))
MOBILE_LQR = ((1.0, 1.0, 0.0, 0.0, 0.0, 0.0), (10.0, 10.0))


def paper_default_gains(model: str, plant) -> PDGains:
    r"""The default gain set of ``--scenario paper`` (the paper gives none).

    The current-trial gains :math:`\Psi_2, \Phi_2` are an LQR state feedback of the
    linearisation at rest read as output PD feedback: for the planar robot the outputs
    :math:`(x, \theta)` and their derivatives are the whole state, so
    :math:`u = -Kx = \Psi_2 e + \Phi_2\dot e` with :math:`\Psi_2 = K_{[x,\theta]}`,
    :math:`\Phi_2 = K_{[\dot x,\dot\theta]}` (:data:`PLANAR_LQR`); for the balanced mobile robot
    an LQR on :math:`(X, \psi, v, \theta, \dot\theta, \dot\psi)` (:data:`MOBILE_LQR`, Y is not
    controllable at rest), keeping the X, ψ and their rate columns (the balance loop already
    acts on θ). The previous-trial gains are :data:`LEARNING_FRACTION` times these. They are a
    starting point, not a certified design: ``check`` reports what they do.
    """
    sys = plant.linearize()
    A, B = np.asarray(sys.A), np.asarray(sys.B)
    if model == "planar":
        q, r = PLANAR_LQR
        K, _, _ = control.lqr(A, B, np.diag(q), np.diag(r))
        Psi2, Phi2 = K[:, [0, 2]], K[:, [1, 3]]
    else:
        q, r = MOBILE_LQR
        idx = [0, 2, 3, 4, 5, 6]  # X, psi, v, theta, theta_dot, psi_dot
        K, _, _ = control.lqr(A[np.ix_(idx, idx)], B[idx], np.diag(q), np.diag(r))
        Psi2, Phi2 = np.zeros((2, 3)), np.zeros((2, 3))
        Psi2[:, 0], Psi2[:, 2] = K[:, 0], K[:, 1]
        Phi2[:, 0], Phi2[:, 2] = K[:, 2], K[:, 5]
    return PDGains(LEARNING_FRACTION * Phi2, Phi2, LEARNING_FRACTION * Psi2, Psi2)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "check", help="verdicts of the convergence conditions for a gain set",
        description="Evaluate the paper's theorem (and its relative-degree-aware form), the "
                    "lifted checks (spectral radius, norms, transient growth, error floor) and "
                    "the frequency-domain condition; each condition with value and verdict.")
    p.add_argument("--model", choices=sorted(CHECK_MODELS), default="planar",
                   help="planar robot, or mobile robot with its inner balance loop "
                        "(default: planar)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="override a robot parameter (repeatable)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", choices=("paper",),
                     help="the paper's Section 5 settings with the documented default gains")
    src.add_argument("--gains", metavar="FILE.toml", help="gains file (see load_gains)")
    p.add_argument("--relative-degree-aware", action="store_true",
                   help="evaluate the theorem with H = C A^(r-1) B instead of CB")
    p.add_argument("--ts", type=float, default=None, help="sample time [s] (default: the "
                   "gains file's or scenario's, else 0.01)")
    p.add_argument("-N", type=int, default=None, dest="N",
                   help="samples per trial (default: trial length / ts, 2 s)")
    p.add_argument("--k-f", type=float, default=None, dest="k_f",
                   help="Lipschitz constant k_f (default: ||A||_2 of the linearisation)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    plant = CHECK_MODELS[args.model](params)
    disturbances = None
    horizon = DEFAULT_HORIZON
    if args.scenario == "paper":
        from ..scenarios import paper_scenario
        from ..scenarios.pipeline import scenario_disturbance_bounds

        sc = paper_scenario()
        gains = paper_default_gains(args.model, plant)
        forgetting = VariableForgetting(delta=sc.delta, Lambda=sc.Lambda)
        ts_file = sc.ts
        horizon = sc.horizon
        disturbances = scenario_disturbance_bounds(sc, plant.n_x, plant.n_y)
        source = "scenario paper (default gains: LQR current-trial loop, see check --help)"
    else:
        gf = load_input(args.gains, "--gains", load_gains)
        gains, forgetting, ts_file = gf.gains, gf.forgetting, gf.ts
        source = f"gains file {args.gains}"
    ts = args.ts if args.ts is not None else (ts_file if ts_file is not None else DEFAULT_TS)
    if not np.isfinite(ts) or ts <= 0:
        raise CLIError(f"--ts must be a positive number of seconds; got {ts!r}")
    N = args.N if args.N is not None else int(round(horizon / ts))
    if N < 1:
        raise CLIError(f"-N must be at least 1 sample; got {N}")
    check_trial_length(N, plant.n_y, plant.n_u, "-N")
    gains.check_dimensions(plant.n_u, plant.n_y, N)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = analyse(plant, gains, forgetting, ts=ts, N=N,
                         relative_degree_aware=args.relative_degree_aware, k_f=args.k_f,
                         disturbances=disturbances)
    notes = [f"{w.category.__name__}: {w.message}" for w in caught]
    notes.append("lifted along u = 0 from the state x0 = 0 (at rest); the theorem uses the "
                 "linearisation there")
    if args.json:
        out = report.to_dict()
        out["source"] = source
        out["model"] = args.model
        out["warnings"] = notes
        emit_json(out)
    else:
        print(f"[{source}]")
        print(report.to_text())
        for n in notes:
            print(f"Warning: {n}")
    return 0
