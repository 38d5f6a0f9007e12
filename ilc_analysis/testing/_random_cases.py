r"""Seeded random LTI problems and learning laws of every kind, for property tests and for the
comparison of the dense and the operator engines (``benchmarks/bench_engine_comparison.py``).

:func:`random_problem` draws a discrete plant (1-3 states, 1-2 inputs and outputs; stable, a
quarter of the SISO ones non-minimum-phase by construction) at the plant input, or a SISO plant
(possibly unstable) inside a PID loop with learning at the loop's reference or input; the
closed loop must be stable. :func:`random_law` draws a law of one of
:data:`RANDOM_LAW_KINDS` scaled to the plant (gains from the inverse of the first Markov
parameter it acts through, step sizes from an estimate of :math:`\sigma_{\max}(G)`), so that
both converging and diverging laws appear. A law that does not fit the problem (an inverse
model of a non-minimum-phase plant, an unstable current-trial loop) raises
:class:`~ilc_analysis.exceptions.ParameterError`; draw again.
"""

from __future__ import annotations

import control
import numpy as np

from .._validation import positive_int
from ..exceptions import ParameterError, ShapeError

__all__ = ["random_problem", "random_law", "RANDOM_LAW_KINDS"]

#: The law kinds :func:`random_law` draws.
RANDOM_LAW_KINDS = ("pd", "pd-lead", "pd-q-filter", "pd-variable-forgetting", "ql",
                    "inverse-model", "gradient", "time-reversal", "norm-optimal")


def _stable_matrix(rng, n: int, radius: float) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A * radius / max(float(np.max(np.abs(np.linalg.eigvals(A)))), 1e-3)


def _plant(rng, n_u: int, n_y: int, radius: float, ts: float, nmp: bool):
    """A strictly proper discrete plant with ``C B`` of reasonable size; ``nmp``: SISO with a
    zero outside the unit circle."""
    while True:
        n_x = int(rng.integers(1, 4))
        if nmp:
            n_x = max(n_x, 2)
            poles = rng.uniform(-radius, radius, size=n_x)
            zero = float(rng.choice([-1.0, 1.0]) * rng.uniform(1.1, 3.0))
            num = np.poly([zero] + list(rng.uniform(-0.8, 0.8, size=n_x - 2)))
            sys = control.ss(control.tf(num, np.poly(poles), ts))
            A, B, C = sys.A, sys.B, sys.C
        else:
            A = _stable_matrix(rng, n_x, radius)
            B, C = rng.normal(size=(n_x, n_u)), rng.normal(size=(n_y, n_x))
        if np.linalg.norm(C @ B) >= 0.2 * np.linalg.norm(C) * np.linalg.norm(B):
            return control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1])), ts)


def random_problem(rng, N: int, *, square: bool = False, minimum_phase: bool = False,
                   loops: bool = True, ts: float = 0.01):
    r"""A random :class:`~ilc_analysis.problem.ILCProblem` of N samples (module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
    N : int
        Trial length.
    square : bool
        As many outputs as inputs.
    minimum_phase : bool
        Only plants (or loops) whose zeros lie inside the unit circle (for an inverse model).
    loops : bool
        Allow the PID-loop problems.
    ts : float
        Sample time [s].

    Returns
    -------
    ILCProblem
    """
    from ..exceptions import UnstableLoopError
    from ..problem import ILCProblem, LoopInput, LoopReference, pid

    N = positive_int(N, "N")
    while True:
        loop = loops and rng.random() < 0.25
        n_u = 1 if loop else int(rng.integers(1, 3))
        n_y = n_u if loop or square or rng.random() < 0.7 else int(rng.integers(1, 3))
        nmp = not minimum_phase and n_u == n_y == 1 and rng.random() < 0.3
        radius = float(rng.uniform(0.6, 1.15)) if loop else float(rng.uniform(0.3, 0.97))
        sys = _plant(rng, n_u, n_y, radius, ts, nmp)
        reference = rng.normal(size=(N, n_y))
        try:
            if loop:
                controller = control.c2d(pid(float(rng.uniform(0.1, 1.5)),
                                             float(rng.uniform(0.0, 0.5))), ts)
                where = (LoopReference if rng.random() < 0.5 else LoopInput)(controller)
                problem = ILCProblem(sys, ts=ts, N=N, reference=reference,
                                     name="random loop", learning_at=where)
            else:
                problem = ILCProblem(sys, ts=ts, N=N, reference=reference, name="random")
            system = problem.lti_system
            if max(np.abs(np.linalg.eigvals(system.A)), default=0.0) >= 0.995:
                continue                                # a slow or unstable loop: again
            if minimum_phase and not _minimum_phase(system):
                continue
            _ = problem.lifted_plant                    # overflow: ParameterError
            return problem
        except (ParameterError, UnstableLoopError):
            continue


def _minimum_phase(system) -> bool:
    if system.ninputs != system.noutputs:
        return False
    zeros = control.zeros(system)
    return bool(np.all(np.abs(zeros) < 0.98)) if np.size(zeros) else True


def _markov(problem, lag: int) -> np.ndarray:
    """The lifted G's block at ``lag`` (its first block column)."""
    t = problem.lifted_plant.G.toeplitz_blocks()
    return np.asarray(t[min(lag, t.shape[0] - 1)])


def _lead(rng, problem) -> int:
    """A lead of one sample around the lag where the plant's impulse response peaks (how a
    lead is chosen in practice: the learning reads the error where the input shows most),
    at least 1."""
    t = problem.lifted_plant.G.toeplitz_blocks()
    peak = int(np.argmax(np.linalg.norm(t[:min(t.shape[0], 200)], axis=(1, 2))))
    return max(1, peak + int(rng.integers(-1, 2)))


def _inverse_gain(rng, problem, lag: int) -> np.ndarray:
    r""":math:`\kappa\,h^{+}(I + 0.3\,\Xi)`: a learning gain acting through the Markov
    parameter h at ``lag`` (κ log-uniform in [0.05, 2])."""
    h = _markov(problem, lag)
    kappa = float(10.0 ** rng.uniform(-1.3, 0.3))
    noise = np.eye(h.shape[0]) + 0.3 * rng.normal(size=(h.shape[0], h.shape[0]))
    return kappa * np.linalg.pinv(h) @ noise


def _sigma_max(problem) -> float:
    """An estimate of :math:`\\sigma_{\\max}(G)` (power iteration on the operator)."""
    G = problem.lifted_plant.G
    v = np.random.default_rng(0).standard_normal(G.shape[1])
    s = 1.0
    for _ in range(30):
        w = G.rmatvec(G.matvec(v))
        s = float(np.linalg.norm(w))
        v = w / s
    return float(np.sqrt(s))


def _q_filter(rng, ts: float, N: int):
    """A random Q-filter that fits a trial of N samples: an FIR of at most N/3 - 2 taps
    beyond its first, so that forward-backward filtering's padding of 3 (order + 1) samples
    stays below N (a Butterworth's padding is at most 15 samples, below the 20 of the
    shortest random trial)."""
    from ..laws import QFilter

    cutoff = float(rng.uniform(0.02, 0.3)) / ts
    kind = rng.choice(["butterworth", "butterworth", "first-order", "fir", "dct", "zero-state"])
    if kind == "butterworth":
        return QFilter.butterworth(cutoff, int(rng.integers(1, 5)))
    if kind == "first-order":
        return QFilter.first_order(cutoff)
    if kind == "fir":
        return QFilter.fir(cutoff, int(rng.integers(5, max(6, min(22, N // 3 - 1)))))
    if kind == "dct":
        return QFilter.dct(cutoff, int(rng.integers(1, 4)))
    return QFilter.butterworth(cutoff, int(rng.integers(1, 4)), ends="zero-state")


def _pd(rng, problem, *, lead: int = 0, q_filter=None, forgetting=None, current=None):
    from ..laws import FixedForgetting, PDGains, PDLaw

    n_u, n_y, ts = problem.n_u, problem.n_y, problem.ts
    psi1 = _inverse_gain(rng, problem, lead)
    phi1 = 0.1 * psi1 * ts * rng.normal()
    current = rng.random() < 0.3 if current is None else current
    psi2 = phi2 = np.zeros((n_u, n_y))
    if current:
        psi2 = 0.3 * _inverse_gain(rng, problem, 0)
        phi2 = 0.05 * psi2 * ts * rng.normal()
    if forgetting is None:
        forgetting = FixedForgetting(float(rng.choice([0.0, 0.0, 0.05, 0.3])))
    return PDLaw(PDGains(phi1, phi2, psi1, psi2, lead=lead), forgetting, q_filter=q_filter)


def _ql(rng, problem):
    from ..laws import QLLaw

    n_u, ts = problem.n_u, problem.ts
    advance = _lead(rng, problem) if rng.random() < 0.7 else 0
    gain = _inverse_gain(rng, problem, advance)
    if rng.random() < 0.5:
        L = gain
    else:
        p = float(rng.uniform(-0.5, 0.9))
        L = control.ss([[p]], rng.normal(size=(1, problem.n_y)), (1.0 - p) * gain @
                       rng.normal(size=(problem.n_y, 1)), 0.5 * gain, ts)
    Q, zero_phase = None, False
    pick = rng.random()
    if pick < 0.3:
        q = float(rng.uniform(0.0, 0.8))
        Q = control.ss(q * np.eye(n_u), np.eye(n_u), (1.0 - q) * np.eye(n_u),
                       np.zeros((n_u, n_u)), ts)
        zero_phase = bool(rng.random() < 0.6)
    elif pick < 0.55:
        Q = _q_filter(rng, ts, problem.N)
    return QLLaw(L, Q=Q, advance=advance, zero_phase=zero_phase)


def _inverse(rng, problem):
    from ..laws import InverseModelLaw

    gamma = float(rng.uniform(0.1, 1.9))
    pick = rng.random()
    Q, zero_phase = None, False
    if pick < 0.5:
        Q = _q_filter(rng, problem.ts, problem.N)
    elif pick < 0.75:
        n_u = problem.n_u
        q = float(rng.uniform(0.0, 0.8))
        Q = control.ss(q * np.eye(n_u), np.eye(n_u), (1.0 - q) * np.eye(n_u),
                       np.zeros((n_u, n_u)), problem.ts)
        zero_phase = bool(rng.random() < 0.6)
    return InverseModelLaw(problem.lti_system, gamma, Q=Q, zero_phase=zero_phase)


def _model_plant(rng, problem, error: float):
    """The problem's plant with every matrix entry off by a relative ``error`` (normal)."""
    from ..model import DiscretePlant

    s = problem.lti_system
    A = s.A * (1.0 + error * rng.normal(size=s.A.shape))
    if max(np.abs(np.linalg.eigvals(A)), default=0.0) >= 0.999:
        A = s.A
    sys = control.ss(A, s.B * (1.0 + error * rng.normal(size=s.B.shape)),
                     s.C * (1.0 + error * rng.normal(size=s.C.shape)), s.D, problem.ts)
    return DiscretePlant.from_statespace(sys, name="model (perturbed)")


def _gradient(rng, problem):
    from ..laws import GradientLaw

    beta = float(rng.uniform(0.1, 1.3)) * 2.0 / _sigma_max(problem) ** 2
    pick = rng.random()
    if pick < 0.35:
        return GradientLaw(beta, problem.dplant)
    if pick < 0.65:
        return GradientLaw(beta, problem.lifted)
    return GradientLaw(beta, _model_plant(rng, problem, float(rng.uniform(0.02, 0.3))))


def _norm_optimal(rng, problem):
    from ..laws import NormOptimalLaw
    from ..problem import ILCProblem

    lam = float(10.0 ** rng.uniform(-3.0, 0.5)) * _sigma_max(problem) ** 2
    rho = 0.0 if rng.random() < 0.6 else float(10.0 ** rng.uniform(-3.0, 0.0)) * lam
    pick = rng.random()
    if pick < 0.45:
        return NormOptimalLaw(problem.lifted, weight_input_change=lam, weight_input=rho)
    if pick < 0.75:
        return NormOptimalLaw.from_problem(problem, weight_input_change=lam, weight_input=rho)
    model = _model_plant(rng, problem, float(rng.uniform(0.02, 0.3)))
    twin = ILCProblem(model, ts=problem.ts, N=problem.N,
                      reference=np.zeros((problem.N, problem.n_y)), shift=problem.shift)
    return NormOptimalLaw(twin.lifted, weight_input_change=lam, weight_input=rho)


def random_law(kind: str, rng, problem):
    """A random law of ``kind`` (:data:`RANDOM_LAW_KINDS`) scaled to ``problem`` (module
    docstring).

    Parameters
    ----------
    kind : str
        One of :data:`RANDOM_LAW_KINDS`.
    rng : numpy.random.Generator
        The source of the law's random parameters (seeded: the same draw gives the same law).
    problem : ILCProblem
        The problem the law is drawn for (its plant, N, ts and loop scale the gains).

    Returns
    -------
    LearningLaw
        The law.

    Raises
    ------
    ParameterError
        An unknown kind, or a law that does not fit the problem (draw again).
    """
    from ..laws import QFilter, TimeReversalLaw, VariableForgetting

    if kind == "pd":
        return _pd(rng, problem)
    if kind == "pd-lead":
        return _pd(rng, problem, lead=_lead(rng, problem))
    if kind == "pd-q-filter":
        q = _q_filter(rng, problem.ts, problem.N)
        if isinstance(q, QFilter) and q.kind != "dct":
            try:
                q._check_length(problem.N, q._design(1.0 / problem.ts)[1])
            except ShapeError as exc:       # the documented 'draw again'
                raise ParameterError(f"the drawn Q-filter does not fit: {exc}") from exc
        lead = _lead(rng, problem) if rng.random() < 0.6 else 0
        return _pd(rng, problem, lead=lead, q_filter=q, current=False)
    if kind == "pd-variable-forgetting":
        return _pd(rng, problem, forgetting=VariableForgetting(
            delta=float(rng.uniform(0.6, 0.99)), Lambda=6.0), current=False)
    if kind == "ql":
        return _ql(rng, problem)
    if kind == "inverse-model":
        return _inverse(rng, problem)
    if kind == "gradient":
        return _gradient(rng, problem)
    if kind == "time-reversal":
        return TimeReversalLaw(float(rng.uniform(0.1, 1.3)) * 2.0 / _sigma_max(problem) ** 2)
    if kind == "norm-optimal":
        return _norm_optimal(rng, problem)
    raise ParameterError(f"kind must be one of {RANDOM_LAW_KINDS}; got {kind!r}")
