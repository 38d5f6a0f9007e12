r"""Write the two-mass example's data files: ``plant.npz`` and ``reference.csv``.

This script stands for whatever tool a user already has (MATLAB, a system-identification
package, a hand derivation): it only *produces* the files; ``design.toml`` names them, and
``ilc-analysis check / simulate / synthesize`` run on them with no Python written.

The plant is a two-mass drive: a force F on mass 1 (the motor side), the position of mass 2
(the load) measured, a spring k and a damper c between the masses, no spring to ground:

.. math::

    m_1\ddot x_1 = F - k(x_1 - x_2) - c(\dot x_1 - \dot x_2),\qquad
    m_2\ddot x_2 = k(x_1 - x_2) + c(\dot x_1 - \dot x_2),

with state :math:`x = (x_1, \dot x_1, x_2, \dot x_2)`, input F [N], output :math:`x_2` [m],
and :math:`m_1 = 1` kg, :math:`m_2 = 0.5` kg, k = 200 N/m, c = 1 N s/m (resonance at
:math:`\sqrt{k(m_1 + m_2)/(m_1 m_2)} = 24.5` rad/s). ``plant.npz`` holds the continuous
matrices A, B, C, D (no ``dt``: continuous; the problem samples it with a zero-order hold).

The reference is a smooth 10 cm move of the load (a quintic from rest to rest in 1.5 s, then
held) on the output window of the design: N = 300 samples at ts = 0.01 s, times
:math:`(s + k)\,T_s` with the shift s = 1. ``reference.csv`` has a header line and one row per
sample.

Run from anywhere: ``python examples/two_mass/make_plant.py``.
"""

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
M1, M2, K, C = 1.0, 0.5, 200.0, 1.0
TS, N, SHIFT = 0.01, 300, 1
MOVE, DURATION = 0.1, 1.5


def matrices():
    """(A, B, C, D) of the two-mass drive (module docstring)."""
    A = np.array([[0.0, 1.0, 0.0, 0.0],
                  [-K / M1, -C / M1, K / M1, C / M1],
                  [0.0, 0.0, 0.0, 1.0],
                  [K / M2, C / M2, -K / M2, -C / M2]])
    B = np.array([[0.0], [1.0 / M1], [0.0], [0.0]])
    Cm = np.array([[0.0, 0.0, 1.0, 0.0]])
    D = np.zeros((1, 1))
    return A, B, Cm, D


def reference() -> np.ndarray:
    """The load position [m] on the output window, shape (N, 1)."""
    t = (SHIFT + np.arange(N)) * TS
    tau = np.clip(t / DURATION, 0.0, 1.0)
    return (MOVE * (10 * tau**3 - 15 * tau**4 + 6 * tau**5))[:, None]


def main() -> None:
    A, B, Cm, D = matrices()
    np.savez(HERE / "plant.npz", A=A, B=B, C=Cm, D=D)
    np.savetxt(HERE / "reference.csv", reference(), delimiter=",", header="x2",
               comments="", fmt="%.17g")


if __name__ == "__main__":
    main()
