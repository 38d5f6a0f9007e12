"""Every parameter of every public callable is documented (issue 17), as python-control's
docstring test does.

The public callables are those of the API reference (``docs/api_listing.py``: each public
module's ``__all__``, their classes' constructors and public methods). A parameter is documented
when its docstring (numpydoc) names it in ``Parameters`` or ``Other Parameters``; a class's
constructor parameter also when the class documents it as an attribute (``Attributes`` or an
attribute docstring, as the fields of a dataclass are), which is where autodoc shows it.

:data:`KNOWN_UNDOCUMENTED` lists what was undocumented when this test was written. It may only
shrink: a listed parameter that becomes documented fails the test until its entry is removed,
and a parameter missing from a callable not listed fails it at once.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
import warnings
from functools import cache
from pathlib import Path

import pytest
from numpydoc.docscrape import NumpyDocString
from sphinx.pycode import ModuleAnalyzer

ROOT = Path(__file__).resolve().parents[1]


def _api_listing():
    spec = importlib.util.spec_from_file_location("api_listing", ROOT / "docs" / "api_listing.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("api_listing", module)
    spec.loader.exec_module(module)
    return module


api_listing = _api_listing()
CALLABLES = list(api_listing.public_callables())


def _parameters(func) -> list[str]:
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):  # a builtin without a signature: nothing to document
        return []
    return [p.name for p in signature.parameters.values()
            if p.name not in ("self", "cls")
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _documented(docstring: str | None, sections=("Parameters", "Other Parameters")) -> set[str]:
    with warnings.catch_warnings():  # numpydoc warns about unknown sections: not our concern
        warnings.simplefilter("ignore")
        doc = NumpyDocString(inspect.cleandoc(docstring or ""))
    names = set()
    for section in sections:
        for entry in doc[section]:
            names |= {n.strip().lstrip("*") for n in entry.name.split(",")}
    return names


@cache
def _attribute_docs(modname: str) -> dict[tuple[str, str], list[str]]:
    return ModuleAnalyzer.for_module(modname).find_attr_docs()


def _class_attributes(cls) -> set[str]:
    names = _documented(cls.__doc__, ("Attributes",))
    for klass in cls.__mro__:
        if klass.__module__.startswith("ilc_analysis"):
            names |= {attr for (qual, attr) in _attribute_docs(klass.__module__)
                      if qual == klass.__qualname__}
    return names


def undocumented(obj) -> list[str]:
    """The parameters of ``obj`` (a function, method or class) its documentation leaves out."""
    params = _parameters(obj)
    if not params:
        return []
    documented = _documented(inspect.getdoc(obj))
    if inspect.isclass(obj):
        documented |= _class_attributes(obj)
    return [p for p in params if p not in documented]


def test_the_reference_lists_the_public_api():
    names = [name for name, _, _ in CALLABLES]
    for expected in ("ilc_analysis.model.Plant", "ilc_analysis.conditions.analyse",
                     "ilc_analysis.laws.PDLaw", "ilc_analysis.problem.ILCProblem",
                     "ilc_analysis.model.Plant.from_ode"):
        assert expected in names
    assert len(names) == len(set(names)), "a callable is listed twice"


def test_undocumented_is_detected():
    """The check itself: a parameter missing from Parameters is found, a listed one is not."""

    def f(a, b, *args, c=1, **kwargs):
        """Summary.

        Parameters
        ----------
        a, c : int
            Documented.
        """

    assert undocumented(f) == ["b"]


@pytest.mark.parametrize("name, obj", [(n, o) for n, o, _ in CALLABLES],
                         ids=[n for n, _, _ in CALLABLES])
def test_every_parameter_is_documented(name, obj):
    missing = undocumented(obj)
    known = KNOWN_UNDOCUMENTED.get(name, ())
    new = [p for p in missing if p not in known]
    assert not new, f"{name}: parameters not in its numpydoc Parameters section: {new}"
    fixed = [p for p in known if p not in missing]
    assert not fixed, (f"{name}: {fixed} are documented now: remove them from "
                       f"KNOWN_UNDOCUMENTED in tests/test_docstrings.py")


def test_known_undocumented_names_exist():
    names = {n for n, _, _ in CALLABLES}
    stale = sorted(set(KNOWN_UNDOCUMENTED) - names)
    assert not stale, f"KNOWN_UNDOCUMENTED lists callables that are not public: {stale}"


#: Parameters left undocumented when this test was written (issue 17), to be documented. Most
#: are in modules that other engineers were rewriting at the time (laws, simulation, studies,
#: synthesis, scenarios), whose docstrings could not be edited then; the rest is the backlog of
#: the other modules. The test fails when an entry is documented, so this list only shrinks.
KNOWN_UNDOCUMENTED: dict[str, tuple[str, ...]] = {
    'ilc_analysis.model.Plant': ('states', 'inputs', 'rhs', 'outputs', 'time'),
    'ilc_analysis.model.DiscretePlant': ('names', 'name'),
    'ilc_analysis.model.RobotParameters': (
        'M', 'm', 'l', 'I', 'g', 'b', 'r', 'track', 'J', 'b_yaw'
    ),
    'ilc_analysis.model.ModelReport': (
        'plant_name', 'state_names', 'input_names', 'output_names', 'x0', 'u0', 'A', 'B', 'C', 'D',
        'eigenvalues', 'relative_degree', 'markov', 'params', 'is_equilibrium', 'notes'
    ),
    'ilc_analysis.lifting.adjoint_product': (
        'dplant', 'N', 'v', 'x0', 'u_nominal', 'w', 't0', 'shift'
    ),
    'ilc_analysis.lifting.jacobian_product': (
        'dplant', 'N', 'du', 'x0', 'u_nominal', 'w', 't0', 'shift'
    ),
    'ilc_analysis.laws.LearningLaw.check': ('lifted_system',),
    'ilc_analysis.laws.LearningLaw.experiments_per_iteration': ('n_u', 'n_y'),
    'ilc_analysis.laws.LearningLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.LearningLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.LearningLaw.operator': ('lifted_system', 'a'),
    'ilc_analysis.laws.LearningLaw.update': ('u_i', 'e_i', 'ts'),
    'ilc_analysis.laws.LiftedLaw.next_input': ('G', 'u_i', 'r', 'u0', 'a'),
    'ilc_analysis.laws.LawResponse.operator': ('P', 'a'),
    'ilc_analysis.laws.plant_response': ('plant', 'omega'),
    'ilc_analysis.laws.PDLaw.check': ('lifted_system',),
    'ilc_analysis.laws.PDLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.PDLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.PDLaw.simulation_law': ('n_u',),
    'ilc_analysis.laws.PDLaw.update': ('u_i', 'e_i', 'ts'),
    'ilc_analysis.laws.QLLaw.check': ('lifted_system',),
    'ilc_analysis.laws.QLLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.QLLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.QLLaw.update': ('u_i', 'e_i', 'ts'),
    'ilc_analysis.laws.LTIFilter': ('A', 'B', 'C', 'D'),
    'ilc_analysis.laws.LTIFilter.apply': ('v', 'advance'),
    'ilc_analysis.laws.LTIFilter.check': ('name', 'n_out', 'n_in', 'ts'),
    'ilc_analysis.laws.LTIFilter.from_user': ('value', 'name'),
    'ilc_analysis.laws.LTIFilter.markov': ('count',),
    'ilc_analysis.laws.LTIFilter.response': ('z',),
    'ilc_analysis.laws.LTIFilter.toeplitz': ('N', 'advance'),
    'ilc_analysis.laws.GradientLaw': ('x0', 'w', 't0', 'shift'),
    'ilc_analysis.laws.GradientLaw.check': ('lifted_system',),
    'ilc_analysis.laws.GradientLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.GradientLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.GradientLaw.step_bound': ('lifted_system',),
    'ilc_analysis.laws.GradientLaw.update': ('u_i', 'e_i', 'ts'),
    'ilc_analysis.laws.TimeReversalLaw.check': ('lifted_system',),
    'ilc_analysis.laws.TimeReversalLaw.experiments_per_iteration': ('n_u', 'n_y'),
    'ilc_analysis.laws.TimeReversalLaw.extra_inputs': ('e_i', 'n_u'),
    'ilc_analysis.laws.TimeReversalLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.TimeReversalLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.TimeReversalLaw.update': ('u_i', 'e_i', 'ts', 'experiment', 'extra_outputs'),
    'ilc_analysis.laws.NormOptimalLaw.check': ('lifted_system',),
    'ilc_analysis.laws.NormOptimalLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.NormOptimalLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.NormOptimalLaw.rho_lambda': ('model', 'rho', 'lam'),
    'ilc_analysis.laws.NormOptimalLaw.update': ('u_i', 'e_i', 'ts'),
    'ilc_analysis.laws.gradient_step_bound': ('G',),
    'ilc_analysis.laws.adjoint_blocks': ('G', 'n_u', 'n_y'),
    'ilc_analysis.laws.InverseModelLaw.check': ('lifted_system',),
    'ilc_analysis.laws.InverseModelLaw.frequency_response': ('plant', 'omega', 'shift'),
    'ilc_analysis.laws.InverseModelLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.InverseModelLaw.update': ('u_i', 'e_i', 'ts'),
    'ilc_analysis.laws.describe_law': ('law',),
    'ilc_analysis.laws.ConstrainedNormOptimalLaw.check': ('lifted_system',),
    'ilc_analysis.laws.ConstrainedNormOptimalLaw.for_problem': (
        'problem', 'weight_error', 'weight_input_change'
    ),
    'ilc_analysis.laws.ConstrainedNormOptimalLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.ConstrainedNormOptimalLaw.solve': ('u_i', 'e_i', 'states'),
    'ilc_analysis.laws.ConstrainedNormOptimalLaw.update': ('u_i', 'e_i', 'ts', 'states'),
    'ilc_analysis.laws.TrialCertificate': ('predicted_violation', 'measured_violation'),
    'ilc_analysis.laws.InfeasibleTrialError': ('message', 'certificate'),
    'ilc_analysis.laws.NonlinearNormOptimalLaw.check': ('lifted_system',),
    'ilc_analysis.laws.NonlinearNormOptimalLaw.lifted': ('lifted_system',),
    'ilc_analysis.laws.NonlinearNormOptimalLaw.linearised': ('lifted_system',),
    'ilc_analysis.laws.NonlinearNormOptimalLaw.solve': ('u_i', 'e_i', 'states'),
    'ilc_analysis.laws.NonlinearNormOptimalLaw.update': ('u_i', 'e_i', 'ts', 'states'),
    'ilc_analysis.laws.GaussNewtonCertificate': ('predicted_violation', 'measured_violation'),
    'ilc_analysis.conditions.LambdaCondition': (
        'gamma1', 'gamma2', 'xi1', 'xi2', 'mu0', 'b_B', 'T', 'k_f', 'b_omega', 'holds'
    ),
    'ilc_analysis.conditions.BlockToeplitzOperator.compose': ('other',),
    'ilc_analysis.conditions.BlockToeplitzOperator.matvec': ('x',),
    'ilc_analysis.conditions.BlockToeplitzOperator.norm_2': ('v0',),
    'ilc_analysis.conditions.BlockToeplitzOperator.norm_2_estimate': ('v0', 'prefer_dense'),
    'ilc_analysis.conditions.BlockToeplitzOperator.power': ('k',),
    'ilc_analysis.conditions.BlockToeplitzOperator.rmatvec': ('y',),
    'ilc_analysis.conditions.TriangularLearningOperator': ('G', 'L1', 'L2', 'A', 'n_u', 'n_y'),
    'ilc_analysis.conditions.TriangularLearningOperator.matvec': ('x',),
    'ilc_analysis.conditions.TriangularLearningOperator.norm_2': ('v0',),
    'ilc_analysis.conditions.TriangularLearningOperator.norm_2_estimate': ('v0', 'prefer_dense'),
    'ilc_analysis.conditions.TriangularLearningOperator.rmatvec': ('y',),
    'ilc_analysis.conditions.structured_learning_operator': ('n_u', 'n_y'),
    'ilc_analysis.conditions.FrequencyCondition': ('ts', 'a'),
    'ilc_analysis.conditions.RelativeDegreeInfo': ('output_names', 'ts'),
    'ilc_analysis.conditions.TheoremResult': (
        'H', 'gamma1', 'gamma2', 'xi1', 'xi2', 'mu0', 'k_f', 'k_f_source', 'couplings', 'condition'
    ),
    'ilc_analysis.conditions.evaluate_theorem': ('output_names',),
    'ilc_analysis.conditions.AnalysisReport': (
        'plant_name', 'conditions', 'relative_degree', 'floor', 'frequency', 'settings', 'notes'
    ),
    'ilc_analysis.conditions.LawAnalysis': (
        'problem_name', 'law_name', 'conditions', 'settings', 'notes'
    ),
    'ilc_analysis.synthesis.SynthesisResult.save': ('path',),
    'ilc_analysis.synthesis.coupling_matrices': ('plant',),
    'ilc_analysis.synthesis.pd_loop_spectral_radius': ('dsys', 'Psi2', 'Phi2'),
    'ilc_analysis.synthesis.parameter_vertices': ('nominal', 'spread', 'names', 'include_nominal'),
    'ilc_analysis.synthesis.parameter_samples': ('nominal', 'spread', 'names', 'count', 'seed'),
    'ilc_analysis.synthesis.PDStructure.gains': ('theta',),
    'ilc_analysis.synthesis.PDStructure.operator': ('theta',),
    'ilc_analysis.synthesis.PDStructure.parameters': ('Psi1', 'Phi1'),
    'ilc_analysis.synthesis.pd_structure': (
        'N', 'n_u', 'n_y', 'ts', 'lead', 'time_varying', 'knot_spacing'
    ),
    'ilc_analysis.synthesis.hat_basis': ('N', 'knot_spacing'),
    'ilc_analysis.simulation.simulate': ('system', 'law'),
    'ilc_analysis.simulation.ProblemLaw': ('problem',),
    'ilc_analysis.simulation.ProblemLaw.check_dimensions': ('N', 'n_u', 'n_y', 'ts', 'shift'),
    'ilc_analysis.simulation.ProblemLaw.feedback_gains': ('N', 'n_u', 'n_y'),
    'ilc_analysis.simulation.ProblemLaw.initial_feedforward': ('N', 'n_u'),
    'ilc_analysis.simulation.ProblemLaw.next_feedforward': ('u', 'e', 'ts', 'experiment', 'states'),
    'ilc_analysis.simulation.problem_law': ('law', 'problem'),
    'ilc_analysis.simulation.SimulatedMachine.from_problem': (
        'problem', 'law', 'disturbances', 'entropy', 'jit'
    ),
    'ilc_analysis.simulation.SimulatedMachine.output_window': ('rec',),
    'ilc_analysis.simulation.known_disturbance': ('w', 'N', 'shift', 'n_x'),
    'ilc_analysis.simulation.Learner.load_state': ('path', 'problem', 'law', 'option'),
    'ilc_analysis.simulation.Learner.save_state': ('path', 'option'),
    'ilc_analysis.simulation.design_fingerprint': ('problem', 'law'),
    'ilc_analysis.simulation.simulate_reference': (
        'plant', 'law', 'y_d', 'iterations', 'x0', 'ts', 'shift', 't0', 'disturbances', 'rtol',
        'atol', 'method'
    ),
    'ilc_analysis.simulation.ILCLaw.check_dimensions': ('N', 'n_u', 'n_y', 'ts', 'shift'),
    'ilc_analysis.simulation.ILCLaw.feedback_gains': ('N', 'n_u', 'n_y'),
    'ilc_analysis.simulation.ILCLaw.initial_feedforward': ('N', 'n_u'),
    'ilc_analysis.simulation.ILCLaw.next_feedforward': ('u', 'e', 'ts'),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.check_dimensions': (
        'N', 'n_u', 'n_y', 'ts', 'shift'
    ),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.closed_loop': (
        'Phi2', 'Psi2', 'u0', 'forgetting', 'q_filter'
    ),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.d_type': (
        'Phi1', 'u0', 'forgetting', 'lead', 'q_filter'
    ),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.feedback_gains': ('N', 'n_u', 'n_y'),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.initial_feedforward': ('N', 'n_u'),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.next_feedforward': ('u', 'e', 'ts'),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.open_loop': (
        'Phi1', 'Psi1', 'u0', 'forgetting', 'lead', 'q_filter'
    ),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.p_type': (
        'Psi1', 'u0', 'forgetting', 'lead', 'q_filter'
    ),
    'ilc_analysis.simulation.OpenClosedLoopPDLaw.pd_type': (
        'Phi1', 'Psi1', 'u0', 'forgetting', 'lead', 'q_filter'
    ),
    'ilc_analysis.simulation.NormOptimalLaw.check_dimensions': ('N', 'n_u', 'n_y', 'ts', 'shift'),
    'ilc_analysis.simulation.NormOptimalLaw.error_floor_gain': ('ts',),
    'ilc_analysis.simulation.NormOptimalLaw.feedback_gains': ('N', 'n_u', 'n_y'),
    'ilc_analysis.simulation.NormOptimalLaw.initial_feedforward': ('N', 'n_u'),
    'ilc_analysis.simulation.NormOptimalLaw.next_feedforward': ('u', 'e', 'ts'),
    'ilc_analysis.simulation.QFilter.apply': ('u', 'ts'),
    'ilc_analysis.simulation.QFilter.butterworth': ('cutoff', 'order'),
    'ilc_analysis.simulation.QFilter.dct': ('cutoff', 'order'),
    'ilc_analysis.simulation.QFilter.fir': ('cutoff', 'taps'),
    'ilc_analysis.simulation.QFilter.lifted_matrix': ('N', 'n_u', 'ts'),
    'ilc_analysis.simulation.QFilter.lifted_norm': ('N', 'ts'),
    'ilc_analysis.simulation.QFilter.magnitude': ('f', 'ts'),
    'ilc_analysis.simulation.QFilter.matrix': ('N', 'ts'),
    'ilc_analysis.simulation.Disturbances.check_dimensions': ('n_x', 'n_y'),
    'ilc_analysis.simulation.Disturbances.paper': ('seed',),
    'ilc_analysis.simulation.Disturbances.realise': (
        'iteration', 't', 'n_x', 'n_y', 'entropy', 'experiment'
    ),
    'ilc_analysis.simulation.DivergenceBounds.fall_angle': ('angle', 'state', 'max_abs_state'),
    'ilc_analysis.simulation.DivergenceBounds.limits': ('state_names',),
    'ilc_analysis.simulation.ILCResult.iterations_to': ('tolerance',),
    'ilc_analysis.simulation.ILCResult.plot': ('ax',),
    'ilc_analysis.simulation.ILCResult.to_netcdf': ('path',),
    'ilc_analysis.simulation.CompiledTrial.run': ('nu', 't'),
    'ilc_analysis.simulation.compiled_trial': ('dplant', 'N', 'shift', 'jit'),
    'ilc_analysis.simulation.window_times': ('N', 'ts', 'shift', 't0'),
    'ilc_analysis.scenarios.PaperScenario.disturbance': ('t',),
    'ilc_analysis.scenarios.PaperScenario.field_doc': ('name',),
    'ilc_analysis.scenarios.PaperScenario.reference': ('shift',),
    'ilc_analysis.scenarios.PaperScenario.sample_times': ('shift',),
    'ilc_analysis.scenarios.load_scenario': ('path',),
    'ilc_analysis.scenarios.circle_reference': ('t',),
    'ilc_analysis.studies.Study.assignments': ('index',),
    'ilc_analysis.studies.Study.chunk': ('c',),
    'ilc_analysis.studies.Study.from_design': (
        'design', 'axes', 'compute', 'seed', 'name', 'chunk_size'
    ),
    'ilc_analysis.studies.Study.point_seed': ('index',),
    'ilc_analysis.studies.Compute.from_table': ('table',),
    'ilc_analysis.studies.Axis.parameter_values': ('path',),
    'ilc_analysis.studies.load_study': ('path',),
    'ilc_analysis.studies.study_from_table': ('data', 'base_dir', 'source'),
    'ilc_analysis.studies.StudyRun': ('study', 'directory', 'executor', 'workers'),
    'ilc_analysis.studies.SerialExecutor.map': ('study', 'chunks', 'metric_names'),
    'ilc_analysis.studies.DaskExecutor.map': ('study', 'chunks', 'metric_names'),
    'ilc_analysis.studies.executor_for': ('executor', 'workers', 'scheduler', 'timeout'),
    'ilc_analysis.studies.grid': ('parameter', 'values', 'name', 'start', 'stop', 'num'),
    'ilc_analysis.studies.choice': ('name', 'options'),
    'ilc_analysis.studies.monte_carlo': ('parameters', 'count', 'seed', 'name', 'nominal'),
    'ilc_analysis.studies.latin_hypercube': ('parameters', 'count', 'seed', 'name', 'nominal'),
    'ilc_analysis.studies.vertices': ('parameters', 'name', 'include_nominal', 'nominal'),
    'ilc_analysis.studies.evaluate_point': ('study', 'index', 'metric_names'),
    'ilc_analysis.studies.output_variables': ('study', 'metric_names'),
    'ilc_analysis.studies.labelled_dataset': ('study', 'flat'),
    'ilc_analysis.studies.open_results': ('path',),
    'ilc_analysis.studies.point_seed': ('seed', 'index'),
}
