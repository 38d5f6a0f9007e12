r"""Record three identification trials of the two-mass drive: ``trial_<i>.csv`` (i = 1..3).

This script stands for the user's data logger: it only *produces* the recorded trials (and the
desired motion ``reference.csv``). The design is then made from these files alone: the design
file ``design.toml`` names them under ``[plant] trials``, the toolkit identifies the lifted
model with its confidence bound (docs/identification.md), and ``ilc-analysis check
design.toml`` identifies it again from the same files and re-verifies the certificate over the
identified set.

What is recorded: the two-mass drive of ``examples/two_mass`` (``plant.npz``) under its PID
servo loop (kp = 6, ki = 4, kd = 4, tf = 0.05, as in ``examples/two_mass/design.toml``), from
the loop's reference r (held by a zero-order hold, ts = 0.01 s) to the sampled load position
x2: the plant the learning acts on when it adjusts the loop's reference. Each trial

* starts from rest and lasts N = 1 000 samples (10 s);
* applies a white Gaussian reference excitation r(k) of unit variance, k = 0..N-1;
* logs the output window x2(1), ..., x2(N) (shift 1: the sampled loop has relative degree 1)
  with 40 dB SNR: white Gaussian noise of standard deviation RMS(x2) / 100 of that trial.

``trial_<i>.csv`` has the header ``r,x2`` and one row per sample: r(k) and x2(k + 1).
``reference.csv`` is the desired load motion of ``examples/two_mass/reference.csv`` (3 s),
held at its final value to the 10 s of the trial.

``python examples/two_mass_trials/record.py`` writes the trials and the reference (seeded: the
files are reproducible). ``python examples/two_mass_trials/record.py --design`` then writes
``design.toml``: the norm-optimal law on the identified model with its certificate
(``Design.certify``; the same as loading a design file without a certificate and saving it
certified).
"""

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
TWO_MASS = HERE.parent / "two_mass"
TS, N, SHIFT = 0.01, 1000, 1
PID = {"kp": 6.0, "ki": 4.0, "kd": 4.0, "tf": 0.05}
TRIALS, SNR_DB, SEED = 3, 40.0, 2028
#: the design: the identified FIR length (assumption A2 of docs/identification.md) and the
#: norm-optimal weights (docs/identification.md, "The robust certificate"). M = 600 is refuted
#: by the F-test against a FIR of length N (p = 4e-7; the loop's impulse response past 600
#: samples is not below the noise), which suggests M >= 647: 700 is a round length with margin.
FIR_LENGTH, WEIGHT_INPUT_CHANGE, WEIGHT_INPUT = 700, 1e-2, 1e-2


def loop():
    """The sampled loop r -> x2 (a discrete ``control.StateSpace``, zero-order hold)."""
    import control

    data = np.load(TWO_MASS / "plant.npz")
    P = control.ss(data["A"], data["B"], data["C"], data["D"])
    kp, ki, kd, tf = PID["kp"], PID["ki"], PID["kd"], PID["tf"]
    C = control.tf([kp * tf + kd, kp + ki * tf, ki], [tf, 1.0, 0.0])
    closed = control.feedback(control.series(control.ss(C), P), 1)
    return control.c2d(control.ss(closed), TS, method="zoh")


def respond(sys, r: np.ndarray) -> np.ndarray:
    """The noise-free output window x2(1..N) of the loop at rest driven by r(0..N-1)."""
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    x = np.zeros(A.shape[0])
    y = np.empty(r.size)
    for k in range(r.size):
        x = A @ x + B[:, 0] * r[k]
        y[k] = (C @ x)[0] + D[0, 0] * (r[k + 1] if k + 1 < r.size else 0.0)
    return y


def records(seed: int = SEED) -> list[tuple[np.ndarray, np.ndarray]]:
    """The ``TRIALS`` recorded trials ``(r, x2)``, each ``(N,)``, with 40 dB SNR noise."""
    rng = np.random.default_rng(seed)
    sys = loop()
    out = []
    for _ in range(TRIALS):
        r = rng.standard_normal(N)
        y = respond(sys, r)
        std = np.sqrt(np.mean(y ** 2)) / 10.0 ** (SNR_DB / 20.0)
        out.append((r, y + std * rng.standard_normal(N)))
    return out


def reference() -> np.ndarray:
    """The two-mass reference (3 s) held at its final value to N samples, ``(N,)``."""
    ref = np.loadtxt(TWO_MASS / "reference.csv", skiprows=1)
    return np.concatenate([ref, np.full(N - ref.size, ref[-1])])


def main() -> None:
    for i, (r, y) in enumerate(records(), start=1):
        np.savetxt(HERE / f"trial_{i}.csv", np.column_stack([r, y]), delimiter=",",
                   header="r,x2", comments="")
    np.savetxt(HERE / "reference.csv", reference()[:, None], header="x2", comments="")


DESIGN = f"""format = "ilc-analysis-design/1"

[plant]
trials = [{", ".join(f'"trial_{i}.csv"' for i in range(1, TRIALS + 1))}]
inputs = ["r"]
outputs = ["x2"]
identification = {{ fir_length = {FIR_LENGTH}, dt = {TS}, shift = {SHIFT} }}

[problem]
name = "two-mass drive from three recorded trials, learning at the PID loop's reference"
ts = {TS}
N = {N}
shift = {SHIFT}
reference = "reference.csv"

[law]
kind = "norm-optimal"
weight_input_change = {WEIGHT_INPUT_CHANGE}
weight_input = {WEIGHT_INPUT}
"""


def design() -> None:
    """Write ``design.toml``: the design above, certified on the identified model and over
    the identified set."""
    from ilc_analysis.design import load_design, save_design

    draft = HERE / "design_draft.toml"
    draft.write_text(DESIGN, encoding="utf-8")
    try:
        certified = load_design(draft).certify()
    finally:
        draft.unlink()
    save_design(certified, HERE / "design.toml",
                command="python examples/two_mass_trials/record.py --design")


if __name__ == "__main__":
    design() if "--design" in sys.argv[1:] else main()
