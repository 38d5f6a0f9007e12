r"""A trial without a plant model: what a learner on a real machine needs and nothing more.

An :class:`~ilc_analysis.problem.ILCProblem` holds a plant model (it is lifted, analysed and
simulated). A law designed from measured data (a design from FRF data,
``docs/measured-data.md``) has no model, yet it can drive the machine trial by trial
(:class:`~ilc_analysis.simulation.Learner`): the learner only needs the trial's frame, which
:class:`TrialSpec` holds:

* ``ts``, ``N``, ``shift``: sample time, window length and the shift s of the output window
  (the error is :math:`e(j) = y_d(j) - y(j + s)`, j = 0..N-1);
* ``reference``: :math:`y_d` on the window, ``(N, n_y)``;
* ``input_names``, ``output_names``: the channels of the input CSV written and of the measured
  record read (``n_u``, ``n_y`` are their counts);
* the first trial's input is zero (:meth:`TrialSpec.initial_input`).

It cannot be lifted or simulated: a law that needs the lifted model to be set up is refused by
the learner with a message saying so.
"""

from __future__ import annotations

import numpy as np

from .._validation import (
    MAX_SHIFT,
    MAX_TRIAL_SAMPLES,
    as_finite_array,
    positive,
    positive_int,
)
from ..exceptions import ParameterError
from ._problem import _frozen

__all__ = ["TrialSpec", "is_trial_spec"]


def _names(value, what: str, count: int | None) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise ParameterError(f"{what} must be a list of channel names; got {value!r:.80}")
    names = tuple(value)
    if not names or not all(isinstance(n, str) and n and n.strip() == n for n in names):
        raise ParameterError(f"{what} must be non-empty strings without surrounding blanks; "
                             f"got {list(names)!r:.80}")
    if len(set(names)) != len(names):
        raise ParameterError(f"{what} must be distinct; got {list(names)}")
    if count is not None and len(names) != count:
        raise ParameterError(f"{what} must name {count} channel(s), one per column of the "
                             f"reference; got {len(names)}")
    return names


class TrialSpec:
    r"""The frame of a trial on a machine with no plant model (module docstring).

    Parameters
    ----------
    ts : float
        Sample time [s], > 0.
    N : int
        Samples in the output window (trial length), 1 .. ``MAX_TRIAL_SAMPLES``.
    reference : array_like, shape (N, n_y)
        :math:`y_d(j)`, j = 0..N-1, finite.
    shift : int
        Shift s >= 0 of the output window (a learner needs s >= 1).
    input_names : sequence of str
        One distinct name per input channel (n_u of them).
    output_names : sequence of str
        One distinct name per output channel: as many as the reference's columns.
    name : str, optional
        The trial's name (messages, state files); default ``"trial"``.

    Raises
    ------
    ParameterError
        A value out of range or of the wrong type (named).
    ShapeError
        ``reference`` is not ``(N, len(output_names))``.
    """

    def __init__(self, ts, N, reference, *, shift, input_names, output_names,
                 name: str = "trial") -> None:
        self.ts = positive(ts, "ts (sample time)")
        self.N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
        self.shift = positive_int(shift, "shift", minimum=0, maximum=MAX_SHIFT)
        self.output_names = _names(output_names, "output_names", None)
        self.input_names = _names(input_names, "input_names", None)
        self.reference = _frozen(as_finite_array(reference, "reference",
                                                 shape=(self.N, len(self.output_names))))
        if not isinstance(name, str) or not name:
            raise ParameterError(f"name must be a non-empty string; got {name!r:.80}")
        self.name = name

    @property
    def n_u(self) -> int:
        """Number of input channels."""
        return len(self.input_names)

    @property
    def n_y(self) -> int:
        """Number of output channels."""
        return len(self.output_names)

    def initial_input(self) -> np.ndarray:
        """The first trial's input: zeros ``(N, n_u)`` (a fresh array)."""
        return np.zeros((self.N, self.n_u))

    def describe(self) -> dict:
        """A plain dict of the trial (arrays as nested lists): ``name``, ``ts``, ``N``,
        ``shift``, ``reference``, ``input_names``, ``output_names``."""
        return {"name": self.name, "ts": self.ts, "N": self.N, "shift": self.shift,
                "reference": self.reference.tolist(), "input_names": list(self.input_names),
                "output_names": list(self.output_names)}

    def __repr__(self) -> str:
        return (f"<TrialSpec {self.name!r}: N = {self.N}, ts = {self.ts:g} s, shift "
                f"{self.shift}, inputs {list(self.input_names)}, outputs "
                f"{list(self.output_names)}>")


def is_trial_spec(obj) -> bool:
    """True when ``obj`` is a :class:`TrialSpec`.

    Parameters
    ----------
    obj : object
        Anything.
    """
    return isinstance(obj, TrialSpec)
