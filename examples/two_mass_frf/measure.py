r"""Measure the two-mass drive's FRF five times: ``measurement_<i>.csv`` (i = 1..5).

This script stands for the user's measurement system (a dynamic signal analyser, a multisine
experiment): it only *produces* the measurement files. The design is then made from these
files alone (``ilc-analysis design-frf``, or :func:`ilc_analysis.synthesis.design_from_frf`),
with no model.

What is measured: the two-mass drive of ``examples/two_mass`` (``plant.npz``) under its PID
servo loop (kp = 6, ki = 4, kd = 4, tf = 0.05, as in ``examples/two_mass/design.toml``), from the
loop's reference r (held by a zero-order hold, ts = 0.01 s) to the sampled load position: the
plant the learning acts on when it adjusts the loop's reference. The excitation is periodic
with period N = 300 samples, so the response is measured on the DFT bins
:math:`f_k = k/(N T_s)`, k = 0..150 (0 to 50 Hz).

Each of the five measurements sees

* the drive with its spring stiffness k scaled by :math:`(1 + \delta_i)^2`, :math:`\delta_i`
  uniform in [-3 %, 3 %]: a 3 % spread of the resonance :math:`\propto\sqrt k` (the machine
  varies between measurements: temperature, position, load);
* 1 % complex Gaussian noise: :math:`G^{(i)}_k = G_{\delta_i}(e^{j\omega_kT_s})(1 + 0.01\,n)`,
  n standard complex normal (real and imaginary parts of variance 1/2).

Run from anywhere: ``python examples/two_mass_frf/measure.py`` (seeded: the files are
reproducible).
"""

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
PLANT = HERE.parent / "two_mass" / "plant.npz"
TS, N, SHIFT = 0.01, 300, 1
PID = {"kp": 6.0, "ki": 4.0, "kd": 4.0, "tf": 0.05}
MEASUREMENTS, NOISE, SPREAD, SEED = 5, 0.01, 0.03, 2028


def loop(delta: float = 0.0):
    """The sampled loop r -> x2 (a discrete ``control.StateSpace``) with the resonance moved by
    the relative amount ``delta`` (stiffness scaled by (1 + delta)^2)."""
    import control

    data = np.load(PLANT)
    A = data["A"].copy()
    A[:, 0] *= (1.0 + delta) ** 2       # the spring terms: columns of x1 and x2 in the
    A[:, 2] *= (1.0 + delta) ** 2       # velocity rows (the position rows have zeros there)
    P = control.ss(A, data["B"], data["C"], data["D"])
    kp, ki, kd, tf = PID["kp"], PID["ki"], PID["kd"], PID["tf"]
    C = control.tf([kp * tf + kd, kp + ki * tf, ki], [tf, 1.0, 0.0])
    closed = control.feedback(control.series(control.ss(C), P), 1)
    return control.c2d(control.ss(closed), TS, method="zoh")


def frequencies() -> np.ndarray:
    """The DFT bins k/(N ts), k = 0..N//2 [Hz]."""
    return np.arange(N // 2 + 1) / (N * TS)


def response(sys) -> np.ndarray:
    """The response of a discrete SISO system on :func:`frequencies`, ``(n_f,)`` complex."""
    z = np.exp(2j * np.pi * frequencies() * TS)
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    X = np.linalg.solve(z[:, None, None] * np.eye(A.shape[0]) - A,
                        np.broadcast_to(B, (z.size, *B.shape)))
    return (C @ X + D)[:, 0, 0]


def measurements(seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    """``(deltas, responses)``: the five resonance offsets and measured responses (n, n_f)."""
    rng = np.random.default_rng(seed)
    deltas = rng.uniform(-SPREAD, SPREAD, MEASUREMENTS)
    out = []
    for d in deltas:
        G = response(loop(d))
        noise = (rng.standard_normal(G.size) + 1j * rng.standard_normal(G.size)) / np.sqrt(2)
        out.append(G * (1.0 + NOISE * noise))
    return deltas, np.array(out)


def main() -> None:
    from ilc_analysis.model import write_frf_csv

    _, Gs = measurements()
    for i, G in enumerate(Gs, start=1):
        write_frf_csv(HERE / f"measurement_{i}.csv", frequencies(), G)


if __name__ == "__main__":
    main()
