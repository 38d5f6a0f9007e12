"""Bad input to the learning laws: each a ParameterError / ShapeError naming the parameter."""

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    LiftedLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
    VariableForgetting,
)
from ilc_analysis.laws._base import plant_response
from ilc_analysis.laws._gradient import gradient_step_bound
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant, Plant, discretize

TS = 0.1
PLANT = DiscretePlant.from_statespace(control.ss([[0.8, 0.1], [0.0, 0.5]], [[0.0], [1.0]],
                                                 [[1.0, 0.0]], 0, TS))
LS = lift(PLANT, 10)
#: zero at z = 2: non-minimum phase
NMP = DiscretePlant.from_statespace(control.ss(control.tf([1.0, -2.0], [1.0, -0.5, 0.06], TS)))


@pytest.mark.parametrize("beta", [0.0, -1.0, float("nan"), float("inf"), True, "0.1"])
def test_gradient_and_time_reversal_reject_a_bad_step_size(beta):
    with pytest.raises(ParameterError, match="beta"):
        GradientLaw(beta, LS)
    with pytest.raises(ParameterError, match="beta"):
        TimeReversalLaw(beta)


@pytest.mark.parametrize("gamma", [0.0, -0.5, float("nan"), False])
def test_inverse_model_rejects_a_bad_gain(gamma):
    with pytest.raises(ParameterError, match="gamma"):
        QLLaw.inverse_model(PLANT, gamma)


def test_inverse_model_needs_a_square_minimum_phase_model():
    with pytest.raises(ParameterError, match="not minimum-phase.*2\\.0"):
        QLLaw.inverse_model(NMP, 1.0)
    wide = DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0, 1.0]], [[1.0]], 0, TS))
    with pytest.raises(ShapeError, match="square plant"):
        QLLaw.inverse_model(wide, 1.0)
    with pytest.raises(ParameterError, match="discrete-time"):
        QLLaw.inverse_model(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 1.0)


@pytest.mark.parametrize(("kw", "match"), [
    ({"weight_input_change": 0.0}, "weight_input_change \\(R\\) must be positive definite"),
    ({"weight_input_change": [0.1, -0.1] * 5}, "weight_input_change"),
    ({"weight_input_change": 0.1, "weight_error": -1.0}, "weight_error \\(Q\\) must be positive "
                                                         "semi-definite"),
    ({"weight_input_change": 0.1, "weight_input": -0.1}, "weight_input \\(S\\)"),
    ({"weight_input_change": np.diag(np.r_[np.ones(9), -1.0])}, "smallest eigenvalue"),
    ({"weight_input_change": np.triu(np.ones((10, 10)))}, "must be symmetric"),
    ({"weight_input_change": float("nan")}, "weight_input_change.*finite"),
    ({"weight_input_change": True}, "weight_input_change"),
])
def test_norm_optimal_rejects_weights_that_are_not_positive_definite(kw, match):
    with pytest.raises(ParameterError, match=match):
        NormOptimalLaw(LS, **kw)


@pytest.mark.parametrize(("kw", "match"), [
    ({"weight_input_change": [0.1, 0.2]},
     "weight_input_change \\(R\\) must be a scalar, shape \\(1,\\)"),
    ({"weight_input_change": np.eye(3)}, "weight_input_change.*found shape \\(3, 3\\)"),
])
def test_norm_optimal_rejects_weights_of_the_wrong_shape(kw, match):
    with pytest.raises(ShapeError, match=match):
        NormOptimalLaw(LS, **kw)


def test_norm_optimal_rho_lambda_range():
    with pytest.raises(ParameterError, match="rho"):
        NormOptimalLaw.rho_lambda(LS, -0.1, 1.0)
    with pytest.raises(ParameterError, match="lam"):
        NormOptimalLaw.rho_lambda(LS, 0.1, 0.0)
    with pytest.raises(ParameterError, match="model must be a LiftedSystem"):
        NormOptimalLaw(LS.G, weight_input_change=1.0)


def test_filters_at_another_sample_time_are_rejected():
    L_slow = control.tf([0.5], [1.0, -0.2], 0.2)
    with pytest.raises(ParameterError, match="L has sample time 0.2 s; the trial has ts = 0.1"):
        QLLaw(L_slow).lifted(LS)
    with pytest.raises(ParameterError, match="L has sample time"):
        QLLaw(L_slow).update(np.zeros((10, 1)), np.zeros((10, 1)), TS)
    with pytest.raises(ParameterError, match="L and Q must have the same sample time"):
        QLLaw(control.tf([0.5], [1.0], TS), control.tf([0.5], [1.0, -0.5], 0.2))
    with pytest.raises(ParameterError, match="L must be a discrete-time"):
        QLLaw(control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(ParameterError, match="L must be proper.*advance"):
        QLLaw(control.tf([1.0, 0.0, 0.0], [1.0, 0.5], TS))
    with pytest.raises(ParameterError, match="the law's model has sample time 0.1 s"):
        GradientLaw(0.1, LS).update(np.zeros((10, 1)), np.zeros((10, 1)), 0.05)


def test_ql_law_rejects_bad_structure():
    with pytest.raises(ShapeError, match="L must map 1 channel\\(s\\) to 1"):
        QLLaw(np.ones((2, 1))).lifted(LS)
    with pytest.raises(ShapeError, match="Q must be square"):
        QLLaw(1.0, np.ones((1, 2)))
    for advance in (-1, 1.5, True):
        with pytest.raises(ParameterError, match="advance"):
            QLLaw(1.0, advance=advance)
    with pytest.raises(ParameterError, match="advance = 10 samples is not shorter"):
        QLLaw(1.0, advance=10).lifted(LS)
    with pytest.raises(ParameterError, match="zero_phase=True needs an LTI Q"):
        QLLaw(1.0, zero_phase=True)
    with pytest.raises(ParameterError, match="zero_phase must be True or False"):
        QLLaw(1.0, 1.0, zero_phase=1)
    with pytest.raises(ParameterError, match="L must be a discrete python-control system"):
        QLLaw(None)


def test_updates_reject_wrong_shapes():
    u, e = np.zeros((10, 1)), np.zeros((10, 1))
    laws = [PDLaw(PDGains.zeros(1, 1)), QLLaw(1.0), GradientLaw(0.1, LS),
            NormOptimalLaw(LS, weight_input_change=1.0)]
    for law in laws:
        with pytest.raises(ShapeError, match="e_i"):
            law.update(u, np.zeros((9, 1)), TS)
        with pytest.raises(ShapeError, match="u_i"):
            law.update(np.zeros(10), e, TS)
        with pytest.raises(ParameterError, match="u_i.*finite"):
            law.update(np.full((10, 1), np.nan), e, TS)
    for law in laws[:1] + laws[2:]:
        with pytest.raises(ShapeError, match="u_i"):
            law.update(np.zeros((10, 2)), e, TS)
    with pytest.raises(ShapeError, match="u_i must have shape \\(10, 1\\) \\(the model's trial"):
        GradientLaw(0.1, LS).update(np.zeros((8, 1)), np.zeros((8, 1)), TS)


def test_model_based_laws_reject_another_trial():
    other = lift(PLANT, 12)
    for law in (GradientLaw(0.1, LS), NormOptimalLaw(LS, weight_input_change=1.0)):
        with pytest.raises(ShapeError, match="\\(N, n_u, n_y, shift\\) = \\(10, 1, 1, 2\\)"):
            law.lifted(other)
    with pytest.raises(ParameterError, match="lifted_system must be a LiftedSystem"):
        GradientLaw(0.1, LS).lifted(LS.G)
    with pytest.raises(ParameterError, match="model must be a LiftedSystem or a DiscretePlant"):
        GradientLaw(0.1, LS.G)
    with pytest.raises(ParameterError, match="G is zero"):
        gradient_step_bound(np.zeros((3, 3)))


def test_time_reversal_rejects_bad_experiments():
    with pytest.raises(ParameterError, match="free_response must be None"):
        TimeReversalLaw(0.1, free_response="measured")
    with pytest.raises(ParameterError, match="free_response.*finite"):
        TimeReversalLaw(0.1, free_response=np.full((10, 1), np.inf))
    law = TimeReversalLaw(0.1)
    u, e = np.zeros((10, 1)), np.ones((10, 1))
    with pytest.raises(ParameterError, match="exactly one of experiment"):
        law.update(u, e, TS)
    with pytest.raises(ShapeError, match="extra_outputs must hold 1 outputs"):
        law.update(u, e, TS, extra_outputs=[])
    with pytest.raises(ShapeError, match="extra output 0 must have shape \\(10, 1\\)"):
        law.update(u, e, TS, experiment=lambda v: np.zeros((9, 1)))
    with pytest.raises(ShapeError, match="free_response must have shape \\(10, 1\\)"):
        TimeReversalLaw(0.1, free_response=np.zeros((9, 1))).lifted(LS)


def test_lifted_law_rejects_bad_parts_and_forgetting():
    q, p = 10, 10
    with pytest.raises(ParameterError, match="L1 must be finite"):
        LiftedLaw(np.full((q, p), np.nan))
    with pytest.raises(ShapeError, match="L2 must have shape \\(10, 10\\)"):
        LiftedLaw(np.zeros((q, p)), np.zeros((q, p + 1)))
    with pytest.raises(ShapeError, match="Q \\(lifted Q-filter\\) must have shape"):
        LiftedLaw(np.zeros((q, p)), None, np.zeros((q, p + 1)))
    for a in (1.0, -0.1, float("nan"), True, (0.5, 0.1)):
        with pytest.raises(ParameterError, match="a \\(forgetting"):
            LiftedLaw(np.zeros((q, p)), a=a)
    ll = PDLaw(PDGains.zeros(1, 1), VariableForgetting(0.5, 1.0)).lifted(LS)
    with pytest.raises(ParameterError, match="variable forgetting factor in \\[0, 0.5\\]"):
        ll.operator(LS)
    with pytest.raises(ParameterError, match="within this law's forgetting range"):
        ll.operator(LS, a=0.7)
    with pytest.raises(ShapeError, match="G must have shape \\(10, 10\\)"):
        PDLaw(PDGains.zeros(1, 1)).lifted(LS).operator(np.zeros((10, 11)))
    with pytest.raises(ParameterError, match="L2 is not causal"):
        LiftedLaw(np.zeros((q, p)), np.eye(q)).operator(LS)


def test_frequency_response_only_where_defined():
    omega = np.linspace(0.1, 1.0, 3)
    tv = PDGains(*(np.zeros((10, 1, 1)) for _ in range(4)))
    with pytest.raises(ParameterError, match="time-invariant gains"):
        PDLaw(tv).frequency_response(PLANT, omega)
    with pytest.raises(ParameterError, match="not the law's model"):
        GradientLaw(0.1, LS).frequency_response(NMP, omega)
    with pytest.raises(ParameterError, match="time-invariant diagonal weights"):
        NormOptimalLaw(LS, weight_input_change=np.eye(10)).frequency_response(PLANT, omega)
    with pytest.raises(ParameterError, match="omega must be non-empty with values in"):
        QLLaw(1.0).frequency_response(PLANT, [100.0])
    x = ca.SX.sym("x", 1)
    u = ca.SX.sym("u", 1)
    nonlinear = discretize(Plant.from_ode(states=x, inputs=u, rhs=-ca.sin(x) + u, outputs=x),
                           TS, method="rk4")
    with pytest.raises(ParameterError, match="nonlinear"):
        plant_response(nonlinear, omega)


def test_pd_law_rejects_bad_parts():
    with pytest.raises(ParameterError, match="gains must be a PDGains"):
        PDLaw(np.zeros((1, 1)))
    with pytest.raises(ParameterError, match="forgetting must be"):
        PDLaw(PDGains.zeros(1, 1), 0.1)
    with pytest.raises(ParameterError, match="q_filter must be a QFilter"):
        PDLaw(PDGains.zeros(1, 1), FixedForgetting(0.0), q_filter=0.5)
    with pytest.raises(ShapeError, match="u0"):
        PDLaw(PDGains.zeros(1, 1), u0=np.zeros((3, 3, 3)))
    with pytest.raises(ShapeError, match="Phi1 must have shape \\(2, 1\\)"):
        PDLaw(PDGains.zeros(1, 1)).lifted(lift(DiscretePlant.from_statespace(
            control.ss([[0.5]], [[1.0, 1.0]], [[1.0]], 0, TS)), 5))
