"""synthesize(problem, ...): one verb over an ILCProblem, a ready law, a typed certificate."""

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ILCDeprecationWarning, ParameterError
from ilc_analysis.laws import FixedForgetting, PDLaw, VariableForgetting
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.problem import ILCProblem
from ilc_analysis.synthesis import Certificate, SynthesisResult, synthesize

N, TS = 24, 0.1
FIRST_ORDER = control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]])


def _problem(plant=FIRST_ORDER, n=N):
    return ILCProblem(plant, TS, n, np.zeros((n, 1)), name="first order")


def _G(problem):
    """The lifted G of the ZOH-sampled first-order plant, from its Markov parameters
    (numpy, independent of the package's lifting): y_{k+1} = sum_j C Ad^(k-j) Bd u_j."""
    ad = np.exp(-TS)
    bd = 1.0 - ad
    n = problem.N
    return np.array([[bd * ad ** (i - j) if i >= j else 0.0 for j in range(n)]
                     for i in range(n)])


def _norm_T(problem, gains, a, Q=None):
    r""":math:`\|Q((1-a)I - L_1G)\|_2` of a time-invariant SISO open-loop PD without lead:
    :math:`(L_1)_{kk} = \Psi_1 + \Phi_1/T_s`, :math:`(L_1)_{k,k-1} = -\Phi_1/T_s`."""
    psi, phi = float(gains.Psi1[0, 0]), float(gains.Phi1[0, 0])
    n = problem.N
    L1 = (psi + phi / TS) * np.eye(n) - phi / TS * np.eye(n, k=-1)
    T = (1 - a) * np.eye(n) - L1 @ _G(problem)
    return np.linalg.norm(T if Q is None else Q @ T, 2)


def test_lifted_synthesis_returns_a_law_ready_for_analysis():
    problem = _problem()
    q = QFilter.dct(2.0)
    res = synthesize(problem, method="lifted", target=0.95, forgetting=0.05, q_filter=q,
                     bounds={"Psi1": 5.0, "Phi1": 5.0})
    assert isinstance(res, SynthesisResult) and res.holds
    assert isinstance(res.law, PDLaw)
    assert res.law.gains is res.gains and res.law.q_filter is q
    assert res.law.forgetting == FixedForgetting(0.05)
    assert isinstance(res.certificate, Certificate)
    Q = q.lifted_matrix(N, 1, TS)
    assert res.certificate.value == pytest.approx(_norm_T(problem, res.gains, 0.05, Q),
                                                  rel=1e-6)
    assert res.certificate.value < 0.95 and res.certificate.verdict == "holds"


def test_robust_set_certifies_the_worst_plant():
    slow = _problem()
    fast = _problem(control.ss([[-2.0]], [[2.0]], [[1.0]], [[0.0]]))
    res = synthesize(slow, plants=[fast], forgetting=0.1, target=1.0)
    assert res.certificate.plants == 2
    assert res.certificate.value == pytest.approx(max(res.certificate.norm_2_per_plant))
    assert res.certificate.norm_2_per_plant[0] == pytest.approx(
        _norm_T(slow, res.gains, 0.1), rel=1e-6)


def test_paper_and_frequency_methods_run_on_the_problem():
    problem = _problem()
    paper = synthesize(problem, method="paper", forgetting=VariableForgetting(0.8, 1.0),
                       bounds={"Phi1": 1.0, "Phi2": 1.0})
    assert paper.certificate.quantity == "tight_contraction" and paper.holds
    assert paper.law.forgetting == VariableForgetting(0.8, 1.0)
    freq = synthesize(problem, method="frequency", forgetting=0.1,
                      bounds={"Psi1": 1.0, "Phi1": 1e-9})
    assert freq.certificate.lifted_check_length == N and freq.holds
    assert freq.certificate.lifted_norm_2 == pytest.approx(_norm_T(problem, freq.gains, 0.1),
                                                           rel=1e-6)


def test_as_dict_is_plain_data_and_to_dict_its_old_name():
    res = synthesize(_problem(), forgetting=0.1)
    with pytest.warns(ILCDeprecationWarning, match="as_dict"):
        assert res.to_dict() == res.as_dict()
    assert res.as_dict()["certificate"] == res.certificate.as_dict()
    assert isinstance(res.summary(), str) and "lifted synthesis" in res.summary()


def test_certificate_round_trips_exactly_what_is_stored():
    res = synthesize(_problem(), forgetting=VariableForgetting(0.9, 1.0))
    data = res.certificate.as_dict()
    again = Certificate.from_dict(data)
    assert again == res.certificate
    assert list(again.as_dict()) == list(data) and again.as_dict() == data
    assert data["forgetting_box_upper"] == again.forgetting_box_upper


_KEYS = Certificate.keys_known()


@settings(max_examples=50, deadline=None)
@given(st.lists(st.sampled_from(_KEYS), unique=True),
       st.one_of(st.none(), st.floats(allow_nan=False), st.text(max_size=5)))
def test_certificate_round_trip_keeps_keys_order_and_none(keys, value):
    data = {k: value for k in keys}
    cert = Certificate.from_dict(data)
    assert cert.as_dict() == data and list(cert.as_dict()) == keys


def test_unknown_certificate_key_is_named():
    with pytest.raises(ParameterError, match="unknown key 'norm_3'"):
        Certificate.from_dict({"quantity": "norm_2", "norm_3": 1.0})
    with pytest.raises(ParameterError, match="mapping"):
        Certificate.from_dict([("quantity", "norm_2")])


def test_bad_requests_are_refused_by_name():
    problem = _problem()
    with pytest.raises(ParameterError, match="problem must be an ILCProblem"):
        synthesize(problem.lifted)
    with pytest.raises(ParameterError, match="method must be one of"):
        synthesize(problem, method="lmi")
    with pytest.raises(ParameterError, match="time-varying.*needs method 'lifted'"):
        synthesize(problem, method="frequency", structure="time-varying")
    with pytest.raises(ParameterError, match="no q_filter and no lead"):
        synthesize(problem, method="paper", lead=1)
    with pytest.raises(ParameterError, match="solver applies to 'paper' and 'frequency'"):
        synthesize(problem, solver="CLARABEL")
    with pytest.raises(ParameterError, match=r"plants\[0\].*LiftedSystem"):
        synthesize(problem, plants=[FIRST_ORDER])
    with pytest.raises(ParameterError, match=r"plants\[0\]: .*same trial"):
        synthesize(problem, plants=[_problem(n=N + 1)])


def test_robot_parameter_box_lives_with_the_paper():
    """The robot's parameter box is the paper's; synthesis is generic (the old names resolve
    with a warning: tests/legacy/test_renamed_names.py)."""
    import ilc_analysis.paper as paper
    import ilc_analysis.synthesis as synthesis
    from ilc_analysis.paper import _robust_robot as robust_robot

    assert paper.parameter_vertices is robust_robot.parameter_vertices
    assert paper.robot_liftings is robust_robot.robot_liftings
    assert not {"parameter_vertices", "robot_liftings"} & set(synthesis.__all__)
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        _ = synthesis.nothing


def test_scenario_gains_give_their_law_with_their_own_filter():
    from ilc_analysis.paper._synthesis_step import ScenarioGains

    res = synthesize(_problem(), forgetting=0.1, q_filter=QFilter.dct(2.0))
    g = ScenarioGains(gains=res.gains, q_filter=res.law.q_filter, result=res, sigma_min_G=0.0)
    law = g.law(u0=np.zeros(1))
    assert law.q_filter is res.law.q_filter and law.forgetting == FixedForgetting(0.1)
    assert g.law(VariableForgetting(0.9, 1.0)).forgetting == VariableForgetting(0.9, 1.0)
    assert g.certificate == res.certificate.as_dict()
