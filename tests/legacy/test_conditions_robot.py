"""The paper's robot: the degenerate theorem (CB = 0), its relative-degree-aware form, and the
λ-norm ultimate bound against a nonlinear simulation of the paper's scenario."""

import json
import math

import control
import numpy as np
import pytest
from legacy_form import analyse

from ilc_analysis.analysis import DisturbanceBounds, evaluate_theorem, relative_degree_info
from ilc_analysis.analysis._relative_degree_form import sampled_diagonal_block
from ilc_analysis.analysis._verdicts import VERDICTS
from ilc_analysis.exceptions import DegenerateConditionWarning, TransientGrowthWarning
from ilc_analysis.laws import FixedForgetting, PDGains, VariableForgetting
from ilc_analysis.model import planar_robot
from ilc_analysis.model._robots import upright_linear_matrices

PLANAR = control.ss(*upright_linear_matrices())


def test_cb_zero_is_detected_and_the_gains_drop_out():
    info = relative_degree_info(PLANAR, output_names=("x", "theta"))
    assert info.degrees == (2, 2) and info.cb_zero
    np.testing.assert_allclose(info.H.ravel(), [0.735267, 4.633161], rtol=1e-6)  # CAB
    results = []
    for scale in (0.0, 1.0, -50.0):
        g = PDGains([[scale, 2 * scale]], [[3 * scale, scale]], [[1.0, 1.0]], [[2.0, 2.0]])
        with pytest.warns(DegenerateConditionWarning, match=r"CB = 0 on x, theta.*Phi1, Phi2"):
            th = evaluate_theorem(PLANAR, g, FixedForgetting(0.15), T=2.0,
                                  output_names=("x", "theta"))
        results.append((th.gamma1, th.gamma2, th.degenerate))
    assert results == [(pytest.approx(0.85), 1.0, True)] * 3   # whatever the gains


def test_variable_forgetting_makes_the_paper_condition_fail_at_a_to_zero():
    g = PDGains([[0.1, 0.1]], [[0.1, 0.1]], [[1.0, 1.0]], [[2.0, 2.0]])
    with pytest.warns(DegenerateConditionWarning):
        th = evaluate_theorem(PLANAR, g, VariableForgetting(), T=2.0)
    assert th.gamma1 == 1.0 and not th.holds


@pytest.mark.parametrize("Phi1, Phi2, holds", [
    ([[0.1, 0.1]], [[0.2, 0.1]], True),      # 1 - a - Phi1 CAB small, X = 1 + Phi2 CAB > 1
    ([[-0.1, -0.1]], [[-0.2, -0.1]], False),  # wrong sign: gamma2 > 1
    ([[0.5, 0.5]], [[0.0, 0.0]], False),      # too much gain: |0.85 - 2.68| > 1
])
def test_relative_degree_aware_form_distinguishes_gains(Phi1, Phi2, holds):
    g = PDGains(Phi1, Phi2, [[1.0, 1.0]], [[2.0, 2.0]])
    th = evaluate_theorem(PLANAR, g, FixedForgetting(0.15), T=2.0,
                          form="relative-degree-aware")
    assert not th.degenerate and th.holds is holds
    H = PLANAR.C @ PLANAR.A @ PLANAR.B
    Y = 0.85 - np.asarray(Phi1) @ H
    X = 1 + np.asarray(Phi2) @ H
    assert th.gamma1 == pytest.approx(abs(Y.item()))
    assert th.gamma2 == pytest.approx(1 / abs(X.item()))


def test_report_says_degenerate_and_why_and_aware_report_differs():
    g = PDGains([[0.1, 0.05]], [[0.2, 0.1]], [[1.0, 1.0]], [[2.0, 2.0]])
    with pytest.warns(DegenerateConditionWarning, match="degenerate"):
        rep = analyse(planar_robot(), g, FixedForgetting(0.15), ts=0.01, N=30,
                      transient_threshold=1e300)
    assert rep.verdict("gamma1_gamma2") == "degenerate"
    assert rep.verdict("cb_zero") == "degenerate"
    assert "CB = 0" in rep["gamma1"].meaning and "Phi1, Phi2" in rep["gamma1"].meaning
    g_bad = g.replace(Phi1=[[-0.1, -0.05]], Phi2=[[-0.2, -0.1]])
    verdicts = []
    for gains in (g, g_bad):
        with pytest.warns(DegenerateConditionWarning):
            rep = analyse(planar_robot(), gains, FixedForgetting(0.15), ts=0.01, N=30,
                          relative_degree_aware=True, transient_threshold=1e300)
        verdicts.append(rep.verdict("gamma1_gamma2"))
        assert rep.verdict("paper_gamma1_gamma2") == "degenerate"
    assert verdicts == ["holds", "fails"]


def test_sampled_form_is_the_diagonal_of_the_lifted_operator():
    from ilc_analysis.laws._gains import learning_operators
    from ilc_analysis.lifting import learning_operator, lift
    from ilc_analysis.model import DiscretePlant

    ts, N = 0.01, 12
    dsys = control.c2d(PLANAR, ts)
    info = relative_degree_info(PLANAR, dsys=dsys)
    assert info.shift == 1
    g = PDGains([[0.3, 0.1]], [[0.2, 0.4]], [[5.0, 1.0]], [[2.0, 7.0]])
    ls = lift(DiscretePlant.from_statespace(dsys), N)
    L1, L2 = learning_operators(g, N, ls.shift, ts)
    T = learning_operator(ls.G, L1, L2, 0.15)
    blocks, rho, _ = sampled_diagonal_block(info.H_sampled, g.Phi1, g.Psi1, 0.15, ts)
    np.testing.assert_allclose(np.diag(T), blocks[0, 0, 0, 0], rtol=1e-12)  # Phi2, Psi2 drop out
    assert rho == pytest.approx(max(abs(np.linalg.eigvals(blocks[0, 0]))))


def test_report_exports_are_json_text_and_html():
    g = PDGains([[0.1, 0.05]], [[0.2, 0.1]], [[1.0, 1.0]], [[2.0, 2.0]])
    with pytest.warns((DegenerateConditionWarning, TransientGrowthWarning)):
        rep = analyse(planar_robot(), g, VariableForgetting(), ts=0.01, N=40,
                      relative_degree_aware=True)
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    names = {c["name"] for c in d["conditions"]}
    assert {"gamma1", "gamma2", "gamma1_gamma2", "contraction_tight", "lambda_min",
            "ultimate_bound", "spectral_radius", "norm_2", "norm_inf", "transient_peak",
            "error_floor"} <= names
    assert all(c["verdict"] in VERDICTS for c in d["conditions"])
    assert d["relative_degree"]["per_output"] == {"x": 2, "theta": 2}
    assert set(rep["spectral_radius"].details) >= {"a=0", "a=0.15"}   # both forgetting bounds
    text = rep.to_text()
    assert "spectral_radius" in text and "Verdict:" in text
    html = rep._repr_html_()
    assert "<table>" in html and "degenerate" in html


# --- the lambda-norm ultimate bound against the nonlinear simulation of the paper's scenario ----
def test_lambda_norm_ultimate_bound_holds_in_the_paper_scenario():
    """The paper's scenario (ilc_analysis.paper) shortened to one half lap, T = 1 s
    (N = 100 at 100 Hz), on the balanced mobile robot with the paper's disturbances
    0.01 sin(40 pi t) on every state and output; u_d from the CasADi inverse solve
    (lifting.realizable_reference). The paper gives no gains: heading-aligned P-type learning
    gains (forward error to common-mode torque 0.02, heading error to differential torque
    0.002) and the traditional law's constant forgetting a = 0.15 (the theorem needs a > 0:
    with the variable factor, a -> 0 makes gamma1 = 1). The theorem's constants are taken along
    the reference: k_f = sup ||df/dx||, b_B = sup ||df/du||."""
    from ilc_analysis.laws import PDLaw
    from ilc_analysis.lifting import realizable_reference
    from ilc_analysis.model import discretize
    from ilc_analysis.paper import paper_scenario
    from ilc_analysis.problem._disturbances import Disturbances
    from ilc_analysis.simulation import DivergenceBounds
    from ilc_analysis.simulation._engine import simulate_plant

    sc = paper_scenario().replace(horizon=1.0)
    plant, N, a = sc.plant(), sc.N, 0.15
    dp = discretize(plant, sc.ts)
    x0 = sc.initial_state()
    y_d = sc.reference(1)
    ref = realizable_reference(dp, y_d, x0, N)
    assert ref.realisable()
    c, s = np.cos(y_d[:, 2]), np.sin(y_d[:, 2])
    Psi1 = np.stack([[[0.02 * ck, 0.02 * sk, -0.002], [0.02 * ck, 0.02 * sk, 0.002]]
                     for ck, sk in zip(c, s, strict=True)])
    gains = PDGains(np.zeros_like(Psi1), np.zeros_like(Psi1), Psi1, np.zeros_like(Psi1))
    law = PDLaw(gains, FixedForgetting(a), u0=np.array(sc.u0))
    dist = Disturbances(state_amplitude=sc.disturbance_amplitude,
                        output_amplitude=sc.disturbance_amplitude,
                        state_frequency=sc.disturbance_frequency,
                        output_frequency=sc.disturbance_frequency)
    res = simulate_plant(dp, law, y_d, sc.iterations, x0, disturbances=dist,
                   bounds=DivergenceBounds.fall_angle())
    assert not res.diverged
    du = ref.u_d[None] - res.dataset["u"].values          # (iteration, N, n_u)

    lin = [plant.linearize(x, u) for x, u in zip(ref.x_d[:N], ref.u_d, strict=True)]
    k_f = max(np.linalg.norm(np.asarray(sy.A), 2) for sy in lin)
    b_B = max(np.linalg.norm(np.asarray(sy.B), 2) for sy in lin)
    with pytest.warns(DegenerateConditionWarning):
        th = evaluate_theorem(
            lin[0], gains, FixedForgetting(a), T=sc.horizon, k_f=k_f,
            disturbances=DisturbanceBounds.sinusoid(
                sc.disturbance_amplitude, 2 * math.pi * sc.disturbance_frequency,
                plant.n_x, plant.n_y),
            delta_u0=float(np.max(np.linalg.norm(ref.u_d - np.array(sc.u0), axis=1))))
    lc = th.condition
    # b_B of the linearisation at x0 may differ along the reference: use the sup
    from ilc_analysis.analysis._paper_theorem import lambda_condition

    lc = lambda_condition(th.gamma1, th.gamma2, th.xi1, th.xi2, b_B=b_B, T=sc.horizon,
                          k_f=k_f, b_omega=lc.b_omega, mu0=th.mu0)
    assert lc.holds
    # ZOH input: sup_t e^{-lambda t}||du(t)|| is attained at the sample instants
    t = np.arange(N) * sc.ts
    tail = du[-10:]                                          # lim sup over the last trials
    for lam in (lc.lambda_opt, 1.01 * lc.lambda_min, 2 * lc.lambda_min, 10 * lc.lambda_min):
        lam_norm = np.max(np.exp(-lam * t)[None] * np.linalg.norm(tail, axis=2), axis=1)
        assert np.all(lam_norm <= lc.bound(lam)), (lam, lam_norm.max(), lc.bound(lam))


@pytest.mark.parametrize("kw, exc, match", [
    ({"N": 0}, ValueError, r"N \(samples per trial\) must be an integer >= 1"),
    ({"ts": 0.0}, ValueError, r"ts \(sample time\) must be positive"),
    ({"ts": float("nan")}, ValueError, r"ts \(sample time\) must be finite"),
    ({"gains": PDGains.zeros(2, 2)}, ValueError, r"Phi1 must have shape \(1, 2\)"),
    ({"delta_u0": np.full((10, 1), np.inf)}, ValueError, "delta_u0 must be finite"),
    ({"forgetting": 0.1}, ValueError, "forgetting must be a FixedForgetting"),
    ({"k_f": -1.0}, ValueError, "k_f must be non-negative"),
])
def test_analyse_bad_input(kw, exc, match):
    args = {"gains": PDGains.zeros(1, 2), "forgetting": FixedForgetting(0.1), "ts": 0.01,
            "N": 10}
    args.update(kw)
    with pytest.raises(exc, match=match):
        analyse(planar_robot(), args.pop("gains"), args.pop("forgetting"), **args)
