r"""Where learning acts: at the plant input, or at the reference or the input of a servo loop.

Three places, each a small frozen object handed to :class:`~ilc_analysis.problem.ILCProblem`
as ``learning_at``:

* :class:`PlantInput` -- the learned signal v is the plant input, :math:`u = v`;
* :class:`LoopReference` -- a feedback loop with an LTI controller C is closed around the plant
  and learning adjusts the loop's reference (v has one channel per plant output),

  .. math::

      u = C_c x_c + D_c (v - y), \qquad x_c^+ = A_c x_c + B_c (v - y)
      \quad(\dot x_c \text{ in continuous time});

* :class:`LoopInput` -- the same loop tracks the reference :math:`y_d` and learning adds a
  feed-forward at the plant input (v has one channel per plant input),

  .. math::

      u = C_c x_c + D_c (y_d - y) + v, \qquad x_c^+ = A_c x_c + B_c (y_d - y).

The controller is a python-control LTI system (``TransferFunction`` or ``StateSpace``),
continuous, or discrete with the problem's sample time; it must be proper and take every plant
output (inputs = n_y, outputs = n_u). :func:`pid` builds the usual filtered PID.

**Reference timing.** The reference is given on the output window, :math:`y_d(j)` at the time
:math:`t_0 + (s + j)T_s` of :math:`y(s + j)`, while the loop runs at the input samples k. The
loop's reference at sample k, :math:`r(k)` (the first trial's learned signal of
:class:`LoopReference`, the reference the controller compares with y in :class:`LoopInput`), is
taken as ``reference_timing`` says (:meth:`LoopReference.loop_reference`):

.. math::

    \texttt{"ahead"}:\ r(k) = y_d(k),\qquad
    \texttt{"same-sample"}:\ r(k) = y_d\big(\max(k - s, 0)\big),\qquad k = 0, \dots, N-1.

``"ahead"`` (the default) hands the loop at sample k the output wanted s samples later, when
what enters at k first shows in y; ``"same-sample"`` hands it the output wanted at the same
time, :math:`y_k = G_r (r + a_k)` sample by sample, the convention of IterativeLearningControl.jl
and of most textbooks. Before the window (k < s) the output wanted is not in y_d: it is held at
:math:`y_d(0)`, or given, ``reference_start`` :math:`= [r(0), \dots, r(s-1)]` (the reference at
the trial's start, as ``lsim(feedback(P*C), r)`` feeds r(0) at sample 0). With s = 0 the
timings coincide (docs/theory.md §13).
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import control
import numpy as np

from .._validation import (
    MAX_FILTER_ORDER,
    as_finite_array,
    check_limit,
    positive,
    positive_int,
    real,
)
from ..exceptions import ParameterError, ShapeError

__all__ = ["PlantInput", "LoopReference", "LoopInput", "pid", "LEARNING_AT_KINDS",
           "REFERENCE_TIMINGS", "controller_matrices", "controller_description",
           "controller_from_description"]

#: When the loop's reference at input sample k is taken from y_d (module docstring).
REFERENCE_TIMINGS = ("ahead", "same-sample")


def pid(kp, ki=0.0, kd=0.0, tf=None) -> control.TransferFunction:
    r"""The filtered PID controller

    .. math::

        C(s) = k_p + \frac{k_i}{s} + \frac{k_d\, s}{t_f\, s + 1},

    a proper python-control ``TransferFunction`` (SISO; for several channels build one per
    channel, e.g. with ``control.append``, or give a ``StateSpace``).

    Parameters
    ----------
    kp, ki, kd : float
        Proportional, integral and derivative gains (finite reals; any sign).
    tf : float, optional
        Time constant of the derivative filter [s], > 0. Required when ``kd != 0``: a pure
        derivative :math:`k_d s` is improper and cannot be realised in state space.

    Returns
    -------
    control.TransferFunction
        Continuous time; static gain ``kp`` when ``ki = kd = 0``.

    Raises
    ------
    ParameterError
        A gain not a finite real number; ``kd != 0`` without ``tf > 0``.

    Examples
    --------
    >>> C = pid(2.0, 1.0, 0.1, tf=0.01)
    >>> [float(c) for c in C.den[0][0]]
    [0.01, 1.0, 0.0]
    """
    kp, ki, kd = real(kp, "kp"), real(ki, "ki"), real(kd, "kd")
    s = control.tf("s")
    C = control.tf([kp], [1.0])
    if ki != 0.0:
        C = C + ki / s
    if kd != 0.0:
        if tf is None:
            raise ParameterError(
                "tf (derivative filter time constant) must be a positive number when kd != 0: "
                "kd*s alone is improper; use pid(kp, ki, kd, tf) with tf > 0, "
                "C(s) = kp + ki/s + kd*s/(tf*s + 1)")
        tf = positive(tf, "tf (derivative filter time constant)")
        C = C + control.tf([kd, 0.0], [tf, 1.0])
    elif tf is not None:
        positive(tf, "tf (derivative filter time constant)")
    return control.tf(C.num, C.den, name="pid")


def _degree(poly) -> int:
    coeffs = np.trim_zeros(np.atleast_1d(np.asarray(poly, dtype=float)), "f")
    return len(coeffs) - 1


def _check_proper(tf: control.TransferFunction) -> None:
    for i in range(tf.noutputs):
        for j in range(tf.ninputs):
            dn, dd = _degree(tf.num[i][j]), _degree(tf.den[i][j])
            if dn > dd:
                raise ParameterError(
                    f"controller is improper: channel ({i}, {j}) has numerator degree {dn} > "
                    f"denominator degree {dd}, so it has no state-space realisation; a PID "
                    "needs a derivative filter: pid(kp, ki, kd, tf) with tf > 0")


def controller_matrices(controller, name: str = "controller"):
    """``(A, B, C, D, dt)`` of a proper LTI controller, as finite float arrays.

    ``dt`` is 0.0 for continuous time (also for a static gain without a sample time) and the
    sample time for discrete time. The controller may have no state (a static gain).

    Parameters
    ----------
    controller : control.TransferFunction or control.StateSpace
        A proper LTI controller (continuous or discrete time).
    name : str, optional
        How error messages name it.

    Raises
    ------
    ParameterError
        Not a python-control LTI system; improper; discrete with unspecified sample time
        (``dt=True``); NaN/inf or complex entries.
    """
    if not isinstance(controller, control.TransferFunction | control.StateSpace):
        raise ParameterError(
            f"{name} must be a python-control TransferFunction or StateSpace (e.g. "
            f"pid(kp, ki, kd, tf) or control.ss(A, B, C, D)); got {type(controller).__name__}")
    if controller.dt is True:
        raise ParameterError(f"{name} is discrete-time with an unspecified sample time "
                             "(dt=True); give dt equal to the problem's ts")
    if isinstance(controller, control.TransferFunction):
        _check_proper(controller)
        try:
            controller = control.ss(controller)
        except ValueError as exc:   # pragma: no cover - _check_proper refuses these first
            raise ParameterError(f"{name} has no state-space realisation: {exc}") from exc
    n, m, p = controller.nstates, controller.ninputs, controller.noutputs
    if m == 0 or p == 0:
        raise ShapeError(f"{name} must have at least one input and one output; found "
                         f"{m} inputs and {p} outputs")
    A = as_finite_array(np.asarray(controller.A).reshape(n, n), f"{name}.A", shape=(n, n))
    B = as_finite_array(np.asarray(controller.B).reshape(n, m), f"{name}.B", shape=(n, m))
    C = as_finite_array(np.asarray(controller.C).reshape(p, n), f"{name}.C", shape=(p, n))
    D = as_finite_array(np.asarray(controller.D).reshape(p, m), f"{name}.D", shape=(p, m))
    dt = 0.0 if controller.dt in (None, 0) else positive(controller.dt, f"{name}.dt")
    return A, B, C, D, dt


def controller_description(controller) -> dict:
    """A TOML-safe description of an LTI controller: ``{"tf": {num, den, dt}}`` for a SISO
    transfer function, ``{"ss": {A, B, C, D, dt}}`` otherwise (``dt = 0`` is continuous).

    Parameters
    ----------
    controller : control.TransferFunction or control.StateSpace
        A proper LTI controller (continuous or discrete time).
    """
    if isinstance(controller, control.TransferFunction) and controller.ninputs == 1 \
            and controller.noutputs == 1:
        dt = 0.0 if controller.dt in (None, 0) else float(controller.dt)
        return {"tf": {"num": [float(c) for c in np.atleast_1d(controller.num[0][0])],
                       "den": [float(c) for c in np.atleast_1d(controller.den[0][0])],
                       "dt": dt}}
    A, B, C, D, dt = controller_matrices(controller)
    return {"ss": {"A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "D": D.tolist(),
                   "dt": dt}}


def _keys(d, allowed, required, where) -> dict:
    if not isinstance(d, dict):
        raise ParameterError(f"{where} must be a table (dict); found {type(d).__name__}")
    unknown = sorted(set(d) - set(allowed))
    if unknown:
        raise ParameterError(f"{where} has unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    missing = [k for k in required if k not in d]
    if missing:
        raise ParameterError(f"{where} is missing key(s) {missing}")
    return d


def _dt(value, where) -> float | None:
    dt = real(value, f"{where}.dt")
    if dt < 0:
        raise ParameterError(f"{where}.dt must be 0 (continuous) or a sample time > 0; "
                             f"got {value!r}")
    return None if dt == 0 else dt


def controller_from_description(d, where: str = "controller"):
    """The inverse of :func:`controller_description`; also accepts
    ``{"pid": {kp, ki, kd, tf}}``.

    Parameters
    ----------
    d : dict
        ``{"tf": ...}``, ``{"ss": ...}`` or ``{"pid": ...}``.
    where : str, optional
        The key path error messages name.

    Raises
    ------
    ParameterError
        Unknown or missing keys (named with ``where``), non-finite entries, improper controller.
    ShapeError
        Matrices of inconsistent shapes.
    """
    _keys(d, ("tf", "ss", "pid"), (), where)
    if len(d) != 1:
        raise ParameterError(f"{where} must have exactly one of the keys 'pid', 'tf', 'ss'; "
                             f"found {sorted(d)}")
    kind, spec = next(iter(d.items()))
    sub = f"{where}.{kind}"
    if kind == "pid":
        _keys(spec, ("kp", "ki", "kd", "tf"), ("kp",), sub)
        try:
            return pid(spec["kp"], spec.get("ki", 0.0), spec.get("kd", 0.0), spec.get("tf"))
        except ParameterError as exc:       # pid() names its arguments; add the key path
            raise ParameterError(f"{sub}: {exc}") from exc
    if kind == "tf":
        _keys(spec, ("num", "den", "dt"), ("num", "den"), sub)
        for key in ("num", "den"):       # degree + 1 coefficients, counted before converting
            if isinstance(spec[key], list | tuple):
                check_limit(len(spec[key]), MAX_FILTER_ORDER + 1, f"{sub}.{key}",
                            "coefficients (degree + 1, MAX_FILTER_ORDER + 1)")
        num = as_finite_array(spec["num"], f"{sub}.num", ndim=1)
        den = as_finite_array(spec["den"], f"{sub}.den", ndim=1)
        if num.size == 0 or den.size == 0 or not np.any(den != 0):
            raise ParameterError(f"{sub}: num and den must be non-empty coefficient lists "
                                 "(highest power first) with a nonzero denominator")
        dt = _dt(spec.get("dt", 0.0), sub)
        C = control.tf(num, den) if dt is None else control.tf(num, den, dt)
        try:
            _check_proper(C)
        except ParameterError as exc:
            raise ParameterError(f"{sub}: {exc}") from exc
        return C
    _keys(spec, ("A", "B", "C", "D", "dt"), ("D",), sub)
    D = as_finite_array(spec["D"], f"{sub}.D", ndim=2)
    p, m = D.shape
    if isinstance(spec.get("A"), list | tuple):
        check_limit(len(spec["A"]), MAX_FILTER_ORDER, f"{sub}.A",
                    "rows (controller states; MAX_FILTER_ORDER)")
    if "A" in spec and np.size(spec["A"]) > 0:
        A = as_finite_array(spec["A"], f"{sub}.A", ndim=2)
        n = A.shape[0]
        A = as_finite_array(A, f"{sub}.A", shape=(n, n))
        B = as_finite_array(spec.get("B"), f"{sub}.B", shape=(n, m))
        C = as_finite_array(spec.get("C"), f"{sub}.C", shape=(p, n))
    else:
        A, B, C = np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0))
    dt = _dt(spec.get("dt", 0.0), sub)
    return control.ss(A, B, C, D) if dt is None else control.ss(A, B, C, D, dt)


@dataclass(frozen=True)
class PlantInput:
    """Learning acts at the plant input: the learned signal is u itself (n_u channels)."""

    kind = "plant-input"

    def describe(self) -> dict:
        return {"kind": self.kind}

    def __repr__(self) -> str:
        return "PlantInput()"


@dataclass(frozen=True, eq=False)
class _Loop:
    controller: object
    reference_timing: str = "ahead"
    reference_start: Any = None     # array_like; a read-only ndarray after __post_init__
    kind: ClassVar[str]             # set by each subclass
    if TYPE_CHECKING:               # not a field: set in __post_init__
        _matrices: tuple = field(init=False)    # (Ac, Bc, Cc, Dc, dt)

    def __post_init__(self):
        if not isinstance(self.reference_timing, str) \
                or self.reference_timing not in REFERENCE_TIMINGS:
            raise ParameterError(f"reference_timing must be one of {REFERENCE_TIMINGS}; got "
                                 f"{self.reference_timing!r:.80}")
        if self.reference_start is not None:
            if self.reference_timing != "same-sample":
                raise ParameterError("reference_start (the loop's reference before the output "
                                     "window) applies to reference_timing='same-sample'; with "
                                     "'ahead' the loop's reference is y_d itself")
            start = as_finite_array(self.reference_start, "reference_start", ndim=2)
            start.setflags(write=False)
            object.__setattr__(self, "reference_start", start)
        A, B, C, D, dt = controller_matrices(self.controller, "controller")
        object.__setattr__(self, "_matrices", (A, B, C, D, dt))

    def loop_reference(self, y_d, shift: int) -> np.ndarray:
        r"""The loop's reference :math:`r(k)`, k = 0..N-1, from :math:`y_d` on the output window
        y(s..N-1+s), as :attr:`reference_timing` says:

        .. math::

            \texttt{"ahead"}:\ r(k) = y_d(k),\qquad
            \texttt{"same-sample"}:\ r(k) = y_d(k - s)\ (k \ge s),

        and before the window (k < s) the given ``reference_start`` row k, else
        :math:`y_d(0)`.

        Parameters
        ----------
        y_d : array_like, shape (N, n_y)
            The reference on the output window.
        shift : int
            The output-window shift s >= 0.

        Returns
        -------
        ndarray, shape (N, n_y)
            A new array.

        Raises
        ------
        ShapeError
            ``reference_start`` is not ``(shift, n_y)``.
        """
        y_d = as_finite_array(y_d, "y_d", ndim=2)
        shift = positive_int(shift, "shift", minimum=0)
        start = self.reference_start
        if start is not None and start.shape != (min(shift, y_d.shape[0]), y_d.shape[1]):
            raise ShapeError(f"reference_start must hold the loop's reference at the "
                             f"{shift} sample(s) before the output window, one row each: "
                             f"shape ({shift}, {y_d.shape[1]}); found shape {start.shape}")
        if self.reference_timing == "ahead" or shift == 0:
            return np.array(y_d)
        k = np.arange(y_d.shape[0])
        r = y_d[np.maximum(k - shift, 0)]
        if start is not None:
            r[:start.shape[0]] = start
        return r

    @property
    def matrices(self):
        """``(Ac, Bc, Cc, Dc, dt)`` of the controller (dt = 0.0: continuous)."""
        return self._matrices

    @property
    def is_discrete(self) -> bool:
        return self._matrices[4] > 0

    def check(self, n_u: int, n_y: int, ts: float) -> None:
        """The controller fits a plant with ``n_u`` inputs, ``n_y`` outputs, sampled at ``ts``.

        Parameters
        ----------
        n_u, n_y : int
            Number of plant inputs and outputs.
        ts : float
            The problem's sample time [s].

        Raises
        ------
        ShapeError
            Controller inputs != n_y or outputs != n_u.
        ParameterError
            Discrete controller whose sample time differs from ``ts``.
        """
        A, B, C, D, dt = self._matrices
        if B.shape[1] != n_y or C.shape[0] != n_u:
            raise ShapeError(
                f"controller must take all {n_y} plant output(s) and drive all {n_u} plant "
                f"input(s): expected {n_y} input(s) and {n_u} output(s); found "
                f"{B.shape[1]} input(s) and {C.shape[0]} output(s)")
        if dt > 0 and not math.isclose(dt, ts, rel_tol=1e-9, abs_tol=0.0):
            raise ParameterError(
                f"controller is discrete with dt = {dt!r} s, which differs from the problem's "
                f"ts = {ts!r} s; a discrete controller must run at the problem's sample time "
                "(or give it in continuous time)")

    def describe(self) -> dict:
        """``{kind, controller}``, and ``reference_timing`` when it is not ``'ahead'``,
        ``reference_start`` when given."""
        d = {"kind": self.kind, "controller": controller_description(self.controller)}
        if self.reference_timing != "ahead":
            d["reference_timing"] = self.reference_timing
        if self.reference_start is not None:
            d["reference_start"] = self.reference_start.tolist()
        return d

    def __repr__(self) -> str:
        A, B, C, D, dt = self._matrices
        time = "continuous" if dt == 0 else f"discrete, dt={dt:g}"
        timing = "" if self.reference_timing == "ahead" else \
            f", reference {self.reference_timing}" + (
                "" if self.reference_start is None else
                f" from r(0) = {np.array2string(self.reference_start[0], precision=4)}")
        return (f"{type(self).__name__}(controller: {time}, {A.shape[0]} states, "
                f"{B.shape[1]} in, {C.shape[0]} out{timing})")

    def _repr_html_(self) -> str:
        return html.escape(repr(self))


@dataclass(frozen=True, eq=False, repr=False)
class LoopReference(_Loop):
    r"""Learning adjusts the reference v of a feedback loop closed around the plant.

    .. math::

        u = C_c x_c + D_c (v - y),\qquad \dot x_c\ (\text{or } x_c^+) = A_c x_c + B_c (v - y).

    The learned signal has n_y channels; the first trial runs the plain servo loop, v = r
    (:meth:`loop_reference`: :math:`r = y_d` with ``reference_timing="ahead"``, y_d delayed by
    the shift with ``"same-sample"``, where :math:`v_k = r + a_k` and :math:`y_k = G_r(r + a_k)`
    sample by sample).

    Parameters
    ----------
    controller : control.TransferFunction or control.StateSpace
        Proper, n_y inputs, n_u outputs; continuous, or discrete with dt = ts.
    reference_timing : {'ahead', 'same-sample'}, optional
        Which sample of y_d the loop's reference carries at input sample k (module docstring;
        default ``'ahead'``: :math:`r(k) = y_d(k)`, the output wanted at sample k + s).
    reference_start : array_like, shape (s, n_y), optional
        With ``'same-sample'``: the loop's reference :math:`r(0), \dots, r(s-1)` at the samples
        before the output window (``lsim(feedback(P*C), r)`` feeds r(0) at sample 0); default
        :math:`y_d(0)` held.
    """

    kind = "loop-reference"


@dataclass(frozen=True, eq=False, repr=False)
class LoopInput(_Loop):
    r"""The loop tracks y_d; learning adds a feed-forward v at the plant input.

    .. math::

        u = C_c x_c + D_c (r - y) + v,\qquad
        \dot x_c\ (\text{or } x_c^+) = A_c x_c + B_c (r - y),

    with the loop's reference r of :meth:`loop_reference` (:math:`r = y_d` with
    ``reference_timing="ahead"``, y_d delayed by the shift with ``"same-sample"``). The
    learned signal has n_u channels (default nominal zero). The reference enters the
    composite as a known state disturbance (``ILCProblem.w``) when the plant is LTI, and is
    built into the composite's (time-varying) step otherwise.

    Parameters
    ----------
    controller : control.TransferFunction or control.StateSpace
        Proper, n_y inputs, n_u outputs; continuous, or discrete with dt = ts.
    reference_timing : {'ahead', 'same-sample'}, optional
        Which sample of y_d the controller sees at input sample k (module docstring; default
        ``'ahead'``: :math:`r(k) = y_d(k)`, the output wanted at sample k + s).
    reference_start : array_like, shape (s, n_y), optional
        With ``'same-sample'``: the reference the controller sees at the samples before the
        output window, :math:`r(0), \dots, r(s-1)`; default :math:`y_d(0)` held.
    """

    kind = "loop-input"


#: ``learning_at`` kinds by the name used in descriptions.
LEARNING_AT_KINDS = {"plant-input": PlantInput, "loop-reference": LoopReference,
                     "loop-input": LoopInput}
