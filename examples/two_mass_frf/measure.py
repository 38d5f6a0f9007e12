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
reproducible). ``python examples/two_mass_frf/measure.py --design`` then writes ``design.toml``
from these files alone, as ``ilc-analysis design-frf measurement_*.csv --ts 0.01 --reference
../two_mass/reference.csv --inputs r --outputs x2`` does, and adds what the data cannot give:
the ``[simulation]`` table (the true loop of ``examples/two_mass``, the model ``simulate`` runs
on; not used by the design or its certificate).
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


HEADER = """\
# A Q/L law designed from five measured FRFs of the two-mass drive's servo loop (no model),
# written by 'python examples/two_mass_frf/measure.py --design' (the design of 'ilc-analysis
# design-frf'; docs/measured-data.md). [simulation] at the end is the one table the data cannot
# give: the model 'simulate' runs on.
#
#   ilc-analysis check    examples/two_mass_frf/design.toml       # the certificate, from the data
#   ilc-analysis learn    examples/two_mass_frf/design.toml --state state.json --out input_1.csv
#   ilc-analysis simulate examples/two_mass_frf/design.toml --iterations 20 --out frf_run
"""

SIMULATION = f"""
# the model the simulation runs on, here the true loop of examples/two_mass (not used by the
# design or the certificate, which come from the data alone)
[simulation]
plant = {{ file = "../two_mass/plant.npz", inputs = ["F"], outputs = ["x2"] }}
learning_at = {{ kind = "loop-reference", controller = {{ pid = {{ kp = {PID['kp']}, \
ki = {PID['ki']}, kd = {PID['kd']}, tf = {PID['tf']} }} }} }}
discretization = {{ method = "zoh" }}
"""


def design() -> None:
    """Write ``design.toml`` from the measurement files (module docstring)."""
    from ilc_analysis.design import save_frf_design
    from ilc_analysis.model import read_frf
    from ilc_analysis.synthesis import design_from_frf

    files = [HERE / f"measurement_{i}.csv" for i in range(1, MEASUREMENTS + 1)]
    designed = design_from_frf(read_frf(files, TS), shift=SHIFT)
    out = HERE / "design.toml"
    save_frf_design(designed, out, files, ts=TS, reference=HERE.parent / "two_mass" /
                    "reference.csv", inputs=["r"], outputs=["x2"],
                    command="python examples/two_mass_frf/measure.py --design")
    out.write_text(HEADER + out.read_text(encoding="utf-8") + SIMULATION, encoding="utf-8")


if __name__ == "__main__":
    import sys

    design() if "--design" in sys.argv[1:] else main()
