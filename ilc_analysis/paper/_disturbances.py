r"""The paper's disturbances (Section 5): :math:`\omega_i(t) = \nu_i(t) = 0.01\sin(40\pi t)`.

The generic disturbance model is :class:`ilc_analysis.problem.Disturbances`; these are the
paper's numbers for it.
"""

from __future__ import annotations

from ..problem._disturbances import Disturbances

__all__ = ["PAPER_AMPLITUDE", "PAPER_FREQUENCY", "paper_disturbances"]

#: Amplitude of the paper's ω_i = ν_i = 0.01 sin(40πt) (Section 5).
PAPER_AMPLITUDE = 0.01
#: Frequency of the paper's disturbance sin(40πt): 20 Hz.
PAPER_FREQUENCY = 20.0


def paper_disturbances(*, seed: int | None = None, **extra) -> Disturbances:
    r"""Section 5: :math:`\omega_i(t) = \nu_i(t) = 0.01\sin(40\pi t)` on every channel.

    Parameters
    ----------
    seed : int or None, optional
        Seed of the noise streams (:attr:`~ilc_analysis.problem.Disturbances.seed`); None
        draws fresh entropy.
    **extra
        Further fields of :class:`~ilc_analysis.problem.Disturbances` (e.g. ``state_noise``,
        ``reset_error``) added to the paper's sinusoids.
    """
    return Disturbances.sinusoids(PAPER_AMPLITUDE, PAPER_FREQUENCY, seed=seed, **extra)
