r"""Write the robot-joint example's data files: ``reference.csv`` and ``initial_input.csv``.

This script stands for whatever tool a user already has (a trajectory generator, MATLAB): it
only *produces* the files; ``design.toml`` names them, and ``ilc-analysis check / simulate /
synthesize`` run on them with no Python written.

The plant is a robot joint with its own position servo, seen from its position command
:math:`q_{cmd}` [rad] to the joint angle q [rad]: the servo's current loop as a first-order
lag and the closed position loop as a second-order mode,

.. math::

    G(s) = \frac{a}{s + a}\cdot\frac{\omega_0^2}{s^2 + 2\zeta\omega_0 s + \omega_0^2},
    \qquad a = 8.8\ \mathrm{s^{-1}},\ \omega_0 = 37\ \mathrm{rad/s},\ \zeta = 0.5,

with unit DC gain. It is sampled at 400 Hz (ts = 2.5 ms) with a zero-order hold.

The reference is a point-to-point motion: quintic moves of :data:`MOVE` rad from rest to rest
in :data:`MOVE_TIME` s, each followed by a dwell of :data:`DWELL` s, alternating direction. A
3 s trial (N = 1 200) is one move and its dwell. :func:`reference` gives the same motion for
any sample time and length (the benchmark's 20 s trial at 1 kHz: six moves and dwells, and a
seventh move that ends at the trial's end).

The first trial's command is the reference itself, at the command's own sample times
:math:`k T_s` (what a user sends a servo with unit DC gain before learning anything).

Run from anywhere: ``python examples/robot_joint/make_reference.py``.
"""

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: the joint (module docstring): current-loop pole [1/s], servo mode [rad/s] and damping
A_POLE, OMEGA0, ZETA = 8.8, 37.0, 0.5
#: the example's sampling: 400 Hz, 1 200 samples (3 s), output window shifted by one sample
TS, N, SHIFT = 0.0025, 1200, 1
#: the motion: move [rad], its duration [s], the dwell after it [s]
MOVE, MOVE_TIME, DWELL = 1.0, 2.0, 1.0


def transfer_function() -> tuple[list[float], list[float]]:
    """(num, den) of G(s), highest power first (module docstring)."""
    num = [A_POLE * OMEGA0**2]
    den = np.polymul([1.0, A_POLE], [1.0, 2.0 * ZETA * OMEGA0, OMEGA0**2])
    return num, [float(c) for c in den]


def motion(t: np.ndarray) -> np.ndarray:
    """The joint angle [rad] at times ``t`` [s] (module docstring): alternating quintic moves
    of MOVE rad in MOVE_TIME s, each followed by DWELL s at rest."""
    t = np.asarray(t, dtype=float)
    period = MOVE_TIME + DWELL
    cycle = np.floor(t / period)
    tau = np.clip((t - cycle * period) / MOVE_TIME, 0.0, 1.0)
    blend = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    start = np.where(cycle % 2 == 0, 0.0, MOVE)
    return start + np.where(cycle % 2 == 0, 1.0, -1.0) * MOVE * blend


def reference(ts: float = TS, n: int = N, shift: int = SHIFT) -> np.ndarray:
    """y_d on the output window, times (shift + k) ts, shape (n, 1)."""
    return motion((shift + np.arange(n)) * ts)[:, None]


def initial_input(ts: float = TS, n: int = N) -> np.ndarray:
    """The first trial's command: the motion at the input's times k ts, shape (n, 1)."""
    return motion(np.arange(n) * ts)[:, None]


def main() -> None:
    np.savetxt(HERE / "reference.csv", reference(), delimiter=",", header="q",
               comments="", fmt="%.17g")
    np.savetxt(HERE / "initial_input.csv", initial_input(), delimiter=",", header="q_cmd",
               comments="", fmt="%.17g")


if __name__ == "__main__":
    main()
