r"""Disturbances of a trial: state disturbance ω_i, output disturbance ν_i, reset errors.

The paper's plant, eq (18), is

.. math::

    \dot x_i = f(x_i, t) + B u_i + \omega_i(t), \qquad y_i = C x_i + \nu_i(t),

and its Section 5 uses :math:`\omega_i(t) = \nu_i(t) = 0.01\,\sin(40\pi t)` on every channel
(the paper's numbers live with the paper: :func:`ilc_analysis.paper.paper_disturbances`).
This module holds the generic disturbance model a problem carries.

In the sampled simulation :math:`\omega_i` is held over each sample (it is the ``w`` argument
of :attr:`DiscretePlant.step`) and :math:`\nu_i(k)` is added to the measured output,
so the learning law sees :math:`e_i(k) = y_d(k) - h(x_i(k)) - \nu_i(k)`.

On top of the deterministic sinusoids, each trial can carry iteration-varying white noise and a
random initial-state (reset) error :math:`x_i(0) = x_0 + \epsilon_i`. Trial i draws from its
own stream ``SeedSequence(seed, spawn_key=(i,))``: the same seed gives the same trials, and
trial i's noise does not depend on how many trials ran before it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validation import as_finite_array, nonnegative
from ..exceptions import InternalError, ParameterError, ShapeError

__all__ = ["Disturbances", "TrialDisturbance", "DEFAULT_FREQUENCY", "NO_DISTURBANCES"]

#: Frequency [Hz] of a sinusoidal disturbance whose frequency is not given (20 Hz, the
#: frequency of the paper's disturbance, kept so existing descriptions read the same).
DEFAULT_FREQUENCY = 20.0


@dataclass(frozen=True)
class TrialDisturbance:
    """The realised disturbance of one trial (arrays over the samples of the trial)."""

    w: np.ndarray
    """state disturbance ω(k), shape (K, n_x), held over sample k"""
    nu: np.ndarray
    """output disturbance ν(k), shape (K, n_y), added to the measured output"""
    reset: np.ndarray
    """initial-state error ε_i, shape (n_x,): the trial starts at x0 + ε_i"""


def _amplitude(value, name: str):
    """A non-negative scalar, or a non-negative per-channel vector."""
    if np.ndim(value) == 0:
        return nonnegative(value, name)
    arr = as_finite_array(value, name, ndim=1)
    if np.any(arr < 0):
        raise ParameterError(f"{name} must be non-negative")
    arr.setflags(write=False)
    return arr


def _per_channel(value, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ShapeError(f"{name} must be a scalar or have shape ({n},) (one per channel); "
                         f"found shape {arr.shape}")
    return arr


def _sinusoid(frequency: float, amplitude: np.ndarray, t: np.ndarray) -> np.ndarray:
    r""":math:`\sin(2\pi f t_k)\,A` on the samples ``t`` ``(K,)``, ``(K, len(A))`` (zeros, with no
    sine evaluated, when every amplitude is zero)."""
    if not amplitude.any():
        return np.zeros((t.size, amplitude.size))
    return np.outer(np.sin(2 * math.pi * frequency * t), amplitude)


@dataclass(frozen=True)
class Disturbances:
    r"""Disturbance model of the simulation (all zero by default).

    .. math::

        \omega_i(k) &= A_\omega \sin(2\pi f_\omega t_k) + \sigma_\omega\,\xi_{i}(k),\\
        \nu_i(k) &= A_\nu \sin(2\pi f_\nu t_k) + \sigma_\nu\,\zeta_{i}(k),\\
        x_i(0) &= x_0 + \sigma_0\,\eta_i,

    with :math:`\xi, \zeta, \eta` standard normal, independent across samples, channels and
    trials. Amplitudes and standard deviations are scalars (every channel) or per-channel
    vectors.
    """

    state_amplitude: float | np.ndarray = 0.0
    """A_ω: amplitude of the sinusoidal state disturbance (per state, or scalar)"""
    state_frequency: float = DEFAULT_FREQUENCY
    """f_ω [Hz]"""
    output_amplitude: float | np.ndarray = 0.0
    """A_ν: amplitude of the sinusoidal output disturbance (per output, or scalar)"""
    output_frequency: float = DEFAULT_FREQUENCY
    """f_ν [Hz]"""
    state_noise: float | np.ndarray = 0.0
    """σ_ω: standard deviation of the white state noise, iteration-varying"""
    output_noise: float | np.ndarray = 0.0
    """σ_ν: standard deviation of the white measurement noise, iteration-varying"""
    reset_error: float | np.ndarray = 0.0
    """σ_0: standard deviation of the initial-state error of each trial"""
    seed: int | None = None
    """seed of the noise streams; None draws fresh entropy (recorded in the result)"""

    def __post_init__(self) -> None:
        for name in ("state_amplitude", "output_amplitude", "state_noise", "output_noise",
                     "reset_error"):
            object.__setattr__(self, name, _amplitude(getattr(self, name), name))
        for name in ("state_frequency", "output_frequency"):
            object.__setattr__(self, name, nonnegative(getattr(self, name), name + " (Hz)"))
        if self.seed is not None and (isinstance(self.seed, bool)
                                      or not isinstance(self.seed, int | np.integer)
                                      or self.seed < 0):
            raise ParameterError(f"seed must be a non-negative integer or None; got {self.seed!r}")

    @classmethod
    def paper(cls, *, seed: int | None = None, **extra) -> Disturbances:
        r"""Old call form of :func:`ilc_analysis.paper.paper_disturbances` (Section 5:
        :math:`\omega_i(t) = \nu_i(t) = 0.01\sin(40\pi t)` on every channel; the numbers'
        home is :data:`ilc_analysis.paper.PAPER_AMPLITUDE` /
        :data:`~ilc_analysis.paper.PAPER_FREQUENCY`, a test ties the two).

        Parameters
        ----------
        seed : int or None, optional
            Seed of the noise streams (see :attr:`seed`); None draws fresh entropy.
        **extra
            Further fields of :class:`Disturbances` added to the paper's sinusoids.
        """
        return cls.sinusoids(0.01, 20.0, seed=seed, **extra)

    @classmethod
    def sinusoids(cls, amplitude, frequency: float, *, seed: int | None = None,
                  **extra) -> Disturbances:
        r""":math:`\omega_i(t) = \nu_i(t) = A\sin(2\pi f t)` on every channel.

        Parameters
        ----------
        amplitude : float or array_like
            :math:`A` of both the state and the output disturbance (scalar or per channel).
        frequency : float
            :math:`f` [Hz] of both.
        seed : int or None, optional
            Seed of the noise streams (see :attr:`seed`); None draws fresh entropy.
        **extra
            Further fields of :class:`Disturbances` (e.g. ``state_noise``, ``reset_error``).
        """
        return cls(state_amplitude=amplitude, state_frequency=frequency,
                   output_amplitude=amplitude, output_frequency=frequency, seed=seed, **extra)

    @property
    def is_random(self) -> bool:
        """Whether any noise or reset error is switched on."""
        return any(np.any(np.asarray(getattr(self, n)) > 0)
                   for n in ("state_noise", "output_noise", "reset_error"))

    def check_dimensions(self, n_x: int, n_y: int) -> None:
        """Raise :class:`~ilc_analysis.exceptions.ShapeError` unless per-channel values fit.

        Parameters
        ----------
        n_x : int
            Number of states of the plant: the length a per-channel ``state_amplitude``,
            ``state_noise`` or ``reset_error`` must have.
        n_y : int
            Number of outputs of the plant: the length a per-channel ``output_amplitude`` or
            ``output_noise`` must have.

        Raises
        ------
        ShapeError
            If a per-channel vector has another length.
        """
        for name, n in (("state_amplitude", n_x), ("state_noise", n_x), ("reset_error", n_x),
                        ("output_amplitude", n_y), ("output_noise", n_y)):
            _per_channel(getattr(self, name), n, name)

    def realise(self, iteration: int, t, n_x: int, n_y: int,
                entropy: int, experiment: int = 0) -> TrialDisturbance:
        """The disturbance of trial ``iteration`` on the sample times ``t`` (K,).

        Parameters
        ----------
        iteration : int
            Trial index i; selects the noise stream ``spawn_key=(iteration,)``.
        t : array_like, shape (K,)
            Sample times [s] at which ω and ν are evaluated.
        n_x : int
            Number of states (columns of ``w``, length of ``reset``).
        n_y : int
            Number of outputs (columns of ``nu``).
        entropy : int
            The root seed of the run (``seed``, or the entropy drawn by
            :meth:`root_entropy`).
        experiment : int, optional
            Numbers the plant runs of one iteration: 0 (default) is the trial itself (stream
            ``spawn_key=(iteration,)``), k >= 1 the k-th extra experiment a law asks for
            (e.g. time reversal; stream ``spawn_key=(iteration, k)``): the same sinusoids (a
            repeating disturbance), independent noise and reset error.

        Returns
        -------
        TrialDisturbance
            ``w`` (K, n_x), ``nu`` (K, n_y) and ``reset`` (n_x,).

        Raises
        ------
        ShapeError
            If a per-channel vector does not fit ``n_x`` or ``n_y``.
        """
        t = np.asarray(t, dtype=float)
        w = _sinusoid(self.state_frequency,
                      _per_channel(self.state_amplitude, n_x, "state_amplitude"), t)
        nu = _sinusoid(self.output_frequency,
                       _per_channel(self.output_amplitude, n_y, "output_amplitude"), t)
        reset = np.zeros(n_x)
        if self.is_random:
            key = (iteration,) if experiment == 0 else (iteration, experiment)
            rng = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=key))
            # fixed draw order: reset, state noise, output noise
            reset = _per_channel(self.reset_error, n_x, "reset_error") \
                * rng.standard_normal(n_x)
            w = w + _per_channel(self.state_noise, n_x, "state_noise") \
                * rng.standard_normal((t.size, n_x))
            nu = nu + _per_channel(self.output_noise, n_y, "output_noise") \
                * rng.standard_normal((t.size, n_y))
        return TrialDisturbance(w=w, nu=nu, reset=reset)

    def root_entropy(self) -> int:
        """The root seed of a run: ``seed``, or fresh entropy when ``seed`` is None."""
        if self.seed is not None:
            return int(self.seed)
        entropy = np.random.SeedSequence().entropy
        # a SeedSequence made without entropy draws one int (numpy types it with the inputs)
        if not isinstance(entropy, int):
            raise InternalError("root_entropy: a fresh SeedSequence entropy that is not an int")
        return entropy

    def as_dict(self) -> dict:
        out = {}
        for name in ("state_amplitude", "state_frequency", "output_amplitude",
                     "output_frequency", "state_noise", "output_noise", "reset_error"):
            out[name] = np.asarray(getattr(self, name), dtype=float)
        return out


NO_DISTURBANCES = Disturbances()
