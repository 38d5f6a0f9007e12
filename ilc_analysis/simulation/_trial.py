r"""One trial of the closed loop as one compiled CasADi function.

Per sample k the compiled step does, with the current-trial (feedback) part of the law inside
the trial and the feed-forward :math:`f(k)` computed between trials:

.. math::

    y(k) &= h(x(k), t_k) + \nu(k) \\
    e(k) &= m(k)\,\big(y_d(k - s) - y(k)\big),\qquad m(k) = 1 \text{ iff } s \le k \le N-1+s \\
    u(k) &= f(k) + \Psi_2(k)\,e(k) + \Phi_2(k)\,\frac{e(k) - e(k-1)}{T_s},
            \qquad e(-1) = 0 \\
    x(k+1) &= F(x(k), u(k), \omega(k), t_k)

which is the current-trial term of :mod:`ilc_analysis.laws`'s convention (error measured at k,
zero before the window). The step is repeated with ``mapaccum`` over the whole trial, so no
Python code runs per sample.

By default (``jit=None``) a plant given as an expression graph (every plant but one stepped
by an adaptive integrator, which C code generation cannot take) has its trial compiled to C
where a C compiler is found (``$CC``, else ``cc`` or ``gcc`` on the path): CasADi generates
the closed-loop step's C source, the compiler builds a shared library, and the library is kept
on disk under the hash of its source, compiler and flags (:func:`compiled_cache_dir`), so a
second run, in this process or a new one, with any N, loads it without compiling; the
``mapaccum`` over the trial calls the compiled step sample by sample. A run too short to
repay the compilation (:data:`COMPILE_MIN_STEPS`; e.g. each point of a Monte Carlo study, a
plant of its own) compiles only if the library is already there. Without a compiler the trial
runs in CasADi's virtual machine (interpreted), and an
:class:`~ilc_analysis.exceptions.ILCWarning` says so once per process. ``jit=True`` requires
the compiler, ``jit=False`` never uses it.

The lifted output window is :math:`y(s), \dots, y(N-1+s)`, so the map runs over
:math:`K = N + s` samples; for :math:`k \ge N` (after the last lifted input) the zero-order
hold keeps :math:`u(k) = u(N-1)`. Those inputs cannot reach the window's outputs, because the
first :math:`s-1` Markov parameters vanish (definition of the shift).
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from .._validation import MAX_TRIAL_SAMPLES, positive_int
from ..exceptions import ILCWarning, ParameterError
from ..model import DiscretePlant

__all__ = ["CompiledTrial", "TrialRecord", "compiled_trial", "new_record", "window_times",
           "compiled_cache_dir", "c_compiler", "COMPILE_MIN_STEPS", "build_shared_library",
           "shared_library_path"]

#: flags of the trial's C build (no -ffast-math: the compiled trial computes what the
#: interpreted one does, to rounding)
COMPILE_FLAGS = ("-O2", "-shared", "-fPIC")

#: the environment variable naming the directory of compiled trials
CACHE_ENV = "ILC_CACHE_DIR"


def c_compiler() -> str | None:
    """The C compiler the trials are built with: ``$CC`` if set (and found), else ``cc`` or
    ``gcc`` on the path; None if there is none."""
    for name in (os.environ.get("CC"), "cc", "gcc"):
        if name:
            found = shutil.which(name)
            if found:
                return found
    return None


def compiled_cache_dir() -> Path:
    """Where compiled trials are kept: ``$ILC_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/ilc-analysis/trials`` (``~/.cache/ilc-analysis/trials``)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "ilc-analysis" / "trials"


_stated: set[str] = set()


def _state_once(message: str) -> None:
    """Warn ``message`` once per process (:class:`ILCWarning`)."""
    if message not in _stated:
        _stated.add(message)
        warnings.warn(message, ILCWarning, stacklevel=4)


#: below this many samples in a run (trials x samples per trial) the default compiles a step
#: only if its library is already on disk: gcc -O2 takes about 0.3 ms of CPU per operation of
#: the step and CasADi's virtual machine runs about 1e8 operations per CPU second (the robot's
#: 1 258-operation step on the development machine: 0.4 s to compile, 0.93 s for 80 040
#: interpreted steps), so compiling pays for itself after about 30 000 steps whatever the step
COMPILE_MIN_STEPS = 30_000


def shared_library_path(name: str, source: str, compiler: str,
                        flags: tuple[str, ...] = COMPILE_FLAGS) -> Path:
    """Where the shared library of the C ``source`` is kept: :func:`compiled_cache_dir`,
    named by ``name`` and the hash of the source, the compiler, the flags and CasADi's
    version."""
    key = hashlib.sha256("\0".join([source, compiler, *flags,
                                     ca.CasadiMeta.version()]).encode()).hexdigest()[:24]
    return compiled_cache_dir() / f"{name}_{key}.so"


def _step_source(fn: ca.Function) -> str:
    """The C source CasADi generates for ``fn``."""
    gen = ca.CodeGenerator(fn.name(), {"with_header": False})
    gen.add(fn)
    return gen.dump()


def build_shared_library(name: str, source: str, compiler: str,
                         flags: tuple[str, ...] = COMPILE_FLAGS) -> Path:
    """The shared library of the C ``source``, built once by ``compiler`` with ``flags`` and
    kept at :func:`shared_library_path` (a second call, in this process or a new one, finds
    it on disk).

    Raises
    ------
    ParameterError
        If the compiler fails (its exit status and the end of its messages).
    """
    library = shared_library_path(name, source, compiler, flags)
    if not library.is_file():
        library.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=library.parent, prefix=".build-") as tmp:
            c_file = Path(tmp) / f"{name}.c"
            c_file.write_text(source)
            built = Path(tmp) / library.name
            proc = subprocess.run([compiler, *flags, "-o", str(built), str(c_file), "-lm"],
                                  capture_output=True, text=True, check=False)
            if proc.returncode != 0:
                raise ParameterError(f"compiling {name} with {compiler} failed (exit "
                                     f"{proc.returncode}): {proc.stderr.strip()[-500:]}")
            os.replace(built, library)      # atomic: a concurrent build writes the same file
    return library


def _compile_cached(fn: ca.Function, compiler: str) -> ca.Function:
    """``fn`` as a compiled C library, built once and kept in :func:`compiled_cache_dir`
    (module docstring)."""
    try:
        library = build_shared_library(fn.name(), _step_source(fn), compiler)
    except ParameterError as exc:
        raise ParameterError(f"{exc}; pass jit=False to run the trial interpreted") from None
    return ca.external(fn.name(), str(library))


@dataclass(frozen=True)
class TrialRecord:
    """Everything one trial produced, on the trial samples k = 0..N+s-1."""

    x: np.ndarray
    """state x(k), (K, n_x)"""
    u: np.ndarray
    """applied input u(k), (K, n_u) (held after k = N-1)"""
    y: np.ndarray
    """measured output y(k) = h(x(k)) + ν(k), (K, n_y)"""
    e: np.ndarray
    """error the feedback saw, (K, n_y) (zero outside the window)"""
    signals: np.ndarray
    """the plant's extra signals, (K, n_signals)"""
    bounds: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    """(2,): an upper bound on every :math:`|x_j(k)|` and one on every :math:`|u_j(k)|` that
    the trial found while computing them (a linear trial's compiled kernel), NaN where it has
    none; a finite bound promises finite values. The engine's screen reads the arrays
    themselves where a bound is NaN."""


def new_record(K: int, dplant: DiscretePlant) -> TrialRecord:
    """A record of uninitialised arrays for ``K`` samples of a trial of ``dplant`` (the
    buffers a run writes its trials into).

    Parameters
    ----------
    K : int
        Trial samples (N + s).
    dplant : DiscretePlant
        The plant (its numbers of states, inputs, outputs and signals).
    """
    n_y = dplant.n_y
    return TrialRecord(x=np.empty((K, dplant.n_x)), u=np.empty((K, dplant.n_u)),
                       y=np.empty((K, n_y)), e=np.empty((K, n_y)),
                       signals=np.empty((K, len(dplant.signal_names))))


def window_times(N: int, ts: float, shift: int, t0: float = 0.0) -> np.ndarray:
    r"""The sample times of the lifted output window, :math:`t_0 + (j+s)T_s`, j = 0..N-1.

    Evaluate the reference ``y_d`` at these times.

    Parameters
    ----------
    N : int
        Number of samples of the lifted window.
    ts : float
        Sample time [s].
    shift : int
        Shift s of the lifted output (sampled relative degree): the window starts at sample s.
    t0 : float, optional
        Time of the trial's first sample k = 0 [s] (default 0).

    Returns
    -------
    ndarray, shape (N,)
    """
    return t0 + ts * (np.arange(N) + shift)


class CompiledTrial:
    """The closed-loop trial of ``dplant`` over N lifted samples with shift s, compiled once.

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant whose step, output and signals functions are compiled.
    N : int
        Lifted trial length (number of input samples).
    shift : int
        Sampled relative degree s >= 0 (s = 0: direct feedthrough, the window starts at the
        trial's first sample; the output is then measured with the feed-forward of the same
        sample, so a current-trial feedback, which would form an algebraic loop, is refused
        by :class:`~ilc_analysis.simulation.SimulatedMachine`).
    jit : bool or None, optional
        Compile the trial to C (module docstring): None (default) where a C compiler is found,
        True always (an error without a compiler), False never (CasADi's virtual machine).
    short : bool, optional
        The run is short (fewer than :data:`COMPILE_MIN_STEPS` samples in all): with
        ``jit=None`` the step is compiled only if its library is already on disk.

    Attributes
    ----------
    jit : bool
        Whether the trial runs compiled.
    step : casadi.Function
        The closed-loop step the trial repeats.

    Notes
    -----
    :meth:`run` evaluates on buffers owned by the object, so one instance must not run two
    trials concurrently (threads); :func:`compiled_trial` shares instances.
    """

    def __init__(self, dplant: DiscretePlant, N: int, shift: int, *, jit: bool | None = None,
                 short: bool = False):
        if not isinstance(dplant, DiscretePlant):
            raise ParameterError(f"dplant must be a DiscretePlant; got {type(dplant).__name__}")
        N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
        shift = positive_int(shift, "shift", minimum=0)
        self.dplant, self.N, self.shift = dplant, N, shift
        # an expression graph compiles; a step with an adaptive integrator (cvodes) cannot be
        # generated as C, so the default leaves it interpreted
        graph = all(f.is_a("SXFunction") for f in (dplant.step, dplant.output, dplant.signals))
        self.jit = resolve_jit(jit) if jit is not None or graph else False
        self._short = bool(short) and jit is None
        self.K = N + shift
        n_x, n_u, n_y = dplant.n_x, dplant.n_u, dplant.n_y
        self._layout = {}
        offset = 0
        for key, size in (("ff", n_u), ("yd", n_y), ("mask", 1), ("active", 1), ("w", n_x),
                          ("nu", n_y), ("t", 1), ("psi", n_u * n_y), ("phi", n_u * n_y)):
            self._layout[key] = slice(offset, offset + size)
            offset += size
        self._n_par = offset
        self.function = self._build()
        # Evaluate on preallocated numpy buffers (no DM conversion): casadi reads the
        # parameters column-major, i.e. a C-ordered (K, n_par) array; same for the output.
        self._P = np.zeros((self.K, self._n_par))
        self._carry0 = np.zeros(n_x + n_y + n_u)
        self._out = np.zeros((self.K, self.function.size1_out(0)))
        self._buffer, self._evaluate = self.function.buffer()
        # ``.data``: the arrays' memoryviews. CasADi's stub asks for a size argument that its
        # SWIG wrapper takes from the buffer itself (calls with it fail at runtime).
        self._buffer.set_arg(0, self._carry0.data)  # type: ignore[call-arg]
        self._buffer.set_arg(1, self._P.reshape(-1).data)  # type: ignore[call-arg]
        self._buffer.set_res(0, self._out.reshape(-1).data)  # type: ignore[call-arg]

    def _build(self) -> ca.Function:
        dp = self.dplant
        n_x, n_u, n_y = dp.n_x, dp.n_u, dp.n_y
        sx = all(f.is_a("SXFunction") for f in (dp.step, dp.output, dp.signals))
        # SX or MX: the step is built the same way in either (CasADi's stubs type the two
        # apart, so the checker sees them as Any)
        sym: Any = ca.SX.sym if sx else ca.MX.sym
        carry = sym("carry", n_x + n_y + n_u)
        par = sym("par", self._n_par)
        x, e_prev, u_prev = carry[:n_x], carry[n_x:n_x + n_y], carry[n_x + n_y:]
        L = self._layout
        ff, yd, mask, active = par[L["ff"]], par[L["yd"]], par[L["mask"]], par[L["active"]]
        w, nu, t = par[L["w"]], par[L["nu"]], par[L["t"]]
        Psi2 = ca.reshape(par[L["psi"]], n_u, n_y)
        Phi2 = ca.reshape(par[L["phi"]], n_u, n_y)
        y = dp.output(x, ff, t) + nu
        e = mask * (yd - y)
        de = (e - e_prev) / dp.ts
        u = active * (ff + ca.mtimes(Psi2, e) + ca.mtimes(Phi2, de)) + (1 - active) * u_prev
        x_next = dp.step(x, u, w, t)
        sig = dp.signals(x, u, t)
        step = ca.Function("closed_loop_step", [carry, par],
                           [ca.vertcat(x_next, e, u), ca.vertcat(x, u, y, e, sig)])
        self.step = step
        if self.jit and self._short:    # a short run: compile only if the library exists
            compiler = c_compiler()
            self.jit = (compiler is not None
                            and shared_library_path(step.name(), _step_source(step),
                                                    compiler).is_file())
        if self.jit:        # the step compiled (one library per plant, whatever N)
            compiler = c_compiler()
            if compiler is None:
                raise ParameterError("jit=True needs a C compiler ($CC, cc or gcc on the "
                                     "path); none was found: pass jit=None (compile where "
                                     "possible) or jit=False")
            step = _compile_cached(step, compiler)
        trial = step.mapaccum("trial_map", self.K)
        c0 = ca.MX.sym("carry0", carry.numel())
        P = ca.MX.sym("P", self._n_par, self.K)
        _, out = trial(c0, P)
        return ca.Function("ilc_trial", [c0, P], [out], ["carry0", "P"], ["out"])

    @property
    def operations_per_step(self) -> int | None:
        """Elementary operations of one compiled step (``+``, ``*``, ``sin``, ..., each one;
        inputs, outputs and constants not counted); None for a step that is not a plain
        expression graph (e.g. an adaptive integrator)."""
        if not self.step.is_a("SXFunction"):
            return None
        skip = {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_PARAMETER}
        return sum(self.step.instruction_id(k) not in skip
                   for k in range(self.step.n_instructions()))

    def run(self, x0, ff, y_d, psi2, phi2, w, nu, t,
            out: TrialRecord | None = None) -> TrialRecord:
        r"""Run one trial.

        Parameters
        ----------
        x0 : ndarray, shape (n_x,)
            Initial state x(0) (reset error included).
        ff : ndarray, shape (N, n_u)
            Feed-forward f(k) of this trial; held at f(N-1) for k >= N.
        y_d : ndarray, shape (N, n_y)
            Reference on the lifted window, :math:`y_d(j)` for the output sample j + s.
        psi2, phi2 : ndarray, shape (N, n_u, n_y)
            Current-trial gains :math:`\Psi_2(k)`, :math:`\Phi_2(k)`.
        w : ndarray, shape (K, n_x)
            State disturbance ω(k), K = N + s.
        nu : ndarray, shape (K, n_y)
            Output disturbance ν(k) added to the measured output.
        t : ndarray, shape (K,)
            Sample times t_k [s].
        out : TrialRecord, optional
            The arrays to write the record into (:func:`new_record`); default new arrays.

        Returns
        -------
        TrialRecord
            State, applied input, measured output, error and signals over the K samples
            (``out`` when given).
        """
        N, s = self.N, self.shift
        dp = self.dplant
        self._P.fill(0.0)
        P = self._P.T  # (n_par, K) view of the bound buffer
        L = self._layout
        P[L["ff"], :N] = ff.T
        P[L["ff"], N:] = ff[-1][:, None]
        P[L["yd"], s:] = y_d.T
        P[L["mask"], s:] = 1.0
        P[L["active"], :N] = 1.0
        P[L["w"]] = w.T
        P[L["nu"]] = nu.T
        P[L["t"]] = t
        # casadi reshape is column-major: flatten each (n_u, n_y) gain in Fortran order
        P[L["psi"], :N] = psi2.transpose(0, 2, 1).reshape(N, -1).T
        P[L["phi"], :N] = phi2.transpose(0, 2, 1).reshape(N, -1).T
        self._carry0[:] = 0.0
        self._carry0[:dp.n_x] = x0
        self._evaluate()
        if self._buffer.ret() != 0:  # pragma: no cover - casadi reports evaluation failures
            raise RuntimeError(f"the compiled trial failed (casadi return code "
                               f"{self._buffer.ret()})")
        n_x, n_u, n_y = dp.n_x, dp.n_u, dp.n_y
        cuts = np.cumsum([n_x, n_u, n_y, n_y])
        if out is None:
            x, u, y, e, sig = np.split(self._out.copy(), cuts, axis=1)   # (K, rows)
            return TrialRecord(x=x, u=u, y=y, e=e, signals=sig)
        for target, part in zip((out.x, out.u, out.y, out.e, out.signals),
                                np.split(self._out, cuts, axis=1), strict=True):
            target[...] = part
        out.bounds[:] = np.nan              # no bounds from this trial
        return out


def resolve_jit(jit: bool | None) -> bool:
    """Whether a trial is compiled: ``jit`` if it is a bool, else (None) whether a C compiler
    is found (without one: an :class:`ILCWarning`, once per process)."""
    if jit is not None:
        if not isinstance(jit, bool | np.bool_):
            raise ParameterError(f"jit must be True, False or None (compile where a C compiler "
                                 f"is found); got {jit!r}")
        return bool(jit)
    if c_compiler() is None:
        _state_once("no C compiler found ($CC, cc or gcc): nonlinear trials run interpreted "
                    "in CasADi's virtual machine (install a C compiler for compiled trials, "
                    "or pass jit=False to choose this)")
        return False
    return True


def compiled_trial(dplant: DiscretePlant, N: int, shift: int,
                   jit: bool | None = None, steps: int | None = None) -> CompiledTrial:
    """A cached :class:`CompiledTrial` (building and compiling happens once per plant, N, s;
    the compiled library also on disk, module docstring).

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant (hashable: the cache key includes it).
    N : int
        Lifted trial length (number of input samples).
    shift : int
        Sampled relative degree s >= 0.
    jit : bool or None, optional
        Compile the trial to C: None (default) where a C compiler is found, True always,
        False never.
    steps : int, optional
        Samples the caller will run in all (trials x samples); with ``jit=None`` a run of fewer
        than :data:`COMPILE_MIN_STEPS` compiles the step only if its library is on disk
        (compiling would cost more than it saves).

    Returns
    -------
    CompiledTrial
        Shared between callers with the same arguments: do not run it from two threads at once.
    """
    graph = all(f.is_a("SXFunction") for f in (dplant.step, dplant.output, dplant.signals))
    short = jit is None and steps is not None and steps < COMPILE_MIN_STEPS
    return _cached_trial(dplant, N, shift, resolve_jit(jit) if jit is not None or graph
                         else False, short)


@functools.lru_cache(maxsize=8)
def _cached_trial(dplant: DiscretePlant, N: int, shift: int, jit: bool,
                  short: bool) -> CompiledTrial:
    return CompiledTrial(dplant, N, shift, jit=None if short and jit else jit, short=short)
