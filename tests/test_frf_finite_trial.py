"""The FRF certificate's scope (issue 35): a design from FRF data is judged on the trial it runs,
the finite N-sample trial from rest, not only on the N-periodic trial its frequency condition
proves.

Before: examples/two_mass_frf's design file said ``verdict = "holds"`` and ``check`` exited 0,
while the proof was for N-periodic trials only and, on the true plant, the 300-sample trial that
``learn`` runs had ||T_N||_2 = 1.45. Now the file's verdict and check's exit status are about
the finite trial: ``fails`` (a plant of the set has ||T_N||_2 = 1.18 > 1; on the true loop it is
1.22), the periodic proof is kept beside it with its scope in its name, and check exits 1.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from ilc_analysis.analysis import finite_trial_condition
from ilc_analysis.analysis._frf_finite_trial import periodic_data_bound
from ilc_analysis.cli.main import EXIT_FAILURE, EXIT_OK, main
from ilc_analysis.design import load_design, load_frf_design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.lifting._lti_lifting import block_toeplitz
from ilc_analysis.model import FrequencyResponseData, write_frf_csv
from ilc_analysis.synthesis import design_from_frf

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "two_mass_frf"
TS, N, SHIFT = 0.01, 32, 1
POLE = 0.8


def _first_order(count: int) -> np.ndarray:
    """g_0..g_{count-1} of 0.2 / (z - 0.8): g_0 = 0, g_j = 0.2 * 0.8^(j-1)."""
    g = np.zeros(count)
    g[1:] = 0.2 * POLE ** np.arange(count - 1)
    return g


#: the true tail after one period, sum_{j >= N} |g_j| = 0.8^(N-1)
TAIL = POLE ** (N - 1)


@pytest.fixture(scope="module")
def measured():
    """Five measurements of the first-order plant on the DFT bins of N = 32 (0.5 % complex
    noise), and the design made from them."""
    rng = np.random.default_rng(7)
    f = np.arange(N // 2 + 1) / (N * TS)
    z = np.exp(2j * np.pi * f * TS)
    G = 0.2 / (z - POLE)
    noise = (rng.standard_normal((5, f.size)) + 1j * rng.standard_normal((5, f.size))) / 2 ** .5
    frf = FrequencyResponseData.from_measurements(f, G * (1 + 0.005 * noise), TS)
    return frf, design_from_frf(frf, half_length=8, tail=TAIL)


def _random_member(frf, rng, boundary: bool) -> np.ndarray:
    """The Markov parameters g_0.. (3N of them) of a plant of the set with tail <= TAIL: its
    periodic impulse response is the mean's plus an error whose DFT lies in the discs (real at
    DC and Nyquist), and its impulse response after one period sums to TAIL at most."""
    r = frf.radius
    rho = np.ones(r.size) if boundary else np.sqrt(rng.uniform(0, 1, r.size))
    X = r * rho * np.exp(1j * rng.uniform(0, 2 * np.pi, r.size))
    X[[0, -1]] = r[[0, -1]] * rng.uniform(-1, 1, 2)
    periodic = np.fft.irfft(frf.response[:, 0, 0] + X, n=N)
    tail = rng.standard_normal(2 * N)
    tail *= rng.uniform(0, 1) * TAIL / np.abs(tail).sum()
    g = np.concatenate([periodic, tail])
    g[:N] -= tail[:N] + tail[N:]                 # the tail's aliases leave the bins unchanged
    return g


def test_the_upper_bound_covers_every_plant_of_the_set(measured):
    """With the tail stated, the verdict holds, and on 300 plants of the set (half on the disc
    boundaries, random tails below the bound) and on the true plant, ||T_N||_2 stays below the
    proven upper bound; the lower bound is attained by the mean's FIR plant."""
    frf, design = measured
    finite = design.finite
    assert finite.verdict == "holds" and design.certified
    assert finite.lower <= finite.upper < 1.0
    lifted = design.law.lifted
    rng = np.random.default_rng(35)
    worst = 0.0
    for k in range(300):
        g = _random_member(frf, rng, boundary=bool(k % 2))
        spectrum = np.fft.rfft(g[:N] + g[N:2 * N] + g[2 * N:], n=N)
        assert frf.inside(spectrum).all()
        G = block_toeplitz(g[SHIFT:SHIFT + N, None, None])
        T = _operator(lifted, G)
        worst = max(worst, np.linalg.norm(T, 2))
    assert worst <= finite.upper
    G_true = block_toeplitz(_first_order(N + SHIFT)[SHIFT:, None, None])
    assert np.linalg.norm(_operator(lifted, G_true), 2) <= finite.upper
    g_mean = np.fft.irfft(frf.response[:, 0, 0], n=N)
    G_mean = block_toeplitz(np.concatenate([g_mean[SHIFT:], [0.0]])[:, None, None])
    assert np.linalg.norm(_operator(lifted, G_mean), 2) == pytest.approx(finite.lower, rel=1e-9)


def _operator(lifted, G):
    from ilc_analysis.lifting import LiftedSystem

    ls = LiftedSystem(G=G, d=np.zeros(N), shift=SHIFT, ts=TS, N=N, n_u=1, n_y=1)
    return lifted(ls).operator(G)


def test_without_a_stated_tail_nothing_is_proven_above(measured):
    frf, design = measured
    finite = finite_trial_condition(frf, design.law, shift=SHIFT)
    assert finite.verdict == "unknown" and finite.upper is None
    assert "state a bound of it (tail)" in finite.reason
    assert finite.lower == pytest.approx(design.finite.lower, rel=1e-12)
    with pytest.raises(ParameterError, match="tail must be a finite number >= 0"):
        finite_trial_condition(frf, design.law, shift=SHIFT, tail=-1.0)
    with pytest.raises(ParameterError, match=r"trials of 1 to 32 samples"):
        finite_trial_condition(frf, design.law, 40, shift=SHIFT)


def test_the_data_bound_known_answers():
    """Zero radius: zero. A single bin: the interpolation kernel's sup is exactly r_0 at DC
    (the bound may exceed it only by the Bernstein factor and the dropped shift samples).
    A constant radius r: the Parseval bound sqrt(N) r caps it."""
    assert periodic_data_bound(np.zeros(17), 32, 1) == 0.0
    r = np.zeros(17)
    r[0] = 1.0
    eps = periodic_data_bound(r, 32, 0)
    assert 1.0 <= eps <= 1.0 / (1 - np.pi * 31 / (32 * 32)) * (1 + 1e-9)
    assert periodic_data_bound(np.ones(17), 32, 0) <= np.sqrt(32)
    # the bound is a bound: random errors with |X_k| <= r_k, their triangular Toeplitz norm
    rng = np.random.default_rng(2)
    r = rng.uniform(0, 1, 17)
    eps = periodic_data_bound(r, 32, 2)
    for _ in range(200):
        X = r * np.exp(1j * rng.uniform(0, 2 * np.pi, 17))
        X[[0, -1]] = r[[0, -1]] * np.sign(rng.standard_normal(2))
        x = np.fft.irfft(X, n=32)
        assert np.linalg.norm(block_toeplitz(np.concatenate([x[2:], [0, 0]])[:, None, None]),
                              2) <= eps


def test_the_example_is_judged_on_the_trial_it_runs(capsys):
    """examples/two_mass_frf: proven for the 300-periodic trial (peak 0.72), but the mean's FIR
    plant, a plant of the set, has ||T_N||_2 = 1.18 on the 300-sample trial (the true loop:
    1.22): the file's verdict is fails, check exits 1 and says which scope holds."""
    frf, law, cert, shift = load_frf_design(EXAMPLE / "design.toml")
    assert cert["quantity"] == "finite_trial_norm_2" and cert["verdict"] == "fails"
    assert cert["periodic"]["verdict"] == "holds" and cert["periodic"]["periodic_trial"] == 300
    assert cert["lower"] == pytest.approx(1.176, abs=1e-3)
    true = load_design(REPO / "examples" / "two_mass" / "design.toml").problem
    T_true = law.lifted(true.lifted).operator(np.asarray(true.lifted.G))
    assert np.linalg.norm(T_true, 2) > 1.0
    assert main(["check", str(EXAMPLE / "design.toml"), "--json"]) == EXIT_FAILURE
    report = json.loads(capsys.readouterr().out)
    assert report["reproduced"] and not report["holds"]
    assert report["outcome"].startswith("certificate reproduced: holds for the 300-periodic "
                                        "trial only")


def test_a_design_proven_for_its_trial_checks_with_exit_0(measured, tmp_path, capsys):
    """design-frf --tail on measurements of the first-order plant: the finite trial holds,
    design-frf and check exit 0; the same file without the tail is unknown (exit 1); a trial
    longer than the period is refused (exit 2, naming [problem].N)."""
    frf, _ = measured
    rng = np.random.default_rng(7)
    z = np.exp(2j * np.pi * frf.frequency_hz * TS)
    files = []
    for i in range(5):
        noise = (rng.standard_normal(z.size) + 1j * rng.standard_normal(z.size)) / 2 ** .5
        files.append(write_frf_csv(tmp_path / f"m{i}.csv", frf.frequency_hz,
                                   0.2 / (z - POLE) * (1 + 0.005 * noise)))
    out = tmp_path / "d.toml"
    argv = ["design-frf", *map(str, files), "--ts", "0.01", "--half-length", "8", "--out",
            str(out)]
    assert main([*argv, "--tail", f"{TAIL!r}"]) == EXIT_OK
    assert f"tail = {TAIL!r}" in out.read_text()
    capsys.readouterr()
    assert main(["check", str(out)]) == EXIT_OK
    assert "certificate reproduced and holds for the finite 32-sample trial" in \
        capsys.readouterr().out
    text = out.read_text()
    out.write_text(text.replace(f"tail = {TAIL!r}\n", ""))
    assert main(["check", str(out)]) == EXIT_FAILURE          # the stored verdict: holds
    assert "[certificate].verdict: stored 'holds', recomputed 'unknown'" in \
        capsys.readouterr().out
    out.write_text(text.replace("N = 32", "N = 40"))
    with pytest.raises(DesignFileError, match=r"\[problem\]\.N = 40: .* \(32 samples"):
        load_frf_design(out)
    assert main(["check", str(out)]) == 2


def test_the_example_file_is_what_measure_py_writes(tmp_path, monkeypatch):
    """design.toml is regenerated by its script: the same certificate and law."""
    import shutil

    shutil.copytree(EXAMPLE, tmp_path / "two_mass_frf")
    shutil.copytree(REPO / "examples" / "two_mass", tmp_path / "two_mass")
    sys.path.insert(0, str(tmp_path / "two_mass_frf"))
    try:
        sys.modules.pop("measure", None)
        import measure

        measure.design()
    finally:
        sys.path.remove(str(tmp_path / "two_mass_frf"))
        sys.modules.pop("measure", None)
    _, law_new, cert_new, _ = load_frf_design(tmp_path / "two_mass_frf" / "design.toml")
    _, law_old, cert_old, _ = load_frf_design(EXAMPLE / "design.toml")
    for key in ("nominal_norm_2", "gain_norm_2", "data_bound", "lower"):
        assert cert_new[key] == pytest.approx(cert_old[key], rel=1e-9)
    assert cert_new["periodic"]["value"] == pytest.approx(cert_old["periodic"]["value"],
                                                          rel=1e-9)
