r"""Facts measured from learning runs, set beside the paper's claims (Section 5).

Every number in the report comes from :func:`law_facts` applied to the simulation results, so
a test can recompute the figures from the saved data and compare them with the report. The
metrics themselves are generic (:mod:`ilc_analysis.simulation._metrics`: settling iteration,
rises, reduction); the paper applies them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..simulation import ILCResult
from ..simulation._metrics import (
    RISE_TOLERANCE,
    SETTLE_TOLERANCE,
    rises,
    settling_iteration,
)
from ._robot import PITCH_METRIC

__all__ = ["LawFacts", "law_facts", "SETTLE_TOLERANCE", "RISE_TOLERANCE", "settling_iteration",
           "rises"]


@dataclass(frozen=True)
class LawFacts:
    """What one learning run did, per the paper's claims."""

    label: str
    iterations_run: int
    diverged: bool
    diverged_iteration: int | None
    diverged_time: float | None
    diverged_reason: str | None
    """why the run stopped (e.g. '|theta| = 1.02 exceeds its bound 1'), None if it did not"""
    max_error: list[float]
    """max |e| of every completed trial (empty if the first trial diverged)"""
    max_pitch: list[float]
    first_max_error: float | None
    """None (also for every other per-trial figure below) when no trial completed: the run
    diverged in its first trial, at :attr:`diverged_time`"""
    last_max_error: float | None
    best_max_error: float | None
    reduction: float | None
    """first / last max |e| (how many times smaller the last trial's error is)"""
    settling_iteration: int | None
    increases: int
    """number of iterations whose max |e| exceeds the previous one by more than
    :data:`RISE_TOLERANCE` (0: monotone)"""
    largest_rise: float
    """largest relative rise of max |e| from one iteration to the next (0: never rises)"""
    max_pitch_overall: float | None
    last_max_pitch: float | None

    def as_dict(self) -> dict:
        return asdict(self)


def law_facts(label: str, result: ILCResult) -> LawFacts:
    """Collect :class:`LawFacts` from a simulation result.

    A run that diverged in its first trial has no completed trial: its per-trial figures are
    None and :attr:`LawFacts.diverged_iteration` / :attr:`LawFacts.diverged_time` say where
    it stopped.
    """
    me = np.asarray(result.max_error, dtype=float)
    pitch = np.asarray(result.dataset[PITCH_METRIC].values, dtype=float)
    div = result.divergence
    count, largest = rises(me)
    some = me.size > 0

    def pick(values, fn):
        return float(fn(values)) if some else None

    return LawFacts(
        label=label, iterations_run=int(me.size), diverged=bool(result.diverged),
        diverged_iteration=None if div is None else int(div.iteration),
        diverged_time=None if div is None else float(div.time),
        diverged_reason=None if div is None else str(div.reason),
        max_error=me.tolist(), max_pitch=pitch.tolist(),
        first_max_error=pick(me, lambda v: v[0]), last_max_error=pick(me, lambda v: v[-1]),
        best_max_error=pick(me, np.min), reduction=pick(me, lambda v: v[0] / v[-1]),
        settling_iteration=settling_iteration(me),
        increases=count, largest_rise=largest,
        max_pitch_overall=pick(pitch, np.max), last_max_pitch=pick(pitch, lambda v: v[-1]))
