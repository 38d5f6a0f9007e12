r"""Per-trial learning on a real machine: a learner whose state survives between processes.

A machine that already runs trials (and logs them) is driven, trial by trial, from its logs::

    learner = Learner(problem, law)
    write_input_csv("input_1.csv", learner.first_input(), problem.input_names)
    learner.save_state("state.json")
    # ... the machine runs trial 1 and logs its outputs to trial_1.csv ...
    learner = Learner.load_state("state.json", problem, law)        # e.g. a new process
    y = read_trial_csv("trial_1.csv", problem.output_names, rows=learner.record_length)
    u_next = learner.update(y)                                      # input of the next run
    write_input_csv("input_2.csv", u_next, problem.input_names)
    learner.save_state("state.json")

What the learner takes and gives (index convention of :mod:`ilc_analysis.laws`):

* **input** (:meth:`first_input`, :meth:`update`'s result, :attr:`next_input`):
  ``(N, n_u)``, the learned signal :math:`v(k)` at times :math:`t_0 + kT_s`, k = 0..N-1, held
  after the last sample. For a law with a current-trial part (:class:`~ilc_analysis.laws.PDLaw`
  with :math:`\Psi_2, \Phi_2 \ne 0`) it is the **feed-forward** :math:`f_{i+1}`: the machine's
  own loop must apply, during the trial,
  :math:`v(k) = f_{i+1}(k) + \Psi_2(k)\,e(k) + \Phi_2(k)\,(e(k) - e(k-1))/T_s` with
  :math:`e(k) = y_d(k-s) - y(k)` for :math:`k \ge s` and zero before
  (:attr:`current_trial_feedback`, :attr:`output_is_feedforward`);
* **measurement** (:meth:`update`): the **full record** of the run, ``(N + s, n_y)``: the
  output :math:`y(k)` at times :math:`t_0 + kT_s`, k = 0..N+s-1 (:attr:`record_length` rows,
  the same clock as the input, starting with the first input sample). The learner cuts the
  output window :math:`y(s..N-1+s)` (where the reference applies) itself; a record of any other
  length (e.g. only the window, N rows) is refused with a :class:`ShapeError`, so a log is never
  silently misaligned by the shift s.

Laws with extra experiments per iteration (:class:`~ilc_analysis.laws.TimeReversalLaw`): after a
trial, :meth:`update` returns the input of the first extra experiment (run it open loop, log it
the same way), and so on; after the last one it returns the next trial's input.
:attr:`iteration` and :attr:`experiment` say which run the pending input is for.

The state file (:meth:`save_state`, :meth:`load_state`) is JSON (floats written exactly: the
round trip is bit-exact) with a format name, a version (:data:`STATE_VERSION`) and a fingerprint
of the problem and the law (:func:`design_fingerprint`): a state saved for another design is
refused. Driven this way, the learner reproduces :func:`~ilc_analysis.simulation.simulate` on
the same runs (tested to 1e-12 through CSV files).
"""

from __future__ import annotations

import csv
import functools
import hashlib
import io
import json
import math
from pathlib import Path

import numpy as np

from .._output import check_input_file, output_file
from .._validation import LARGEST_SAMPLE, as_finite_array
from .._validation import shown as shown_value
from ..exceptions import InternalError, ParameterError, ShapeError
from ..lifting import LiftedSystem
from ..problem._trial_spec import is_trial_spec
from ._law_adapter import _plain, as_trial, problem_law

__all__ = ["Learner", "read_trial_csv", "write_input_csv", "design_fingerprint",
           "STATE_FORMAT", "STATE_VERSION"]

#: Format name written into every learner state file.
STATE_FORMAT = "ilc-analysis learner state"
#: Version of the state file layout; other versions are refused.
STATE_VERSION = 1


# ---------------------------------------------------------------------------------------------
# fingerprint
# ---------------------------------------------------------------------------------------------
def _array_digest(arr) -> str:
    a = np.ascontiguousarray(np.asarray(arr, dtype=float))
    return hashlib.sha256(repr(a.shape).encode() + a.tobytes()).hexdigest()


def design_fingerprint(problem, law) -> str:
    """SHA-256 of what the learner's state depends on: the problem (``describe()``, sampled
    system, initial input, known disturbance) and the law (kind, ``describe()``, and the digests
    of its array attributes: a lifted model's G and d, weights, gains). A state saved under one
    fingerprint is refused by a learner with another.

    For a model-free :class:`~ilc_analysis.problem.TrialSpec` the problem part is its
    ``describe()`` (frame, reference, channel names) and its dimensions.

    Parameters
    ----------
    problem : ILCProblem or TrialSpec
        The problem the learner runs on.
    law : LearningLaw
        The learning law (its ``describe()`` and its array attributes are hashed).

    Returns
    -------
    str
        The hexadecimal SHA-256 digest (64 characters).

    Raises
    ------
    ParameterError
        If ``problem`` is neither an :class:`~ilc_analysis.problem.ILCProblem` nor a
        :class:`~ilc_analysis.problem.TrialSpec`.
    """
    problem = as_trial(problem)
    parts: dict = {"problem": _plain(problem.describe())}
    if is_trial_spec(problem):
        parts["dims"] = [problem.N, problem.n_u, problem.n_y, problem.shift]
    else:
        parts.update({
            "dplant": problem.dplant.name,
            "dims": [problem.N, problem.n_u, problem.n_y, problem.n_x, problem.shift],
            "initial_input": _array_digest(problem.initial_input()),
            "w": None if problem.w is None else _array_digest(problem.w)})
    parts.update({"law_type": f"{type(law).__module__}.{type(law).__qualname__}",
                  "law": _plain(law.describe())})
    # arrays a description may summarise (a lifted model's G and d, gains, weights, x0, ...)
    arrays: dict[str, str | list[str]] = {}
    for key, value in sorted(getattr(law, "__dict__", {}).items()):
        if isinstance(value, LiftedSystem):
            arrays[key] = [_array_digest(value.G), _array_digest(value.d)]
        elif isinstance(value, np.ndarray):
            arrays[key] = _array_digest(value)
    parts["law_arrays"] = arrays
    text = json.dumps(parts, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


# ---------------------------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------------------------
def _names(names, what: str) -> list[str]:
    if isinstance(names, str) or not hasattr(names, "__iter__"):
        raise ParameterError(f"{what} must be a sequence of channel names; got {names!r}")
    out = list(names)
    if not out or not all(isinstance(n, str) and n.strip() == n and n for n in out):
        raise ParameterError(f"{what} must be non-empty strings without surrounding blanks; "
                             f"got {out!r}")
    if len(set(out)) != len(out):
        raise ParameterError(f"{what} must be distinct; got {out!r}")
    return out


def write_input_csv(path, u, names, *, option: str = "path"):
    """Write an input ``(N, n_u)`` as CSV: a header of channel names, one row per sample.

    Values are written exactly (shortest round-trip representation), so reading the file back
    gives the same floats. The file is written atomically (a temporary file renamed into place).

    Parameters
    ----------
    path : str or path-like
        The file to write (replaced if it exists).
    u : array_like, shape (N, n_u)
        Finite, of magnitude at most about 1.34e154 (what :func:`read_trial_csv` accepts).
    names : sequence of str
        One distinct name per column (``problem.input_names``).
    option : str
        Name of the path in error messages (e.g. ``'--out'``).

    Returns
    -------
    pathlib.Path
    """
    names = _names(names, "names (input channel names)")
    u = as_finite_array(u, "u (input, (N, n_u))", shape=(None, len(names)))
    if u.size and np.abs(u).max() > LARGEST_SAMPLE:      # read_trial_csv would refuse it
        raise ParameterError(f"u (input, (N, n_u)) must be at most {LARGEST_SAMPLE:.3g} in "
                             f"magnitude (a trial file's bound: its square must not overflow "
                             f"float64); found {shown_value(float(np.abs(u).max()))}")
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for row in u:
        writer.writerow([repr(float(v)) for v in row])
    with output_file(path, option, replaces=functools.partial(_other_csv, names)) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8")
    return Path(path).resolve()


def _other_csv(names: list[str], path: Path) -> str | None:
    """None if the file at ``path`` is an input file this function would write (its header
    is ``names``), else what it is: a measured record, or any other file, is not replaced."""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            first = f.readline(65536)
    except OSError:
        return "a file that cannot be read"
    header = next(csv.reader([first]), [])
    if [h.strip() for h in header] == list(names):
        return None
    return (f"not an input file of the channels {names} (its first line is "
            f"{first.strip()[:60]!r}; a measured record, or another file)")


def read_trial_csv(path, names, *, rows: int | None = None, option: str = "path") -> np.ndarray:
    """Read a logged trial: a CSV file with a header of channel names, one row per sample.

    The header must hold each of ``names`` exactly once and nothing else (in any order); the
    result's columns follow ``names``. Every value must be a finite number whose square is a
    finite float64 (magnitude at most about 1.34e154). Blank lines at the
    end, a UTF-8 byte-order mark and Windows line ends are accepted.

    Parameters
    ----------
    path : str or path-like
        The CSV file to read.
    names : sequence of str
        The expected channels (``problem.output_names`` for a measured record).
    rows : int, optional
        Expected number of samples (for a learner: :attr:`Learner.record_length`).
    option : str
        Name of the path in error messages (e.g. ``'--measured'``).

    Returns
    -------
    ndarray, shape (rows, len(names))

    Raises
    ------
    ParameterError
        Unreadable file, bad header, a value that is not a finite number — naming the file, the
        row (data row from 1, and its line) and the column.
    ShapeError
        A row with the wrong number of fields, or a wrong number of rows.
    """
    names = _names(names, "names (channel names)")
    p = check_input_file(path, option)
    shown = str(path)
    try:
        text = p.read_text(encoding="utf-8-sig")     # a byte-order mark (spreadsheets) is dropped
    except UnicodeDecodeError as exc:
        raise ParameterError(f"{option} {shown!r} is not UTF-8 text (byte {exc.start})") from exc
    except OSError as exc:
        raise ParameterError(f"{option} {shown!r} cannot be read: {exc.strerror}") from exc
    # Parsed line by line into a preallocated array (at most one row per line): a list of
    # every record's strings would take about 70 times the file's size (1.1 GB for a 16 MiB
    # file of short rows), so memory stays a small multiple of the text whatever its shape.
    reader = csv.reader(io.StringIO(text, newline=""))
    header = None
    out = np.empty((text.count("\n") + 1, len(names)))
    r = 0                                                # data rows read
    blank = []                                           # lines of blank rows not yet followed
    try:
        for record in reader:
            line = reader.line_num
            if not any(field.strip() for field in record):
                blank.append(line)
                continue
            if header is None:
                if blank:
                    raise ParameterError(f"{option} {shown!r}, line {blank[0]}: a blank line "
                                         f"before the header; expected the header {names} "
                                         f"on line 1")
                header = _trial_header(record, names, option, shown)
                order = [header.index(n) for n in names]
                continue
            if blank:
                raise ShapeError(f"{option} {shown!r}, line {blank[0]}: a blank line between "
                                 f"samples; expected one row of {len(header)} numbers per "
                                 f"sample (blank lines only at the end)")
            r += 1
            if len(record) != len(header):
                raise ShapeError(f"{option} {shown!r}, row {r} (line {line}): {len(record)} "
                                 f"field(s); the header has {len(header)}")
            for c, j in enumerate(order):
                out[r - 1, c] = _trial_value(record[j], option, shown, r, line, names[c])
    except csv.Error as exc:
        raise ParameterError(f"{option} {shown!r}, line {reader.line_num}: not valid CSV "
                             f"({exc}); expected a header {names} and one row of numbers per "
                             f"sample") from exc
    if header is None:
        raise ParameterError(f"{option} {shown!r} is empty; expected a header {names} and one "
                             f"row per sample")
    out = out[:r]
    if rows is not None and out.shape[0] != rows:
        raise ShapeError(f"{option} {shown!r} has {out.shape[0]} row(s) of samples; expected "
                         f"{rows}")
    if out.shape[0] == 0:
        raise ShapeError(f"{option} {shown!r} has a header but no samples")
    return out


def _trial_header(record: list[str], names: list[str], option: str, shown: str) -> list[str]:
    """The stripped header of a trial file, checked against ``names`` (each once, no other)."""
    header = [h.strip() for h in record]
    missing = [n for n in names if n not in header]
    unknown = [h for h in header if h not in names]
    duplicate = sorted({h for h in header if header.count(h) > 1})
    if missing or unknown or duplicate:
        what = "; ".join(x for x in (
            f"missing {missing}" if missing else "",
            f"unknown {unknown}" if unknown else "",
            f"repeated {duplicate}" if duplicate else "") if x)
        raise ParameterError(f"{option} {shown!r}, row 0 (line 1, the header): expected the "
                             f"columns {names} (any order); found {header}: {what}")
    return header


def _trial_value(field: str, option: str, shown: str, row: int, line: int, column: str) -> float:
    """One sample of a trial file: a finite number of magnitude at most ``LARGEST_SAMPLE``
    (about 1.34e154, the FRF reader's bound: its square must not overflow float64, since the
    regressions, norms and energies computed from a record square every sample)."""
    raw = field.strip()
    try:
        value = float(raw)
    except ValueError:
        value = None
    if value is None or not math.isfinite(value):
        raise ParameterError(f"{option} {shown!r}, row {row} (line {line}), column "
                             f"{column!r}: {raw!r} is not a finite number")
    if abs(value) > LARGEST_SAMPLE:
        raise ParameterError(f"{option} {shown!r}, row {row} (line {line}), column "
                             f"{column!r}: {raw!r} is larger in magnitude than "
                             f"{LARGEST_SAMPLE:.3g} (the square root of the largest float64; "
                             f"its square would overflow); expected a number in physical units")
    return value


# ---------------------------------------------------------------------------------------------
# the learner
# ---------------------------------------------------------------------------------------------
class Learner:
    r"""A learning law on an ILC problem, one run at a time (module docstring).

    Parameters
    ----------
    problem : ILCProblem or TrialSpec
        Any shift; at shift 0 (direct feedthrough) only a law without a current-trial term.
        A :class:`~ilc_analysis.problem.TrialSpec` (a machine
        with no plant model) takes a law that needs no model (e.g. a QLLaw designed from FRF
        data).
    law : LearningLaw
        Set up for ``problem`` (model-based laws on ``problem.lifted``).

    Attributes
    ----------
    problem, law
        As given (``problem`` validated).
    record_length : int
        Rows of a measured record: N + s.
    """

    def __init__(self, problem, law) -> None:
        problem = as_trial(problem)
        self.problem = problem
        self.law = law
        self._adapter = problem_law(law, problem)
        N, n_u, n_y = problem.N, problem.n_u, problem.n_y
        psi2, phi2 = self._adapter.feedback_gains(N, n_u, n_y)
        self._psi2, self._phi2 = np.asarray(psi2, float), np.asarray(phi2, float)
        if problem.shift < 1 and (np.any(self._psi2) or np.any(self._phi2)):
            raise ParameterError(f"problem {problem.name!r} has shift 0 (direct feedthrough) "
                                 f"and the law a current-trial term (Psi2, Phi2): e(k) fed into "
                                 f"u(k) would form an algebraic loop; such a law needs a "
                                 f"strictly proper problem (shift >= 1)")
        self.record_length = N + problem.shift
        self._fingerprint = design_fingerprint(problem, law)
        self._next = self.first_input()
        self._iteration = 1
        self._experiment = 0
        self._pending: dict | None = None   # trial's u, e and the extra outputs so far
        self._last_error: np.ndarray | None = None

    # facts -------------------------------------------------------------------------------------
    @property
    def fingerprint(self) -> str:
        """:func:`design_fingerprint` of the problem and law."""
        return self._fingerprint

    @property
    def iteration(self) -> int:
        """The iteration (trial number, from 1) the pending run belongs to; ``iteration - 1``
        trials have been learned from."""
        return self._iteration

    @property
    def experiment(self) -> int:
        """0 when the pending run is the trial; k >= 1 for the k-th extra experiment (open loop)
        of :attr:`iteration`."""
        return self._experiment

    @property
    def experiments_per_iteration(self) -> int:
        """Plant runs per iteration (1 + the law's extra experiments)."""
        return self._adapter.experiments_per_iteration

    @property
    def next_input(self) -> np.ndarray:
        """The input of the pending run, ``(N, n_u)`` (a copy)."""
        return self._next.copy()

    @property
    def last_error(self) -> np.ndarray | None:
        """The error :math:`e = y_d - y` on the window of the last measured trial, or None."""
        return None if self._last_error is None else self._last_error.copy()

    @property
    def current_trial_feedback(self) -> tuple[np.ndarray, np.ndarray] | None:
        r"""``(Psi2, Phi2)`` ``(N, n_u, n_y)`` the machine's loop must apply during a trial, or
        None for a law without a current-trial part."""
        if not (np.any(self._psi2) or np.any(self._phi2)):
            return None
        return self._psi2.copy(), self._phi2.copy()

    @property
    def output_is_feedforward(self) -> bool:
        """True when the inputs the learner gives are feed-forwards to which the machine's loop
        adds the current-trial feedback (:attr:`current_trial_feedback`)."""
        return self.current_trial_feedback is not None

    def first_input(self) -> np.ndarray:
        """The input of trial 1, ``problem.initial_input()`` ``(N, n_u)`` (a feed-forward when
        :attr:`output_is_feedforward`); does not change the state."""
        return np.array(self.problem.initial_input(), dtype=float)

    def describe(self) -> str:
        """One paragraph: what the pending input is and how the machine must use it."""
        p = self.problem
        run = ("the trial" if self._experiment == 0 else
               f"extra experiment {self._experiment} of {self.experiments_per_iteration - 1} "
               f"(open loop, no feedback)")
        text = (f"{self.law.name} on {p.name!r}: pending run is {run} of iteration "
                f"{self._iteration}; input {p.N} x {p.n_u} ({', '.join(p.input_names)}) at "
                f"t0 + k ts; measure {self.record_length} x {p.n_y} "
                f"({', '.join(p.output_names)}) at t0 + k ts, k = 0..{self.record_length - 1}.")
        if self.output_is_feedforward and self._experiment == 0:
            text += (" The input is the feed-forward: the machine's loop adds Psi2 e(k) + Phi2 "
                     "(e(k) - e(k-1))/ts with e(k) = y_d(k-s) - y(k) (zero for k < s).")
        return text

    # learning ---------------------------------------------------------------------------------
    def _applied_input(self, ff: np.ndarray, e: np.ndarray) -> np.ndarray:
        r"""The input the trial applied: ``ff`` plus the current-trial feedback on the error
        :math:`e(k-s)` (zero before the window), k = 0..N-1."""
        if self.current_trial_feedback is None:
            return ff.copy()
        N, s = self.problem.N, self.problem.shift
        e_t = np.zeros((N, e.shape[1]))
        e_t[s:] = e[:N - s]
        de = np.diff(e_t, axis=0, prepend=np.zeros((1, e.shape[1]))) / self.problem.ts
        return (ff + np.einsum("kij,kj->ki", self._psi2, e_t)
                + np.einsum("kij,kj->ki", self._phi2, de))

    def update(self, y_measured, *, u_applied=None, states=None) -> np.ndarray:
        r"""Learn from the pending run's measured record; return the next run's input.

        Parameters
        ----------
        y_measured : array_like, shape (N + s, n_y)
            The full record :math:`y(k)`, k = 0..N+s-1 (module docstring); finite.
        u_applied : array_like (N, n_u), optional
            For a trial: the input the machine actually applied (feedback included), if it
            logs it; default: the feed-forward plus the current-trial feedback recomputed from
            the measured error (exactly what the simulated trial applies).
        states : array_like (N + s, n_x), optional
            For a trial: the measured states x(k), k = 0..N+s-1; required by a law with state
            bounds (its ``uses_states``), ignored otherwise.

        Returns
        -------
        ndarray, shape (N, n_u)
            The input of the next run (:attr:`iteration`, :attr:`experiment` say which).

        Raises
        ------
        ShapeError
            A record that is not ``(N + s, n_y)`` (e.g. only the window).
        ParameterError
            Non-finite values.
        """
        p = self.problem
        K, n_y = self.record_length, p.n_y
        y = as_finite_array(y_measured, "y_measured (full record of the run, (N + s, n_y))",
                            ndim=2)
        if y.shape != (K, n_y):
            raise ShapeError(
                f"y_measured must be the full record of the run, shape ({K}, {n_y}): y(k) at "
                f"t0 + k ts for k = 0..N+s-1 = 0..{K - 1} (the learner cuts the window s = "
                f"{p.shift}..N-1+s itself); found shape {y.shape}")
        window = y[p.shift:]
        if self._experiment == 0:
            e = p.reference - window
            if u_applied is None:
                u = self._applied_input(self._next, e)
            else:
                u = as_finite_array(u_applied, "u_applied (input the trial applied, (N, n_u))",
                                    shape=(p.N, p.n_u))
            if self._adapter.extra_experiments:
                inputs = self.law.extra_inputs(e, p.n_u)
                self._pending = {"u": u, "e": e, "outputs": []}
                self._experiment = 1
                self._next = np.asarray(inputs[0], dtype=float)
                self._last_error = e
                return self.next_input
            with np.errstate(over="ignore", invalid="ignore"):   # non-finite: _advance refuses
                ff, _ = self._adapter.next_feedforward(u, e, p.ts, states=states)
            out = self._advance(ff)
            self._last_error = e
            return out
        if u_applied is not None:
            raise ParameterError("u_applied is for a trial; the pending run is an extra "
                                 "experiment (its input is applied open loop)")
        pending = self._pending
        if pending is None:
            raise InternalError("set with experiment 1, cleared only when it returns to 0")
        outputs = [*pending["outputs"], window.copy()]
        inputs = self.law.extra_inputs(pending["e"], p.n_u)
        if len(outputs) < len(inputs):
            pending["outputs"] = outputs
            self._experiment += 1
            self._next = np.asarray(inputs[self._experiment - 1], dtype=float)
            return self.next_input
        with np.errstate(over="ignore", invalid="ignore"):       # non-finite: _advance refuses
            ff = self.law.update(pending["u"], pending["e"], p.ts, extra_outputs=outputs)
        return self._advance(np.asarray(ff, dtype=float))

    def _advance(self, ff: np.ndarray) -> np.ndarray:
        if not np.all(np.isfinite(ff)):
            raise ParameterError(f"the learning update after trial {self._iteration} produced a "
                                 f"non-finite input: the learning diverges; the learner's state "
                                 f"is unchanged (still waiting for this run's record)")
        self._next = np.array(ff, dtype=float)
        self._iteration += 1
        self._experiment = 0
        self._pending = None
        return self.next_input

    # state ------------------------------------------------------------------------------------
    def state(self) -> dict:
        """The learner's state as plain JSON-safe values (what :meth:`save_state` writes)."""
        pending = None
        if self._pending is not None:
            pending = {"u": self._pending["u"].tolist(), "e": self._pending["e"].tolist(),
                       "outputs": [o.tolist() for o in self._pending["outputs"]]}
        return {"format": STATE_FORMAT, "version": STATE_VERSION,
                "fingerprint": self._fingerprint, "problem": self.problem.name,
                "law": self.law.name, "iteration": self._iteration,
                "experiment": self._experiment, "next_input": self._next.tolist(),
                "last_error": None if self._last_error is None else self._last_error.tolist(),
                "pending": pending}

    def save_state(self, path, *, option: str = "path"):
        """Write the state as JSON, atomically (floats exact); returns the resolved path.

        Parameters
        ----------
        path : str or path-like
            The state file to write (replaced if it exists).
        option : str, optional
            Name of the path in error messages (e.g. ``'--state'``); default ``'path'``.

        Returns
        -------
        pathlib.Path
            ``path`` resolved.
        """
        text = json.dumps(self.state(), allow_nan=False)
        with output_file(path, option, in_place=True) as tmp:     # the run's own state
            tmp.write_text(text + "\n", encoding="utf-8")
        return Path(path).resolve()

    @classmethod
    def load_state(cls, path, problem, law, *, option: str = "path") -> Learner:
        """A learner for ``problem`` and ``law`` continuing from the state file ``path``.

        Parameters
        ----------
        path : str or path-like
            A state file written by :meth:`save_state`.
        problem : ILCProblem or TrialSpec
            The problem the state was saved for (its fingerprint must match).
        law : LearningLaw
            The law the state was saved for (its fingerprint must match).
        option : str, optional
            Name of the path in error messages (e.g. ``'--state'``); default ``'path'``.

        Returns
        -------
        Learner

        Raises
        ------
        ParameterError
            Not a learner state file (unreadable, invalid JSON, another format or version), a
            state saved for another design (fingerprint mismatch), or corrupted fields (named).
        """
        learner = cls(problem, law)
        p = check_input_file(path, option)
        shown = str(path)
        try:
            state = json.loads(p.read_text(encoding="utf-8-sig"))
        except UnicodeDecodeError as exc:
            raise ParameterError(f"{option} {shown!r} is not a learner state file (not UTF-8 "
                                 f"text)") from exc
        except json.JSONDecodeError as exc:
            raise ParameterError(f"{option} {shown!r} is not a learner state file (invalid JSON "
                                 f"at line {exc.lineno}, column {exc.colno}: {exc.msg})") from exc
        except (ValueError, RecursionError) as exc:   # an integer of 5 000 digits, deep nesting
            raise ParameterError(f"{option} {shown!r} is not a learner state file (a number "
                                 f"longer than Python reads, or nesting too deep: "
                                 f"{str(exc).split(';')[0]})") from exc
        if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
            raise ParameterError(f"{option} {shown!r} is not a learner state file (no "
                                 f"format = {STATE_FORMAT!r})")
        if state.get("version") != STATE_VERSION:
            raise ParameterError(f"{option} {shown!r} has learner state version "
                                 f"{state.get('version')!r}; this version reads {STATE_VERSION}")
        if state.get("fingerprint") != learner._fingerprint:
            raise ParameterError(
                f"{option} {shown!r} was saved for another design (problem "
                f"{state.get('problem')!r}, law {state.get('law')!r}, fingerprint "
                f"{str(state.get('fingerprint'))[:12]}...); this problem and law have "
                f"fingerprint {learner._fingerprint[:12]}...: start a new state or use the "
                f"design it was saved with")
        learner._restore(state, f"{option} {shown!r}")
        return learner

    def _restore(self, state: dict, where: str) -> None:
        p = self.problem
        expected = {"format", "version", "fingerprint", "problem", "law", "iteration",
                    "experiment", "next_input", "last_error", "pending"}
        if set(state) != expected:
            raise ParameterError(f"{where}: corrupted learner state: keys {sorted(state)}; "
                                 f"expected {sorted(expected)}")

        def field(value, name, shape):
            try:
                return as_finite_array(value, name, shape=shape)
            except (ParameterError, ShapeError) as exc:
                raise ParameterError(f"{where}: corrupted learner state: {exc}") from exc

        def count(name, minimum, maximum):
            v = state[name]
            if isinstance(v, bool) or not isinstance(v, int) or not minimum <= v <= maximum:
                raise ParameterError(f"{where}: corrupted learner state: {name} must be an "
                                     f"integer in [{minimum}, {maximum}]; got "
                                     f"{shown_value(v)}")
            return v

        iteration = count("iteration", 1, 2**62)
        experiment = count("experiment", 0, self._adapter.extra_experiments)
        nxt = field(state["next_input"], "next_input", (p.N, p.n_u))
        last = None if state["last_error"] is None else field(state["last_error"], "last_error",
                                                              (p.N, p.n_y))
        pending = state["pending"]
        if (pending is None) != (experiment == 0):
            raise ParameterError(f"{where}: corrupted learner state: pending must be set exactly "
                                 f"when an extra experiment is pending (experiment = "
                                 f"{experiment})")
        if pending is not None:
            if not isinstance(pending, dict) or set(pending) != {"u", "e", "outputs"} \
                    or not isinstance(pending["outputs"], list) \
                    or len(pending["outputs"]) != experiment - 1:
                raise ParameterError(f"{where}: corrupted learner state: pending must hold u, e "
                                     f"and the {experiment - 1} extra output(s) measured so far")
            pending = {"u": field(pending["u"], "pending.u", (p.N, p.n_u)),
                       "e": field(pending["e"], "pending.e", (p.N, p.n_y)),
                       "outputs": [field(o, f"pending.outputs[{k}]", (p.N, p.n_y))
                                   for k, o in enumerate(pending["outputs"])]}
        self._iteration, self._experiment = iteration, experiment
        self._next, self._last_error, self._pending = np.array(nxt), last, pending

    def __repr__(self) -> str:
        return (f"<Learner {self.law.name} on {self.problem.name!r}: iteration "
                f"{self._iteration}, experiment {self._experiment}>")
