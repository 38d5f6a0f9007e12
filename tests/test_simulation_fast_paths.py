"""The fast simulation paths compute what the interpreted CasADi trial computes (issue 36).

* :class:`ModalRecursion` (the Schur modes solved in place by the compiled first-order kernel
  or by BLAS) against the recursion stepped sample by sample: real, complex and defective
  modes, one input or several, any stretch length (none, one sample), into a new, a C-ordered
  or a Fortran-ordered array. The kernel refuses a column outside its array; it is built once
  and kept on disk; without a compiler the recursion takes BLAS silently, a failing build
  says so once, and ``jit=True`` is an error. The bounds the kernel reports (on every state
  it wrote and every input it read) hold, or are not finite, whatever NaN, infinity or
  overflow it met (hypothesis); a linear trial's bounds hold for its record.
* A cached :class:`LinearTrial` keeps no finished run's gains or disturbances alive.
* :class:`LinearTrial` (an LTI plant by its Schur modes) against the
  interpreted :class:`CompiledTrial` on random plants (hypothesis): any shift, N shorter than
  the shift, state and output disturbances, a random initial state, no current-trial feedback
  or a constant one (the closed loop), a defective A (double integrator) and complex modes;
  a time-varying current-trial gain takes the CasADi trial.
* ``simulate`` on an LTI problem against the same learning loop written by hand.
* The compiled nonlinear trial (C, kept on disk) against the interpreted one; a second build
  loads the library without compiling; without a compiler the default falls back, saying so
  once, and ``jit=True`` is an error.
* The learning update as the run makes it: written into the run's row for the next input
  (equal to the public ``between_trials``), and the long products by scalars (equal to
  ``matmul``).
* The run's block from the pool of maps: reused once no array uses it, never while a result
  or a view of it is kept.
* Without current-trial feedback the data set's ``u`` and ``u_ff`` are one array; with it,
  two. The cheap screen of a trial never passes one the exact check refuses (hypothesis:
  non-finite values and states beyond their bounds anywhere, with or without the bounds a
  trial may hand it), and the error extremes it keeps are the data set's ``max_abs_e``.

Tolerances: the paths add the same terms in different orders, so they agree to rounding,
amplified by at most the growth of the recursion over the trial (2-norm of A <= 1.05,
N <= 25 here: a factor below 4); 1e-9 relative to the largest magnitude leaves a wide margin.
"""

from __future__ import annotations

import gc
import warnings
import weakref
from types import SimpleNamespace

import control
import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
import scipy.linalg.blas
import scipy.signal
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ilc_analysis import _arrays as arrays_module
from ilc_analysis._arrays import lazy_zeros, long_matmul, narrow_reduce, recycled_empty
from ilc_analysis.exceptions import ILCWarning, ParameterError, ShapeError
from ilc_analysis.laws import (
    FixedForgetting,
    LearningLaw,
    PDGains,
    PDLaw,
    QFilter,
    VariableForgetting,
)
from ilc_analysis.laws._gains import previous_trial_term
from ilc_analysis.model import DiscretePlant, balanced_mobile_robot, discretize
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import CompiledTrial, DivergenceBounds, simulate
from ilc_analysis.simulation import _engine as engine_module
from ilc_analysis.simulation import _first_order as first_order_module
from ilc_analysis.simulation import _trial as trial_module
from ilc_analysis.simulation._linear_trial import LinearTrial, ModalRecursion
from ilc_analysis.simulation._trial import TrialRecord, window_times

RTOL = 1e-9


def _close(a, b):
    scale = 1.0 + max(np.max(np.abs(a), initial=0.0), np.max(np.abs(b), initial=0.0))
    np.testing.assert_allclose(a, b, rtol=0.0, atol=RTOL * scale)


def _records_agree(rec_fast, rec_ref):
    for name in ("x", "u", "y", "e", "signals"):
        _close(getattr(rec_fast, name), getattr(rec_ref, name))


def _plant(A, B, C, ts=0.1):
    n_y, n_u = C.shape[0], B.shape[1]
    return DiscretePlant.from_statespace(control.ss(A, B, C, np.zeros((n_y, n_u)), ts))


_F = {"real": [[0.9, 0.2, 0.0], [0.1, -0.5, 0.3], [0.0, 0.2, 0.4]],
      "complex_pair": [[0.9, -0.4, 0.1], [0.4, 0.9, 0.0], [0.0, 0.3, -0.7]],
      "jordan": [[1.0, 0.1, 0.0], [0.0, 1.0, 0.1], [0.0, 0.0, 1.0]],
      "triangular": [[0.5, 0.0, 0.0], [0.0, -0.3, 0.0], [0.0, 0.0, 1.02]]}


#: the recursion's solvers this machine has: BLAS always, the compiled kernel with a compiler
_SOLVERS = [False] + ([True] if trial_module.c_compiler() is not None else [])


@settings(max_examples=120, deadline=None)
@given(kind=st.sampled_from(sorted(_F)), n=st.integers(1, 3), m=st.integers(0, 2),
       L=st.sampled_from([0, 1, 2, 7, 40]), layout=st.sampled_from(["new", "C", "F"]),
       jit=st.sampled_from(_SOLVERS), seed=st.integers(0, 2**32 - 1))
def test_the_modal_recursion_equals_the_recursion_stepped_by_samples(kind, n, m, L, layout,
                                                                      jit, seed):
    rng = np.random.default_rng(seed)
    F = np.array(_F[kind])[:n, :n]
    G = rng.standard_normal((n, m)) if m else None     # m = 0: no input matrix (v = r)
    v = rng.standard_normal((L, m if m else n))
    z0 = rng.standard_normal(n)
    z, z_k = np.empty((L, n)), z0.copy()
    for k in range(L):
        z[k] = z_k
        z_k = F @ z_k + (G @ v[k] if m else v[k])
    out = {"new": None, "C": np.empty((L, n)), "F": np.empty((L, n), order="F")}[layout]
    bounds = np.empty(2)
    states, end = ModalRecursion(F, G, jit=jit).run(z0, v, True, out, bounds)
    if out is not None:
        assert states is out
    _close(states, z)
    _close(end, z_k)
    # the kernel's bounds: on every state it wrote and on every input it read (NaN: none)
    assert np.isnan(bounds[0]) == (not jit or L < 2)
    if not np.isnan(bounds[0]):
        assert np.abs(states).max() <= bounds[0]
    if not np.isnan(bounds[1]):
        assert m == 1 and np.abs(v[:L - 1]).max() <= bounds[1]


def test_the_modal_recursion_takes_back_a_solution_the_blas_wrapper_made_on_a_copy(
        monkeypatch):
    real = scipy.linalg.blas.get_blas_funcs

    def copying(names, arrays):         # a wrapper that solves a copy and returns it
        solve = real(names, arrays)
        return lambda k, a, x, **kw: solve(k, a, x.copy(), **kw)

    F = np.array(_F["real"])
    rng = np.random.default_rng(3)
    v, z0 = rng.standard_normal((30, 3)), rng.standard_normal(3)
    expected, _ = ModalRecursion(F, jit=False).run(z0, v)
    monkeypatch.setattr(scipy.linalg.blas, "get_blas_funcs", copying)
    states, _ = ModalRecursion(F, jit=False).run(z0, v)
    _close(states, expected)


@pytest.fixture
def fresh_kernel():
    """The kernel's per-process state cleared before and after the test."""
    first_order_module._loaded.cache_clear()
    trial_module._stated.clear()
    yield first_order_module
    first_order_module._loaded.cache_clear()
    trial_module._stated.clear()


@pytest.mark.skipif(trial_module.c_compiler() is None, reason="no C compiler")
def test_the_compiled_kernel_refuses_a_column_outside_its_array():
    kernel = first_order_module.first_order_kernel(True)
    z, peaks = np.zeros(10), np.empty(3)
    with pytest.raises(ShapeError, match="does not fit a vector of 10"):
        kernel.solve(z, 1, 3, 4, 0.5, peaks)      # elements 1, 4, 7, 10: one past the end
    with pytest.raises(ShapeError, match="writeable contiguous vector"):
        kernel.solve(z[::2], 0, 1, 5, 0.5, peaks)
    with pytest.raises(ShapeError, match="at least 9 samples"):
        kernel.driven(z, 0, 1, 10, 0.5, np.zeros(8), 1.0, peaks)
    with pytest.raises(ShapeError, match="float64 vector of 3"):
        kernel.solve(z, 0, 1, 10, 0.5, np.empty(2))
    with pytest.raises(ParameterError, match="float64 or complex128"):
        kernel.solve(np.zeros(4, dtype=np.float32), 0, 1, 4, 0.5, peaks)
    kernel.solve(z, 1, 3, 3, 0.5, peaks)          # elements 1, 4, 7: inside
    z = np.arange(6, dtype=complex)
    kernel.solve(z, 0, 2, 3, 0.5j, peaks)         # elements 0, 2, 4 of a complex vector
    np.testing.assert_allclose(z[[0, 2, 4]], [0, 2, 4 + 1j])
    np.testing.assert_array_equal(z[[1, 3, 5]], [1, 3, 5])
    assert peaks[0] == 5.0                        # |4| + |1|


@pytest.mark.skipif(trial_module.c_compiler() is None, reason="no C compiler")
@pytest.mark.parametrize("form", ["contiguous", "read-only", "strided", "column of a matrix"])
def test_the_driven_kernel_reads_its_input_in_any_layout(form):
    """The input reaches the kernel by a view of its buffer or by its address (read-only or
    strided): the same recursion either way, stepped by hand; a one-sample column reads no
    input (an empty one is accepted)."""
    kernel = first_order_module.first_order_kernel(True)
    values = np.linspace(-1.0, 2.0, 7)
    v = {"contiguous": values.copy(), "read-only": values.copy(),
         "strided": np.repeat(values, 3)[::3],
         "column of a matrix": np.column_stack([values, -values])[:, 0]}[form]
    if form == "read-only":
        v.flags.writeable = False
    z, peaks = np.zeros(17), np.empty(3)
    z[2] = 0.25
    kernel.driven(z, 2, 2, 8, 0.5, v, 3.0, peaks)
    expected = [0.25]
    for value in values:
        expected.append(0.5 * expected[-1] + 3.0 * value)
    np.testing.assert_array_equal(z[2::2], expected)
    assert z[[0, 1, 3]].tolist() == [0.0, 0.0, 0.0]
    assert peaks[:2].tolist() == [max(map(abs, expected)), 2.0]
    one = np.array([4.0])
    kernel.driven(one, 0, 1, 1, 0.5, np.empty(0), 3.0, peaks)
    assert one.tolist() == [4.0] and peaks[0] == 4.0


_VALUES = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([np.nan, np.inf, -np.inf, 1e308]))


@pytest.mark.skipif(trial_module.c_compiler() is None, reason="no C compiler")
@settings(max_examples=300, deadline=None)
@given(kind=st.sampled_from(["real", "complex", "driven"]),
       t=st.sampled_from([0.0, 0.5, -0.9, 1.0, 3.0, 1e200]),
       values=st.lists(_VALUES, min_size=2, max_size=12), w=st.sampled_from([0.0, 1.0, 1e200]))
def test_the_kernel_s_peaks_bound_what_it_wrote_and_read_or_are_not_finite(kind, t, values, w):
    """A finite peak and check sum promise finite values within the peak, whatever NaN,
    infinity or overflow the recursion met (the screen's soundness rests on it)."""
    kernel = first_order_module.first_order_kernel(True)
    peaks = np.empty(3)
    n = len(values)
    with np.errstate(all="ignore"):
        if kind == "driven":
            z = np.zeros(n)
            z[0] = values[0]
            v = np.array(values[1:] + [0.0])
            kernel.driven(z, 0, 1, n, t, v, w, peaks)
            read, written = v[:n - 1], z
        elif kind == "real":
            z = np.array(values)
            kernel.solve(z, 0, 1, n, t, peaks)
            read, written = np.array(values[1:]), z
        else:
            z = np.array(values) + 1j * np.array(values[::-1])
            kernel.solve(z, 0, 1, n, complex(t, 0.5), peaks)
            read = np.concatenate([np.array(values[1:]), np.array(values[::-1][1:])])
            written = np.concatenate([z.real, z.imag])
    if np.isfinite(peaks[0]) and np.isfinite(peaks[2]):
        assert np.isfinite(written).all() and np.isfinite(read).all()
        magnitude = (np.abs(z.real) + np.abs(z.imag)) if kind == "complex" else np.abs(z)
        assert magnitude.max() <= peaks[0]
        if kind == "driven":
            assert np.abs(read).max(initial=0.0) <= peaks[1]


@pytest.mark.skipif(trial_module.c_compiler() is None, reason="no C compiler")
def test_the_kernel_is_built_once_and_kept_on_disk(fresh_kernel, tmp_path, monkeypatch):
    monkeypatch.setenv("ILC_CACHE_DIR", str(tmp_path))
    assert fresh_kernel.first_order_kernel() is not None
    assert list(tmp_path.glob("ilc_first_order_*.so"))
    fresh_kernel._loaded.cache_clear()          # as a new process: the library is loaded

    def no_compiler(*a, **k):
        raise AssertionError("the compiler ran although the library is on disk")

    monkeypatch.setattr(trial_module.subprocess, "run", no_compiler)
    assert fresh_kernel.first_order_kernel() is not None


def test_without_a_compiler_the_recursion_takes_blas_silently(fresh_kernel, monkeypatch):
    monkeypatch.setattr(fresh_kernel, "c_compiler", lambda: None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert fresh_kernel.first_order_kernel() is None
        recursion = ModalRecursion(np.array([[0.5]]), np.array([[1.0]]))
    assert recursion._kernel is None
    states, _ = recursion.run(np.array([1.0]), np.ones((3, 1)), False)
    _close(states[:, 0], [1.0, 1.5, 1.75])
    with pytest.raises(ParameterError, match="jit=True needs the compiled first-order kernel"):
        ModalRecursion(np.array([[0.5]]), jit=True)


def test_a_kernel_that_does_not_build_is_reported_once(fresh_kernel, tmp_path, monkeypatch):
    monkeypatch.setenv("ILC_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(fresh_kernel, "c_compiler", lambda: "/bin/false")
    with pytest.warns(ILCWarning, match="could not be built or loaded.*solved by BLAS"):
        assert fresh_kernel.first_order_kernel() is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert fresh_kernel.first_order_kernel() is None


@st.composite
def lti_trials(draw):
    n_x = draw(st.integers(1, 3))
    n_u = draw(st.integers(1, 2))
    n_y = draw(st.integers(1, 2))
    N = draw(st.integers(2, 25))
    shift = draw(st.integers(0, 3))     # 0: direct feedthrough (open loop only)
    finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
    A = draw(hnp.arrays(float, (n_x, n_x), elements=finite))
    # scaled to a 2-norm in [0.1, 1.05] (so |eig| <= 1.05 with bounded non-normality; scaling
    # by the spectral radius would blow a nilpotent draw up to entries of 1e12)
    A = A * (draw(st.floats(0.1, 1.05)) / max(np.linalg.norm(A, 2), 1e-300))
    B = draw(hnp.arrays(float, (n_x, n_u), elements=finite))
    C = draw(hnp.arrays(float, (n_y, n_x), elements=finite))
    K = N + shift
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    feedback = draw(st.sampled_from(["none", "constant"] if shift else ["none"]))
    gains = 0.3 * rng.standard_normal((2, n_u, n_y)) if feedback == "constant" \
        else np.zeros((2, n_u, n_y))
    psi2 = np.broadcast_to(gains[0], (N, n_u, n_y)).copy()
    phi2 = np.broadcast_to(0.01 * gains[1], (N, n_u, n_y)).copy()
    noise = 0.1 * draw(st.sampled_from([0.0, 1.0]))     # 0: no disturbances (u drives alone)
    args = dict(x0=rng.standard_normal(n_x), ff=rng.standard_normal((N, n_u)),
                y_d=rng.standard_normal((N, n_y)), psi2=psi2, phi2=phi2,
                w=noise * rng.standard_normal((K, n_x)),
                nu=noise * rng.standard_normal((K, n_y)), t=0.1 * np.arange(K))
    return _plant(A, B, C), N, shift, args


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lti_trials())
def test_linear_trial_equals_the_casadi_trial(case):
    dp, N, shift, args = case
    fast = LinearTrial(dp, N, shift).run(**args)
    ref = CompiledTrial(dp, N, shift, jit=False).run(**args)
    _records_agree(fast, ref)
    x_bound, u_bound = fast.bounds          # the bounds the screen may take (NaN: none)
    assert np.isnan(x_bound) or np.abs(fast.x).max() <= x_bound
    assert np.isnan(u_bound) or np.abs(fast.u).max() <= u_bound
    assert np.isnan(ref.bounds).all()


@pytest.mark.parametrize("A", [
    [[1.0, 0.1], [0.0, 1.0]],                      # double integrator: one defective mode
    [[0.9, -0.4], [0.4, 0.9]],                     # a complex pair
    [[1.0, 0.1, 0.0], [0.0, 1.0, 0.1], [0.0, 0.0, 1.0]],   # a Jordan block of size 3
], ids=["double_integrator", "complex_pair", "jordan3"])
@pytest.mark.parametrize("feedback", [False, True])
def test_linear_trial_on_defective_and_complex_modes(A, feedback):
    A = np.array(A)
    n = A.shape[0]
    dp = _plant(A, np.eye(n)[:, :1], np.eye(n)[:1])
    N, shift = 40, 1
    rng = np.random.default_rng(1)
    psi2 = np.full((N, 1, 1), 0.5 if feedback else 0.0)
    args = dict(x0=rng.standard_normal(n), ff=rng.standard_normal((N, 1)),
                y_d=rng.standard_normal((N, 1)), psi2=psi2, phi2=0.1 * psi2,
                w=np.zeros((N + shift, n)), nu=np.zeros((N + shift, 1)),
                t=0.1 * np.arange(N + shift))
    _records_agree(LinearTrial(dp, N, shift).run(**args),
                   CompiledTrial(dp, N, shift, jit=False).run(**args))


def test_the_linear_trial_keeps_no_finished_run_s_arrays_alive():
    # the trial remembers facts about a machine's read-only gains and disturbances (the same
    # arrays every trial), weakly: they are freed with the machine, not kept by the cached trial
    dp = _plant(np.array([[0.9]]), np.array([[1.0]]), np.array([[1.0]]))
    N, shift = 10, 1
    trial = LinearTrial(dp, N, shift)
    arrays = dict(psi2=np.zeros((N, 1, 1)), phi2=np.zeros((N, 1, 1)),
                  w=np.zeros((N + 1, 1)), nu=np.zeros((N + 1, 1)))
    for a in arrays.values():
        a.setflags(write=False)
    for _ in range(2):                  # the second trial uses what the first remembered
        trial.run(x0=np.zeros(1), ff=np.ones((N, 1)), y_d=np.ones((N, 1)),
                  t=0.1 * np.arange(N + 1), **arrays)
    refs = [weakref.ref(a) for a in arrays.values()]
    del arrays, a
    assert all(ref() is None for ref in refs)


def test_time_varying_feedback_takes_the_casadi_trial():
    dp = _plant(np.array([[0.9]]), np.array([[1.0]]), np.array([[1.0]]))
    N, shift = 10, 1
    psi2 = np.linspace(0.1, 0.5, N).reshape(N, 1, 1)
    args = dict(x0=np.zeros(1), ff=np.ones((N, 1)), y_d=np.ones((N, 1)), psi2=psi2,
                phi2=np.zeros_like(psi2), w=np.zeros((N + 1, 1)), nu=np.zeros((N + 1, 1)),
                t=0.1 * np.arange(N + 1))
    _records_agree(LinearTrial(dp, N, shift).run(**args),
                   CompiledTrial(dp, N, shift, jit=False).run(**args))


@pytest.mark.parametrize("N", [50, 3000])
def test_simulate_lti_equals_the_lfilter_learning_loop(N):
    ts = 1e-3
    y_d = np.sin(2 * np.pi * window_times(N, ts, 1))
    problem = ILCProblem(control.tf([1.0], [0.05, 1.0]), ts, N, y_d[:, None])
    result = simulate(problem, PDLaw.p_type([[0.5]]), 12)
    Ad, Bd, C, D = problem.dplant.matrices[:4]
    b, a = scipy.signal.ss2tf(Ad, Bd, C, D)
    u = np.zeros(N)
    for i in range(12):
        e = y_d - scipy.signal.lfilter(b[0], a, np.append(u, u[-1]))[1:]
        _close(result.dataset["e"].values[i, :, 0], e)
        _close(result.dataset["u"].values[i, :, 0], u)
        u = u + 0.5 * e
    _close(result.dataset["rms_e"].values[:, 0],
           np.sqrt(np.mean(result.dataset["e"].values[:, :, 0] ** 2, axis=1)))
    _close(result.dataset["e_norm"].values,
           np.linalg.norm(result.dataset["e"].values[:, :, 0], axis=1))


# -- the compiled nonlinear trial -------------------------------------------------------------
@pytest.fixture(scope="module")
def robot_plant():
    return discretize(balanced_mobile_robot(), 0.01)


def _robot_args(N):
    rng = np.random.default_rng(3)
    K = N + 1
    return dict(x0=np.zeros(7), ff=0.05 * rng.standard_normal((N, 2)),
                y_d=0.1 * rng.standard_normal((N, 3)),
                psi2=np.full((N, 2, 3), 0.005), phi2=np.full((N, 2, 3), 1e-5),
                w=0.01 * rng.standard_normal((K, 7)), nu=0.01 * rng.standard_normal((K, 3)),
                t=0.01 * np.arange(K))


@pytest.mark.skipif(trial_module.c_compiler() is None, reason="no C compiler")
def test_compiled_nonlinear_trial_equals_the_interpreted_one_and_is_kept_on_disk(
        robot_plant, tmp_path, monkeypatch):
    monkeypatch.setenv("ILC_CACHE_DIR", str(tmp_path))
    N = 30
    compiled = CompiledTrial(robot_plant, N, 1, jit=True)
    assert compiled.jit and list(tmp_path.glob("closed_loop_step_*.so"))
    args = _robot_args(N)
    _records_agree(compiled.run(**args), CompiledTrial(robot_plant, N, 1, jit=False).run(**args))
    # a second build (as in a new process, and for another N) loads the library: the compiler
    # is not run

    def no_compiler(*a, **k):
        raise AssertionError("the compiler ran although the library is on disk")

    monkeypatch.setattr(trial_module.subprocess, "run", no_compiler)
    again = CompiledTrial(robot_plant, N, 1)
    assert again.jit
    _records_agree(again.run(**args), compiled.run(**args))
    assert CompiledTrial(robot_plant, 2 * N, 1).jit
    assert again.operations_per_step > 100


def test_without_a_compiler_the_default_runs_interpreted_and_says_so_once(robot_plant,
                                                                          monkeypatch):
    monkeypatch.setattr(trial_module, "c_compiler", lambda: None)
    monkeypatch.setattr(trial_module, "_stated", set())
    with pytest.warns(ILCWarning, match="no C compiler found"):
        first = CompiledTrial(robot_plant, 10, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        second = CompiledTrial(robot_plant, 10, 1)
    assert not first.jit and not second.jit
    with pytest.raises(ParameterError, match="jit=True needs a C compiler"):
        CompiledTrial(robot_plant, 10, 1, jit=True)


def test_jit_must_be_a_bool_or_none(robot_plant):
    with pytest.raises(ParameterError, match="jit must be True, False or None"):
        CompiledTrial(robot_plant, 10, 1, jit="yes")


def test_simulate_with_feedback_on_an_lti_problem_equals_the_interpreted_trial():
    ts = 0.01
    N = 60
    problem = ILCProblem(control.tf([4.0], [1.0, 1.0, 4.0]), ts, N,
                         np.sin(np.pi * window_times(N, ts, 2))[:, None])
    gains = PDGains(Phi1=[[0.05]], Phi2=[[0.02]], Psi1=[[2.0]], Psi2=[[1.0]], lead=1)
    law = PDLaw(gains)
    fast = simulate(problem, law, 8)
    dp = problem.dplant
    ref = CompiledTrial(dp, N, problem.shift, jit=False)
    ff = problem.initial_input()
    psi2, phi2 = law.feedback_gains(N)
    K = N + problem.shift
    for i in range(8):
        rec = ref.run(problem.x0, ff, problem.reference, psi2, phi2, np.zeros((K, dp.n_x)),
                      np.zeros((K, dp.n_y)), problem.t0 + ts * np.arange(K))
        e = problem.reference - rec.y[problem.shift:]
        _close(fast.dataset["e"].values[i], e)
        _close(fast.dataset["u"].values[i], rec.u[:N])
        ff = law.between_trials(rec.u[:N], e, ts)[0]


@pytest.mark.skipif(trial_module.c_compiler() is None, reason="no C compiler")
def test_a_short_run_compiles_only_a_step_already_on_disk(robot_plant, tmp_path, monkeypatch):
    """A run of fewer than COMPILE_MIN_STEPS samples (a Monte Carlo point, a plant of its own)
    stays interpreted unless the step's library exists; a long run compiles it."""
    monkeypatch.setenv("ILC_CACHE_DIR", str(tmp_path))
    short = trial_module.COMPILE_MIN_STEPS // 31 - 1
    assert not trial_module.compiled_trial(robot_plant, 30, 1, steps=short).jit
    assert not list(tmp_path.glob("*.so"))
    assert trial_module.compiled_trial(robot_plant, 30, 1,
                                       steps=trial_module.COMPILE_MIN_STEPS).jit
    trial_module._cached_trial.cache_clear()
    assert trial_module.compiled_trial(robot_plant, 30, 1, steps=short).jit


# -- the run's arrays, its admissibility screen and its data set -------------------------------
@settings(max_examples=40, deadline=None)
@given(a=hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=3, min_side=1, max_side=6),
                    elements=st.floats(-1e6, 1e6) | st.just(np.nan)),
       ufunc=st.sampled_from([np.maximum, np.minimum]))
def test_narrow_reduce_equals_the_ufunc_reduce(a, ufunc):
    # maximum/minimum are exact (no rounding), and both propagate a NaN: equal as arrays
    for axis in range(a.ndim):
        np.testing.assert_array_equal(narrow_reduce(ufunc, a, axis), ufunc.reduce(a, axis=axis))



@pytest.mark.parametrize("shape", [(3, 4), (40, 20000)])   # np.zeros; a mapped block
def test_lazy_zeros_are_writable_zeros_of_their_own(shape):
    a, b = lazy_zeros(shape), lazy_zeros(shape)
    assert a.shape == shape and a.dtype == np.float64 and a.flags.c_contiguous
    assert a.flags.writeable and not np.any(a)
    a[-1, -1] = 2.0
    assert a[-1, -1] == 2.0 and not np.any(b)


def test_a_run_without_forgetting_has_zero_writable_factors():
    N = 20000                           # the factors' block is a mapped one (lazy_zeros)
    a = simulate(_lag_problem(N), PDLaw.p_type([[0.5]]), 7).dataset["a"].values
    assert a.shape == (7, N) and not np.any(a) and a.flags.writeable

def _lag_problem(N=40):
    ts = 1e-3
    y_d = np.sin(2 * np.pi * window_times(N, ts, 1))
    return ILCProblem(control.tf([1.0], [0.05, 1.0]), ts, N, y_d[:, None], name="lag")


def test_a_state_beyond_its_own_bound_is_caught_when_the_others_are_larger():
    # the screen's whole-array test (max |x| <= the smallest bound) fails, the per-state one
    # decides: a second state whose bound is wide and a first whose bound is crossed
    plant = control.ss(np.diag([-20.0, -1.0]), [[20.0], [0.0]], [[1.0, 0.0]], 0.0)
    N = 40
    x0 = np.array([0.0, 100.0])         # the second state far above 0.5, within its bound
    problem = ILCProblem(plant, 1e-3, N, np.ones((N, 1)), x0=x0)
    first = problem.dplant.state_names[0]
    bound = DivergenceBounds(max_abs_state=1e6, state_limits={first: 0.5})
    law = PDLaw.p_type([[0.5]])
    result = simulate(problem, law, 6, bounds=bound)
    # the reference: the same run without the bound, its first trial with |x_0| > 0.5
    free = simulate(problem, law, 6).dataset["x"].values[:, :, 0]
    over = np.flatnonzero(np.abs(free).max(axis=1) > 0.5)
    assert over.size and over[0] > 0       # trial 1 is admissible, a later one is not
    assert result.diverged and result.divergence.iteration == over[0] + 1
    assert result.iterations == over[0]
    assert result.divergence.state == first
    assert "exceeds its bound 0.5" in result.divergence.reason


def test_runs_of_one_layout_have_their_own_arrays_and_attributes():
    problem = _lag_problem()
    first = simulate(problem, PDLaw.p_type([[0.5]]), 3).dataset
    first.attrs["note"] = "mine"
    first["e"].attrs["note"] = "mine"
    e_first = first["e"].values.copy()
    second = simulate(problem, PDLaw.p_type([[0.2]]), 3).dataset
    assert "note" not in second.attrs and "note" not in second["e"].attrs
    assert second.attrs["law_parameters"] != first.attrs["law_parameters"]
    np.testing.assert_array_equal(first["e"].values, e_first)    # not overwritten
    assert not np.array_equal(second["e"].values[1:], e_first[1:])
    assert second["e"].attrs["long_name"] == "tracking error y_d - y"
    assert list(second["iteration"].values) == [1, 2, 3]


# -- the update written into the run's row, long products by scalars ---------------------------
@settings(max_examples=40, deadline=None)
@given(data=st.data(), n_u=st.integers(1, 3), n_y=st.integers(1, 3), lead=st.integers(0, 3),
       d_part=st.booleans(), varying=st.booleans())
def test_the_open_loop_term_written_into_a_row_equals_the_new_array(data, n_u, n_y, lead,
                                                                     d_part, varying):
    N = data.draw(st.integers(lead + 1, 30))
    gain = hnp.arrays(np.float64, (N, n_u, n_y) if varying else (n_u, n_y),
                      elements=st.floats(-10, 10))
    psi1 = data.draw(gain)
    phi1 = data.draw(gain) if d_part else np.zeros_like(psi1)
    zeros = np.zeros_like(psi1)
    gains = PDGains(Phi1=phi1, Phi2=zeros, Psi1=psi1, Psi2=zeros, lead=lead)
    e = data.draw(hnp.arrays(np.float64, (N, n_y), elements=st.floats(-1e3, 1e3)))
    row = np.full((N, n_u), np.nan)
    written = previous_trial_term(gains, e, 0.01, out=row)
    assert written is row
    np.testing.assert_array_equal(row, previous_trial_term(gains, e, 0.01))


@pytest.mark.parametrize("forgetting", [FixedForgetting(0.0), FixedForgetting(0.1),
                                        VariableForgetting(delta=0.5, Lambda=2.0)])
@pytest.mark.parametrize("q_filter", [None, QFilter.butterworth(20.0)])
def test_the_engine_form_of_a_pd_update_is_between_trials(forgetting, q_filter):
    rng = np.random.default_rng(3)
    N, ts = 60, 1e-3
    gains = PDGains(Phi1=[[0.001, 0.0]], Phi2=[[0.0, 0.0]], Psi1=[[0.5, -0.2]],
                    Psi2=[[0.0, 0.0]], lead=2)
    law = PDLaw(gains, forgetting, q_filter=q_filter, u0=[0.3])
    u, e = rng.standard_normal((N, 1)), rng.standard_normal((N, 2))
    f_public, a_public = law.between_trials(u, e, ts)
    row = np.full((N, 1), np.nan)
    f, a = law._next_feedforward(u, e, ts, row)
    np.testing.assert_array_equal(f, f_public)
    # written into the row where the law can (no Q-filter); the factor None without forgetting
    assert (f is row) == (q_filter is None)
    if forgetting == FixedForgetting(0.0):
        assert a is None and not np.any(a_public)
    else:
        np.testing.assert_array_equal(a, a_public)


@settings(max_examples=60, deadline=None)
@given(X=hnp.arrays(np.float64, st.tuples(st.integers(1, 50), st.integers(1, 10)),
                    elements=st.floats(-1e3, 1e3)),
       q=st.integers(1, 3), data=st.data(), complex_M=st.booleans())
def test_long_matmul_equals_matmul(X, q, data, complex_M):
    M = data.draw(hnp.arrays(np.float64, (X.shape[1], q), elements=st.floats(-1e3, 1e3)))
    if complex_M:
        M = M + 1j * M[::-1]
    out = long_matmul(X, M)
    assert out.dtype == (X @ M).dtype
    np.testing.assert_allclose(out, X @ M, rtol=1e-12, atol=1e-9)


def test_a_user_law_returning_the_wrong_shape_is_refused_by_the_run():
    class Half(LearningLaw):
        name = "half"

        def update(self, u_i, e_i, ts):
            return np.zeros((u_i.shape[0] // 2, u_i.shape[1]))

        def check(self, lifted_system):
            return None

        def lifted(self, lifted_system):
            raise NotImplementedError

        def describe(self):
            return {"law": "half"}

    with pytest.raises(ShapeError, match=r"half: the learning update returned shape \(20, 1\)"):
        simulate(_lag_problem(), Half(), 3)


# -- the run's block from the pool of maps ------------------------------------------------------
N_BIG = (1 << 20) // 8 + 5               # above the pool's threshold


def test_a_block_no_array_uses_is_reused_and_a_kept_one_is_not():
    first = recycled_empty(N_BIG)
    address = first.ctypes.data
    assert first.shape == (N_BIG,) and first.dtype == np.float64 and first.flags.writeable
    first[:] = 1.0
    del first                            # no view left: its map goes back to the pool
    second = recycled_empty(N_BIG - 3)   # fits: the same pages
    assert second.ctypes.data == address and second.size == N_BIG - 3
    kept = second                        # a result the user keeps
    third = recycled_empty(N_BIG)
    assert third.ctypes.data != kept.ctypes.data
    third[:] = 2.0
    assert not np.shares_memory(kept, third) and np.all(kept[:10] == 1.0)


def test_a_view_keeps_its_block_out_of_the_pool():
    block = recycled_empty(N_BIG)
    view = block.reshape(-1)[7:].reshape(-1)
    view[:] = 3.0
    del block
    other = recycled_empty(N_BIG)
    other[:] = 4.0
    assert np.all(view == 3.0)
    assert not np.shares_memory(view, other)


def test_the_pool_keeps_no_map_above_its_total():
    huge = recycled_empty((arrays_module._RECYCLE_KEEP_BYTES >> 3) + 1)
    huge_map = huge.base.obj if isinstance(huge.base, memoryview) else None
    del huge
    assert all(m is not huge_map for m in arrays_module._free_maps)


def test_a_map_much_larger_than_asked_is_not_handed_out_and_small_arrays_are_plain():
    big = recycled_empty(4 * N_BIG)
    address = big.ctypes.data
    del big
    assert recycled_empty(N_BIG).ctypes.data != address    # at most twice the size asked
    small = recycled_empty(100)
    assert small.base is None and small.shape == (100,)


def test_the_run_store_reuses_the_last_runs_block():
    problem = _lag_problem(N=3000)       # 40 x (4 x 3001 + 3000) values: from the pool
    law = PDLaw.p_type([[0.5]])
    first = simulate(problem, law, 40)
    e_first = first.dataset["e"].values.copy()
    address = first.dataset["e"].values.ctypes.data
    del first
    gc.collect()                         # whatever cycles the data set is in: gone
    second = simulate(problem, law, 40)
    assert second.dataset["e"].values.ctypes.data == address
    np.testing.assert_array_equal(second.dataset["e"].values, e_first)
    kept = simulate(problem, law, 40)    # the second run is kept: a map of its own
    assert not np.shares_memory(kept.dataset["e"].values, second.dataset["e"].values)


# -- one array for input and feed-forward; the trial's screen ----------------------------------
def test_without_feedback_the_input_and_the_feed_forward_are_one_array():
    problem = _lag_problem()
    ds = simulate(problem, PDLaw.p_type([[0.5]]), 4).dataset
    assert np.shares_memory(ds["u"].values, ds["u_ff"].values)
    np.testing.assert_array_equal(ds["u"].values, ds["u_ff"].values)
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.5]], Psi2=[[2.0]])
    fed_back = simulate(problem, PDLaw(gains), 4).dataset
    assert not np.shares_memory(fed_back["u"].values, fed_back["u_ff"].values)
    gap = np.abs(fed_back["u"].values - fed_back["u_ff"].values).max(axis=(1, 2))
    assert np.all(gap > 1e-6)           # the feedback acts in every trial
    np.testing.assert_array_equal(fed_back["max_abs_e"].values,
                                  np.abs(fed_back["e"].values).max(axis=1))


_SPECIALS = st.sampled_from([np.nan, np.inf, -np.inf, 3.0, -3.0])   # 3: beyond x's bound 2


@settings(max_examples=300, deadline=None)
@given(data=st.data(), shift=st.integers(0, 3), N=st.integers(2, 12), n_y=st.integers(1, 3),
       signals=st.integers(0, 1), hits=st.integers(0, 3),
       bounds=st.sampled_from(["none", "x", "u", "both"]))
def test_the_screen_passes_no_trial_the_exact_check_refuses(data, shift, N, n_y, signals,
                                                             hits, bounds):
    K = N + shift
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    rec = TrialRecord(x=rng.uniform(-1, 1, (K, 2)), u=rng.uniform(-1, 1, (K, 2)),
                      y=rng.uniform(-1, 1, (K, n_y)), e=np.zeros((K, n_y)),
                      signals=rng.uniform(-1, 1, (K, signals)))
    for _ in range(hits):               # a non-finite value or a state beyond its bound
        name = data.draw(st.sampled_from(["x", "u", "y"] + ["signals"] * signals))
        target = getattr(rec, name)
        k, j = data.draw(st.integers(0, K - 1)), data.draw(st.integers(0, target.shape[1] - 1))
        target[k, j] = data.draw(_SPECIALS)
    # the bounds a trial may hand the screen: what it computed (finite only for finite values)
    for j, (name, wanted) in enumerate((("x", bounds in ("x", "both")),
                                        ("u", bounds in ("u", "both")))):
        values = getattr(rec, name)
        if wanted and np.isfinite(values).all():
            rec.bounds[j] = np.abs(values).max() * data.draw(st.sampled_from([1.0, 1.5]))
    y_d = rng.uniform(-1, 1, (N, n_y))
    window = slice(shift, K)
    with np.errstate(invalid="ignore", over="ignore"):
        rec.e[window] = y_d - rec.y[window]      # as every trial computes it
    limits = np.array([2.0, 2.0])
    e_max, e_min = np.empty(n_y), np.empty(n_y)
    passed = engine_module._admissible(rec, window, e_max, e_min, limits, 2.0)
    names = SimpleNamespace(state_names=("x[0]", "x[1]"), input_names=("u[0]", "u[1]"),
                            output_names=tuple(f"y[{j}]" for j in range(n_y)))
    exact = engine_module._check_trial(rec, limits, names, 1, np.arange(K, dtype=float))
    if passed:
        assert exact is None
    admissible = (np.isfinite(rec.u).all() and np.isfinite(rec.y).all()
                  and np.isfinite(rec.signals).all() and np.isfinite(rec.x).all()
                  and np.abs(rec.x).max() <= 2.0)
    assert (exact is None) == admissible
    if admissible:                      # the extremes the data set keeps as max_abs_e
        assert passed
        np.testing.assert_array_equal(e_max, rec.e[window].max(axis=0))
        np.testing.assert_array_equal(e_min, rec.e[window].min(axis=0))
