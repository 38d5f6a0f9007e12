r"""The arrays of a learning run: every trial's record, allocated once.

A run of I trials of K = N + s samples keeps, per trial, the record of
:class:`~ilc_analysis.simulation._trial.TrialRecord` (state x, applied input u, output y,
error e and the plant's signals, each over the K trial samples) and the trial's feed-forward
:math:`f_i` (N samples). :class:`RunStore` allocates all of them as one block of memory, cut
into one C-ordered ``(I, K, width)`` array per variable (``(I, N, n_u)`` for the feed-forward).
The trial writes its record straight into its slab (:meth:`RunStore.record`), and the result's
data set wraps views of the blocks without copying (:meth:`RunStore.window`: the output window,
samples s .. N-1+s, and the input samples 0 .. N-1).

Why one block: the record is the run's largest cost after the filtering itself (five arrays
of I x N values: 32 MB for 40 trials of 20 000 samples); one allocation is one first touch of
each page, in the order the trials write them, and a run can reuse the block of an earlier
run whose result is gone (:func:`~ilc_analysis._arrays.recycled_empty`: its pages are already
the process's, where fresh memory costs a page fault per page).

A run without current-trial feedback applies its feed-forward as it is (:math:`u_i = f_i`):
its feed-forward is then the input record's rows 0 .. N-1 (``input_is_feedforward``), not a
second copy: the law writes the next trial's input where the trial reads it, and the data
set's ``u`` and ``u_ff`` are views of the same memory.

Each trial's error extremes on the output window (per channel) are kept beside the record
(:attr:`RunStore.error_max`, :attr:`RunStore.error_min`): the engine takes them while the
trial's error is in the cache, to screen the trial (a non-finite output makes them
non-finite) and for the data set's ``max_abs_e``. So are the bounds a trial may find on its
states and inputs while computing them (``TrialRecord.bounds``, NaN until a trial writes
them), which spare the screen reading those arrays again.
"""

from __future__ import annotations

import numpy as np

from .._arrays import lazy_zeros, recycled_empty
from ..model import DiscretePlant
from ._trial import TrialRecord

__all__ = ["RunStore"]

#: the record's variables in the order of the block
_RECORD = ("x", "u", "y", "e", "signals")


class RunStore:
    """The records of up to ``iterations`` trials of ``dplant`` (module docstring).

    Parameters
    ----------
    iterations : int
        Trials of the run.
    N : int
        Lifted trial length.
    shift : int
        Sampled relative degree s (the output window is samples s .. N-1+s).
    dplant : DiscretePlant
        The plant (its numbers of states, inputs, outputs and signals).
    input_is_feedforward : bool, optional
        Whether every trial applies its feed-forward as it is (no current-trial feedback):
        the feed-forward is then a view of the input record (module docstring).

    Attributes
    ----------
    feedforward : ndarray, shape (iterations, N, n_u)
        The feed-forward :math:`f_i` of each trial.
    error_max, error_min : ndarray, shape (iterations, n_y)
        The largest and the smallest error of each trial on the output window, per channel
        (written by the engine).
    experiments : ndarray of int32, shape (iterations,)
        Plant runs of each iteration (the trial and the law's extra experiments).
    """

    def __init__(self, iterations: int, N: int, shift: int, dplant: DiscretePlant,
                 input_is_feedforward: bool = False) -> None:
        K = N + shift
        self.N, self.shift = N, shift
        widths = {"x": dplant.n_x, "u": dplant.n_u, "y": dplant.n_y, "e": dplant.n_y,
                  "signals": len(dplant.signal_names)}
        own_feedforward = 0 if input_is_feedforward else N * dplant.n_u
        block = recycled_empty(iterations * (K * sum(widths.values()) + own_feedforward))
        self._arrays = {}
        start = 0
        for name in _RECORD:
            end = start + iterations * K * widths[name]
            self._arrays[name] = block[start:end].reshape(iterations, K, widths[name])
            start = end
        self.feedforward = (self._arrays["u"][:, :N] if input_is_feedforward
                            else block[start:].reshape(iterations, N, dplant.n_u))
        self.error_max = np.empty((iterations, dplant.n_y))
        self.error_min = np.empty((iterations, dplant.n_y))
        self.experiments = np.zeros(iterations, dtype=np.int32)
        self._factor: np.ndarray | None = None
        self._iterations = iterations
        self._ordered = tuple(self._arrays[name] for name in _RECORD)   # TrialRecord's order
        self._bounds = np.full((iterations, 2), np.nan)      # TrialRecord.bounds, per trial

    def record(self, i: int) -> TrialRecord:
        """Trial ``i``'s record (0-based): views of its slabs, ``(K, width)`` each."""
        x, u, y, e, signals = self._ordered
        return TrialRecord(x[i], u[i], y[i], e[i], signals[i], self._bounds[i])

    def set_factor(self, i: int, a: np.ndarray) -> None:
        """Record trial ``i``'s forgetting factor ``a`` ``(N,)`` (the array exists only once
        a trial has a non-zero one)."""
        if self._factor is None:
            self._factor = np.zeros((self._iterations, self.N))
        self._factor[i] = a

    def window(self, name: str, n: int) -> np.ndarray:
        """The first ``n`` trials of a variable as the data set holds it (a view): ``"x"``,
        ``"y"``, ``"e"``, ``"signals"`` on the output window ``(n, N, width)``, ``"u"`` on the
        input samples ``(n, N, n_u)``."""
        if name == "u":
            return self._arrays["u"][:n, :self.N]
        return self._arrays[name][:n, self.shift:]

    def factor(self, n: int) -> np.ndarray:
        """The forgetting factors of the first ``n`` trials, ``(n, N)`` (zeros for a run
        without forgetting: mapped zero pages, :func:`~ilc_analysis._arrays.lazy_zeros`)."""
        return lazy_zeros((n, self.N)) if self._factor is None else self._factor[:n]
