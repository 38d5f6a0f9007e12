"""The moved and renamed public names of 0.2.0 (issue 25), kept working until 0.3.0.

One table for the whole package: :data:`MOVED_MODULES` for the import hook
(:class:`~ilc_analysis._deprecation.MovedModules`, installed by the package), and
:data:`RENAMED` for each public face's ``__getattr__``
(:func:`~ilc_analysis._deprecation.deprecated_names`): ``old name -> (where it is now,
removed in[, what to use instead])``. Data only: nothing here imports a stage.
"""

from __future__ import annotations

from ._deprecation import REMOVED_IN

#: old module path -> new module path (the same module object)
MOVED_MODULES: dict[str, str] = {
    'ilc_analysis.cli.check_command': 'ilc_analysis.cli._check_command',
    'ilc_analysis.cli.common': 'ilc_analysis.cli._common',
    'ilc_analysis.cli.design_support': 'ilc_analysis.cli._design_support',
    'ilc_analysis.cli.lead_scan_command': 'ilc_analysis.cli._lead_scan_command',
    'ilc_analysis.cli.learn_command': 'ilc_analysis.cli._learn_command',
    'ilc_analysis.cli.lifted_command': 'ilc_analysis.cli._lifted_command',
    'ilc_analysis.cli.model_command': 'ilc_analysis.cli._model_command',
    'ilc_analysis.cli.reproduce_command': 'ilc_analysis.cli._reproduce_command',
    'ilc_analysis.cli.simulate_command': 'ilc_analysis.cli._simulate_command',
    'ilc_analysis.cli.study_command': 'ilc_analysis.cli._study_command',
    'ilc_analysis.cli.synthesize_command': 'ilc_analysis.cli._synthesize_command',
    'ilc_analysis.conditions': 'ilc_analysis.analysis',
    'ilc_analysis.conditions.error_norm': 'ilc_analysis.analysis._error_norm',
    'ilc_analysis.conditions.forgetting_box': 'ilc_analysis.analysis._forgetting_box',
    'ilc_analysis.conditions.frequency': 'ilc_analysis.analysis._frequency',
    'ilc_analysis.conditions.law_analysis': 'ilc_analysis.analysis._law_analysis',
    'ilc_analysis.conditions.lifted_checks': 'ilc_analysis.analysis._lifted_checks',
    'ilc_analysis.conditions.paper_theorem': 'ilc_analysis.analysis._paper_theorem',
    'ilc_analysis.conditions.relative_degree_form': 'ilc_analysis.analysis._relative_degree_form',
    'ilc_analysis.conditions.report': 'ilc_analysis.analysis._report',
    'ilc_analysis.conditions.structured': 'ilc_analysis.analysis._structured',
    'ilc_analysis.conditions.theorem': 'ilc_analysis.analysis._theorem',
    'ilc_analysis.conditions.verdicts': 'ilc_analysis.analysis._verdicts',
    'ilc_analysis.design.array_files': 'ilc_analysis._array_files',
    'ilc_analysis.design.design': 'ilc_analysis.design._design',
    'ilc_analysis.design.file': 'ilc_analysis.design._file',
    'ilc_analysis.design.plant_spec': 'ilc_analysis.design._plant_spec',
    'ilc_analysis.design.signals': 'ilc_analysis.design._signals',
    'ilc_analysis.law': 'ilc_analysis.laws',
    'ilc_analysis.laws.base': 'ilc_analysis.laws._base',
    'ilc_analysis.laws.bounds': 'ilc_analysis.laws._bounds',
    'ilc_analysis.laws.constrained': 'ilc_analysis.laws._constrained',
    'ilc_analysis.laws.gradient': 'ilc_analysis.laws._gradient',
    'ilc_analysis.laws.nonlinear': 'ilc_analysis.laws._nonlinear',
    'ilc_analysis.laws.norm_optimal': 'ilc_analysis.laws._norm_optimal',
    'ilc_analysis.laws.pd': 'ilc_analysis.laws._pd',
    'ilc_analysis.laws.ql': 'ilc_analysis.laws._ql',
    'ilc_analysis.laws.registry': 'ilc_analysis.laws._registry',
    'ilc_analysis.laws.stage_qp': 'ilc_analysis.laws._stage_qp',
    'ilc_analysis.lifting.inverse': 'ilc_analysis.lifting._inverse',
    'ilc_analysis.lifting.lift': 'ilc_analysis.lifting._lift',
    'ilc_analysis.lifting.lifted_system': 'ilc_analysis.lifting._lifted_system',
    'ilc_analysis.lifting.lti_lifting': 'ilc_analysis.lifting._lti_lifting',
    'ilc_analysis.lifting.operators': 'ilc_analysis.lifting._operators',
    'ilc_analysis.lifting.shift': 'ilc_analysis.lifting._shift',
    'ilc_analysis.lifting.trial_map': 'ilc_analysis.lifting._trial_map',
    'ilc_analysis.lifting.validation': 'ilc_analysis.lifting._validation',
    'ilc_analysis.model.discretize': 'ilc_analysis.model._discretize',
    'ilc_analysis.model.linear_analysis': 'ilc_analysis.model._linear_analysis',
    'ilc_analysis.model.paper_defects': 'ilc_analysis.model._paper_defects',
    'ilc_analysis.model.parameters': 'ilc_analysis.model._parameters',
    'ilc_analysis.model.plant': 'ilc_analysis.model._plant',
    'ilc_analysis.model.registry': 'ilc_analysis.model._registry',
    'ilc_analysis.model.report': 'ilc_analysis.model._report',
    'ilc_analysis.model.robots': 'ilc_analysis.model._robots',
    'ilc_analysis.plotting.learning': 'ilc_analysis.plotting._learning',
    'ilc_analysis.plotting.run_figures': 'ilc_analysis.plotting._run_figures',
    'ilc_analysis.problem.compose': 'ilc_analysis.problem._compose',
    'ilc_analysis.problem.learning_at': 'ilc_analysis.problem._learning_at',
    'ilc_analysis.problem.problem': 'ilc_analysis.problem._problem',
    'ilc_analysis.scenarios': 'ilc_analysis.paper',
    'ilc_analysis.scenarios.circle': 'ilc_analysis.paper._circle',
    'ilc_analysis.scenarios.config': 'ilc_analysis.paper._config',
    'ilc_analysis.scenarios.designs': 'ilc_analysis.paper._designs',
    'ilc_analysis.scenarios.figures': 'ilc_analysis.paper._figures',
    'ilc_analysis.scenarios.findings': 'ilc_analysis.paper._findings',
    'ilc_analysis.scenarios.lead_scan': 'ilc_analysis.paper._lead_scan',
    'ilc_analysis.scenarios.nonlinear_comparison': 'ilc_analysis.paper._nonlinear_comparison',
    'ilc_analysis.scenarios.pipeline': 'ilc_analysis.paper._pipeline',
    'ilc_analysis.scenarios.pitch_bounded': 'ilc_analysis.paper._pitch_bounded',
    'ilc_analysis.scenarios.report': 'ilc_analysis.paper._report',
    'ilc_analysis.scenarios.synthesis_step': 'ilc_analysis.paper._synthesis_step',
    'ilc_analysis.simulation.disturbances': 'ilc_analysis.problem._disturbances',
    'ilc_analysis.simulation.divergence': 'ilc_analysis.simulation._divergence',
    'ilc_analysis.simulation.engine': 'ilc_analysis.simulation._engine',
    'ilc_analysis.simulation.law_adapter': 'ilc_analysis.simulation._law_adapter',
    'ilc_analysis.simulation.laws': 'ilc_analysis.simulation._laws',
    'ilc_analysis.simulation.learner': 'ilc_analysis.simulation._learner',
    'ilc_analysis.simulation.machine': 'ilc_analysis.simulation._machine',
    'ilc_analysis.simulation.qfilter': 'ilc_analysis.laws._qfilter',
    'ilc_analysis.simulation.reference': 'ilc_analysis.simulation._reference',
    'ilc_analysis.simulation.results': 'ilc_analysis.simulation._results',
    'ilc_analysis.simulation.trial': 'ilc_analysis.simulation._trial',
    'ilc_analysis.studies.evaluate': 'ilc_analysis.studies._evaluate',
    'ilc_analysis.studies.executors': 'ilc_analysis.studies._executors',
    'ilc_analysis.studies.figures': 'ilc_analysis.studies._figures',
    'ilc_analysis.studies.report': 'ilc_analysis.studies._report',
    'ilc_analysis.studies.run': 'ilc_analysis.studies._run',
    'ilc_analysis.studies.spec': 'ilc_analysis.studies._spec',
    'ilc_analysis.studies.storage': 'ilc_analysis.studies._storage',
    'ilc_analysis.studies.variations': 'ilc_analysis.studies._variations',
    'ilc_analysis.synthesis.boxqp': 'ilc_analysis.synthesis._boxqp',
    'ilc_analysis.synthesis.certify': 'ilc_analysis.synthesis._certify',
    'ilc_analysis.synthesis.feedback': 'ilc_analysis.synthesis._feedback',
    'ilc_analysis.synthesis.frequency': 'ilc_analysis.synthesis._frequency',
    'ilc_analysis.synthesis.lead_scan': 'ilc_analysis.synthesis._lead_scan',
    'ilc_analysis.synthesis.lifted': 'ilc_analysis.synthesis._lifted',
    'ilc_analysis.synthesis.options': 'ilc_analysis.synthesis._options',
    'ilc_analysis.synthesis.paper_level': 'ilc_analysis.synthesis._paper_level',
    'ilc_analysis.synthesis.residual_bound': 'ilc_analysis.synthesis._residual_bound',
    'ilc_analysis.synthesis.result': 'ilc_analysis.synthesis._result',
    'ilc_analysis.synthesis.robust': 'ilc_analysis.synthesis._robust',
    'ilc_analysis.synthesis.sigma_max_conic': 'ilc_analysis.synthesis._sigma_max_conic',
    'ilc_analysis.synthesis.spectral': 'ilc_analysis.synthesis._spectral',
    'ilc_analysis.synthesis.structure': 'ilc_analysis.synthesis._structure',
}

#: face -> {old name: (where it is now, removed in[, what to use instead])}
RENAMED: dict[str, dict[str, tuple[str, ...]]] = {
    'ilc_analysis.model': {
        'FALL_ANGLE': ('ilc_analysis.paper.FALL_ANGLE', REMOVED_IN),
        'PAPER_DEFECTS': ('ilc_analysis.paper.PAPER_DEFECTS', REMOVED_IN),
        'PITCH_STATE': ('ilc_analysis.model._robots.PITCH_STATE', REMOVED_IN),
        'PaperDefect': ('ilc_analysis.paper.PaperDefect', REMOVED_IN),
        'ROBOT_MODELS': ('ilc_analysis.paper.ROBOT_MODELS', REMOVED_IN),
        'balance_gain': ('ilc_analysis.paper.balance_gain', REMOVED_IN),
        'first_nonzero_markov': (
            'ilc_analysis.model._linear_analysis.first_nonzero_markov', REMOVED_IN),
        'pendulum_energy': ('ilc_analysis.paper.pendulum_energy', REMOVED_IN),
        'robot_model': ('ilc_analysis.paper.robot_model', REMOVED_IN),
        'steady_motion_torques': ('ilc_analysis.paper.steady_motion_torques', REMOVED_IN),
        'upright_linear_matrices': ('ilc_analysis.paper.upright_linear_matrices', REMOVED_IN),
        'zoh_matrices': ('ilc_analysis.model._discretize.zoh_matrices', REMOVED_IN),
    },
    'ilc_analysis.lifting': {
        'learning_operators': (
            'ilc_analysis.laws._gains.learning_operators', REMOVED_IN,
            'ilc_analysis.laws.PDLaw(gains, forgetting).lifted(lifted_system)'),
        'adjoint_product': ('ilc_analysis.lifting._trial_map.adjoint_product', REMOVED_IN),
        'difference_operator': ('ilc_analysis.lifting._operators.difference_operator', REMOVED_IN),
        'forgetting_matrix': ('ilc_analysis.lifting._operators.forgetting_matrix', REMOVED_IN),
        'jacobian_product': ('ilc_analysis.lifting._trial_map.jacobian_product', REMOVED_IN),
        'lifted_update': ('ilc_analysis.lifting._operators.lifted_update', REMOVED_IN),
        'realisable_reference': ('ilc_analysis.lifting.realizable_reference', REMOVED_IN),
    },
    'ilc_analysis.problem': {
        'LEARNING_AT_KINDS': ('ilc_analysis.problem._learning_at.LEARNING_AT_KINDS', REMOVED_IN),
        'as_model': ('ilc_analysis.problem._compose.as_model', REMOVED_IN),
        'controller_description': (
            'ilc_analysis.problem._learning_at.controller_description', REMOVED_IN),
        'controller_from_description': (
            'ilc_analysis.problem._learning_at.controller_from_description', REMOVED_IN),
        'controller_matrices': (
            'ilc_analysis.problem._learning_at.controller_matrices', REMOVED_IN),
    },
    'ilc_analysis.laws': {
        'Forgetting': ('ilc_analysis.laws._forgetting.Forgetting', REMOVED_IN),
        'GainsFile': ('ilc_analysis.laws._gains_file.GainsFile', REMOVED_IN),
        'NO_FORGETTING': ('ilc_analysis.laws._forgetting.NO_FORGETTING', REMOVED_IN),
        'adjoint_blocks': ('ilc_analysis.laws._gradient.adjoint_blocks', REMOVED_IN),
        'apply_forgetting': ('ilc_analysis.laws._forgetting.apply_forgetting', REMOVED_IN),
        'apply_q': ('ilc_analysis.laws._qfilter.apply_q', REMOVED_IN),
        'check_Lambda': ('ilc_analysis.laws._forgetting.check_Lambda', REMOVED_IN),
        'check_delta': ('ilc_analysis.laws._forgetting.check_delta', REMOVED_IN),
        'gradient_step_bound': ('ilc_analysis.laws._gradient.gradient_step_bound', REMOVED_IN),
        'learning_operators': ('ilc_analysis.laws._gains.learning_operators', REMOVED_IN),
        'norm_optimal_gains': ('ilc_analysis.laws._norm_optimal.norm_optimal_gains', REMOVED_IN),
        'plant_response': ('ilc_analysis.laws._base.plant_response', REMOVED_IN),
        'previous_trial_term': ('ilc_analysis.laws._gains.previous_trial_term', REMOVED_IN),
    },
    'ilc_analysis.analysis': {
        'AnalysisReport': (
            'ilc_analysis.paper._legacy.AnalysisReport', REMOVED_IN,
            'ilc_analysis.analysis.Analysis'),
        'BlockToeplitzOperator': (
            'ilc_analysis.analysis._structured.BlockToeplitzOperator', REMOVED_IN),
        'Couplings': ('ilc_analysis.paper.Couplings', REMOVED_IN),
        'DEFAULT_REDUCTION_FACTOR': (
            'ilc_analysis.analysis._lifted_checks.DEFAULT_REDUCTION_FACTOR', REMOVED_IN),
        'DEFAULT_TRANSIENT_HORIZON': (
            'ilc_analysis.analysis._lifted_checks.DEFAULT_TRANSIENT_HORIZON', REMOVED_IN),
        'LambdaCondition': ('ilc_analysis.paper.LambdaCondition', REMOVED_IN),
        'LawAnalysis': ('ilc_analysis.analysis.Analysis', REMOVED_IN),
        'TRANSIENT_WARNING_PEAK': (
            'ilc_analysis.analysis._lifted_checks.TRANSIENT_WARNING_PEAK', REMOVED_IN),
        'TriangularLearningOperator': (
            'ilc_analysis.analysis._structured.TriangularLearningOperator', REMOVED_IN),
        'analyse': (
            'ilc_analysis.paper._legacy.analyse', REMOVED_IN, 'ilc_analysis.analysis.analyze'),
        'filtered_error_floor': (
            'ilc_analysis.analysis._lifted_checks.filtered_error_floor', REMOVED_IN),
        'filtered_floor_gain': (
            'ilc_analysis.analysis._lifted_checks.filtered_floor_gain', REMOVED_IN),
        'filtered_operator': (
            'ilc_analysis.analysis._lifted_checks.filtered_operator', REMOVED_IN),
        'forgetting_floor_bound': ('ilc_analysis.paper.forgetting_floor_bound', REMOVED_IN),
        'forgetting_values': (
            'ilc_analysis.analysis._paper_theorem.forgetting_values', REMOVED_IN),
        'gamma_factors': ('ilc_analysis.paper.gamma_factors', REMOVED_IN),
        'lambda_condition': ('ilc_analysis.paper.lambda_condition', REMOVED_IN),
        'lambda_rho': ('ilc_analysis.paper.lambda_rho', REMOVED_IN),
        'law_frequency_assumptions': (
            'ilc_analysis.analysis._frequency.law_frequency_assumptions', REMOVED_IN),
        'law_frequency_condition': (
            'ilc_analysis.analysis._frequency.law_frequency_condition', REMOVED_IN),
        'relative_degree_couplings': (
            'ilc_analysis.analysis._relative_degree_form.relative_degree_couplings', REMOVED_IN),
        'sampled_diagonal_block': (
            'ilc_analysis.analysis._relative_degree_form.sampled_diagonal_block', REMOVED_IN),
        'structured_learning_operator': (
            'ilc_analysis.analysis._structured.structured_learning_operator', REMOVED_IN),
        'tight_contraction': ('ilc_analysis.paper.tight_contraction', REMOVED_IN),
        'xi_mu0': ('ilc_analysis.paper.xi_mu0', REMOVED_IN),
    },
    'ilc_analysis.synthesis': {
        'UNCERTAIN_PARAMETERS': ('ilc_analysis.paper.UNCERTAIN_PARAMETERS', REMOVED_IN),
        'parameter_samples': ('ilc_analysis.paper.parameter_samples', REMOVED_IN),
        'parameter_vertices': ('ilc_analysis.paper.parameter_vertices', REMOVED_IN),
        'robot_liftings': ('ilc_analysis.paper.robot_liftings', REMOVED_IN),
        'coupling_matrices': ('ilc_analysis.synthesis._paper_level.coupling_matrices', REMOVED_IN),
        'hat_basis': ('ilc_analysis.synthesis._structure.hat_basis', REMOVED_IN),
        'least_squares_gains': ('ilc_analysis.synthesis._lifted.least_squares_gains', REMOVED_IN),
        'lqr_pd_feedback': ('ilc_analysis.synthesis._feedback.lqr_pd_feedback', REMOVED_IN),
        'pd_loop_spectral_radius': (
            'ilc_analysis.synthesis._feedback.pd_loop_spectral_radius', REMOVED_IN),
        'synthesize_frequency': (
            'ilc_analysis.synthesis._frequency.synthesize_frequency', REMOVED_IN,
            'ilc_analysis.synthesis.synthesize(problem, method="frequency")'),
        'synthesize_lifted': (
            'ilc_analysis.synthesis._lifted.synthesize_lifted', REMOVED_IN,
            'ilc_analysis.synthesis.synthesize(problem, method="lifted")'),
        'synthesize_paper': (
            'ilc_analysis.synthesis._paper_level.synthesize_paper', REMOVED_IN,
            'ilc_analysis.synthesis.synthesize(problem, method="paper")'),
    },
    'ilc_analysis.synthesis._robust': {
        'UNCERTAIN_PARAMETERS': ('ilc_analysis.paper.UNCERTAIN_PARAMETERS', REMOVED_IN),
        'parameter_samples': ('ilc_analysis.paper.parameter_samples', REMOVED_IN),
        'parameter_vertices': ('ilc_analysis.paper.parameter_vertices', REMOVED_IN),
        'robot_liftings': ('ilc_analysis.paper.robot_liftings', REMOVED_IN),
    },
    'ilc_analysis.simulation': {
        'PAPER_AMPLITUDE': ('ilc_analysis.paper.PAPER_AMPLITUDE', REMOVED_IN),
        'PAPER_FREQUENCY': ('ilc_analysis.paper.PAPER_FREQUENCY', REMOVED_IN),
        'DEFAULT_STATE_LIMIT': (
            'ilc_analysis.simulation._divergence.DEFAULT_STATE_LIMIT', REMOVED_IN),
        'Disturbances': ('ilc_analysis.problem.Disturbances', REMOVED_IN),
        'FALL_ANGLE': ('ilc_analysis.paper.FALL_ANGLE', REMOVED_IN),
        'ILCLaw': (
            'ilc_analysis.simulation._laws.ILCLaw', REMOVED_IN, 'ilc_analysis.laws.LearningLaw'),
        'OpenClosedLoopPDLaw': (
            'ilc_analysis.simulation._laws.OpenClosedLoopPDLaw', REMOVED_IN,
            'ilc_analysis.laws.PDLaw'),
        'ProblemLaw': ('ilc_analysis.simulation._law_adapter.ProblemLaw', REMOVED_IN),
        'QFilter': ('ilc_analysis.laws.QFilter', REMOVED_IN),
        'TrialDisturbance': ('ilc_analysis.problem.TrialDisturbance', REMOVED_IN),
        'design_fingerprint': ('ilc_analysis.simulation._learner.design_fingerprint', REMOVED_IN),
        'known_disturbance': ('ilc_analysis.simulation._machine.known_disturbance', REMOVED_IN),
        'previous_trial_term': ('ilc_analysis.laws._gains.previous_trial_term', REMOVED_IN),
        'problem_law': ('ilc_analysis.simulation._law_adapter.problem_law', REMOVED_IN),
        'simulate_plant': (
            'ilc_analysis.simulation._engine.simulate_plant', REMOVED_IN,
            'ilc_analysis.simulation.simulate(problem, law, iterations)'),
        'simulate_problem': (
            'ilc_analysis.simulation._engine.simulate_problem', REMOVED_IN,
            'ilc_analysis.simulation.simulate'),
        'simulate_reference': (
            'ilc_analysis.simulation._reference.simulate_reference', REMOVED_IN),
        'window_times': ('ilc_analysis.simulation._trial.window_times', REMOVED_IN),
    },
    'ilc_analysis.plotting': {
    },
    'ilc_analysis.paper': {
    },
    'ilc_analysis.design': {
        'CERTIFIED_NUMBERS': ('ilc_analysis.design._design.CERTIFIED_NUMBERS', REMOVED_IN),
        'CHECK_RTOL': ('ilc_analysis.design._design.CHECK_RTOL', REMOVED_IN),
        'DesignFileError': ('ilc_analysis.exceptions.DesignFileError', REMOVED_IN),
        'PAPER_DESIGN_FILES': ('ilc_analysis.paper._designs.PAPER_DESIGN_FILES', REMOVED_IN),
        'design_document': ('ilc_analysis.design._file.design_document', REMOVED_IN),
        'is_gains_file': ('ilc_analysis.design._file.is_gains_file', REMOVED_IN),
        'operator_fingerprint': ('ilc_analysis.design._design.operator_fingerprint', REMOVED_IN),
        'paper_run_designs': ('ilc_analysis.paper._designs.paper_run_designs', REMOVED_IN),
    },
    'ilc_analysis.studies': {
        'AXIS_KINDS': ('ilc_analysis.studies._variations.AXIS_KINDS', REMOVED_IN),
        'LIFTED_CONDITIONS': ('ilc_analysis.studies._evaluate.LIFTED_CONDITIONS', REMOVED_IN),
        'evaluate_point': ('ilc_analysis.studies._evaluate.evaluate_point', REMOVED_IN),
        'labelled_dataset': ('ilc_analysis.studies._storage.labelled_dataset', REMOVED_IN),
        'output_variables': ('ilc_analysis.studies._evaluate.output_variables', REMOVED_IN),
        'point_seed': ('ilc_analysis.studies._spec.point_seed', REMOVED_IN),
    },
}
