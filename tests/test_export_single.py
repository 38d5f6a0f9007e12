"""Single precision with a proof (issue 38): the stated bounds hold on float32 runs.

The export states, for single precision, the rounding each trial adds at most (``per_trial``)
and the floor it adds to the input and tracking errors (``input_floor`` D*,
``tracking_floor``), proven from the certificate's contraction and a rounding analysis of the
generated operations (:mod:`ilc_analysis.export._rounding`). Checked here on the certified
operator (the lifted LTI plant of the design, exactly the model the certificate is about):

* each call of the float32 update is within ``per_trial`` of the exact update of the same
  last input and record (10 runs);
* a float32 learning run of 50 trials (the C update in float32 between trials; for the law
  with a current-trial part, its in-trial step in float32 per sample, emulated in numpy with
  the generated code's operations) stays within D* of the exact run of the same law (with a
  variable forgetting factor: the exact run with the factors the float run's errors give, the
  run the certificate's per-sample bound covers), and its tracking error within the tracking
  floor.

And single precision is refused where no proof is possible: a certificate that is not a
2-norm contraction, a margin the rounding's growth is not absorbed by, a law without a
rounding analysis (time reversal), a design without a certificate.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from conftest import LAW_FACTORIES, mimo_problem, siso_problem
from export_support import build, host_update, needs_compiler

from ilc_analysis.design import Design
from ilc_analysis.exceptions import ExportRefusedError
from ilc_analysis.export import export
from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QFilter,
    VariableForgetting,
)
from ilc_analysis.problem import ILCProblem

F32 = np.float32


def _robot_like(pr) -> PDLaw:
    """The paper's proposed law in small: variable forgetting (eq 12), lead, DCT Q, u0."""
    eye, zero = np.eye(pr.n_u, pr.n_y), np.zeros((pr.n_u, pr.n_y))
    return PDLaw(PDGains(Phi1=0.05 * eye, Phi2=zero, Psi1=0.5 * eye, Psi2=zero, lead=1),
                 VariableForgetting(0.85, 6.0), QFilter.dct(1.0), u0=[0.1] * pr.n_u)


def _with_feedback(pr) -> PDLaw:
    eye, zero = np.eye(pr.n_u, pr.n_y), np.zeros((pr.n_u, pr.n_y))
    return PDLaw(PDGains(Phi1=zero, Phi2=0.05 * eye, Psi1=0.6 * eye, Psi2=0.3 * eye, lead=1),
                 FixedForgetting(0.05), QFilter.butterworth(1.0, 2))


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    """Both designs certified, exported in single precision and built."""
    pr = mimo_problem()
    out = {}
    for name, law in (("robot-like", _robot_like(pr)), ("feedback", _with_feedback(pr))):
        design = Design(pr, law).certify()
        assert design.certificate["verdict"] == "holds"
        d = tmp_path_factory.mktemp("single") / name
        result = export(design, d, precision="single")
        out[name] = (pr, law, result, d)
    return out


def _lifted(pr, law):
    ls = pr.lifted
    ll = law.lifted(ls)
    def dense(M):
        return (None if M is None else (M.toarray() if hasattr(M, "toarray")
                                                   else np.asarray(M)))
    Q = dense(ll.Q)
    return ls.G, dense(ll.L1), dense(ll.L2), np.eye(ls.N * ls.n_u) if Q is None else Q


def test_the_stated_bound_is_proven_and_named(single):
    for _name, (_, _, result, d) in single.items():
        rb = result.rounding
        assert rb is not None and rb.unit_roundoff == 2.0 ** -24
        assert rb.tau < 1 and rb.slope < 1
        assert rb.input_floor * (1 - rb.tau) >= rb.per_trial       # the induction's step
        assert rb.tracking_floor == pytest.approx(rb.norms["G"] * rb.input_floor)
        header = (d / "ilc_law.h").read_text()
        assert "typedef float ilc_real;" in header and "with a proof" in header
        assert f"{rb.input_floor:.3g}" in header.replace("\n *             ", " ")
        source = (d / "ilc_law.c").read_text()
        assert source.count("f,") > 10           # the constants are float literals


@needs_compiler
def test_each_float_call_is_within_the_per_trial_bound(single, tmp_path):
    pr, law, result, d = single["robot-like"]
    host = build(d)
    G, _, _, _ = _lifted(pr, law)
    r = np.asarray(pr.r)
    rng = np.random.default_rng(0)
    worst = 0.0
    ff = F32(pr.initial_input()).astype(float)
    for _ in range(10):
        e = r - G @ ff.reshape(-1)
        y = np.zeros((pr.N + pr.shift, pr.n_y))
        y[pr.shift:] = (pr.reference.reshape(-1) - e).reshape(pr.N, pr.n_y)
        got = host_update(host, tmp_path, pr, ff, y)
        exact = law.update(ff, pr.reference - y[pr.shift:], pr.ts)
        worst = max(worst, float(np.linalg.norm(got - exact)))
        ff = got + F32(1e-3) * rng.standard_normal(got.shape).astype(F32)   # another input
    assert 0.0 < worst <= result.rounding.per_trial


@needs_compiler
def test_a_float_run_of_50_trials_stays_within_the_floor(single, tmp_path):
    """The float32 run (C update) against the exact run with the same forgetting factors."""
    pr, law, result, d = single["robot-like"]
    host = build(d)
    G, L1, _, Q = _lifted(pr, law)
    r = np.asarray(pr.r)
    u0 = law.u0_trial(pr.N, pr.n_u).reshape(-1)
    ff = F32(pr.initial_input()).astype(float)                    # the float machine
    exact = np.array(pr.initial_input(), dtype=float).reshape(-1)
    distance, tracking = [], []
    for _ in range(50):
        e = r - G @ ff.reshape(-1)                                # its trial, exactly
        y = np.zeros((pr.N + pr.shift, pr.n_y))
        y[pr.shift:] = (pr.reference.reshape(-1) - e).reshape(pr.N, pr.n_y)
        nxt = host_update(host, tmp_path, pr, ff, y)
        A = np.repeat(law.forgetting.factor(e.reshape(pr.N, pr.n_y)), pr.n_u)
        exact = Q @ ((1 - A) * exact + A * u0 + L1 @ (r - G @ exact))
        ff = nxt
        distance.append(np.linalg.norm(ff.reshape(-1) - exact))
        tracking.append(np.linalg.norm(G @ (ff.reshape(-1) - exact)))
    rb = result.rounding
    assert max(distance) <= rb.input_floor
    assert max(tracking) <= rb.tracking_floor
    assert max(distance) > 0.0                       # the float run did round


def _float_trial(pr, law, ff, dplant):
    """One trial with the in-trial step in float32 (the generated ilc_step's operations, in
    numpy float32), on the LTI plant from rest: the applied input and the record."""
    A, B, C, D, _ = dplant.matrices
    per = law.gains.per_sample(pr.N)
    psi2, phi2 = per["Psi2"].astype(F32), per["Phi2"].astype(F32)
    ref = pr.reference.astype(F32)
    ts = F32(pr.ts)
    x = np.zeros(A.shape[0])
    K = pr.N + pr.shift
    u = np.zeros((pr.N, pr.n_u))
    y = np.zeros((K, pr.n_y))
    e_prev = np.zeros(pr.n_y, dtype=F32)
    for k in range(K):
        yk = C @ x
        y[k] = yk
        if k < pr.N:
            et = (ref[k - pr.shift] - yk.astype(F32)) if k >= pr.shift else \
                np.zeros(pr.n_y, dtype=F32)
            uk = np.empty(pr.n_u, dtype=F32)
            for i in range(pr.n_u):
                acc_p, acc_d = F32(0), F32(0)
                for j in range(pr.n_y):
                    acc_p = F32(acc_p + psi2[k, i, j] * et[j])
                    acc_d = F32(acc_d + phi2[k, i, j] * F32(F32(et[j] - e_prev[j]) / ts))
                uk[i] = F32(F32(F32(ff[k, i]) + acc_p) + acc_d)
            e_prev = et
            u[k] = uk
            x = A @ x + B @ uk.astype(float)
            assert not np.any(D)
    return u, y


@needs_compiler
def test_a_float_run_with_a_current_trial_part_stays_within_the_floor(single, tmp_path):
    pr, law, result, d = single["feedback"]
    host = build(d)
    G, L1, L2, Q = _lifted(pr, law)
    r = np.asarray(pr.r)
    assert not np.any(pr.lifted.d)                  # the plant from rest: d = 0
    S = np.linalg.inv(np.eye(G.shape[1]) + L2 @ G)
    a = law.forgetting.a
    ff = F32(pr.initial_input()).astype(float)
    exact = S @ (np.array(pr.initial_input()).reshape(-1) + L2 @ r)     # applied input
    distance = []
    for _ in range(50):
        u, y = _float_trial(pr, law, ff, pr.dplant)
        distance.append(np.linalg.norm(u.reshape(-1) - exact))
        ff = host_update(host, tmp_path, pr, ff, y)
        ff_exact = Q @ ((1 - a) * exact + L1 @ (r - G @ exact))
        exact = S @ (ff_exact + L2 @ r)
    assert max(distance) <= result.rounding.input_floor
    assert max(distance) > 0.0


# ---------------------------------------------------------------------------------------------
# refused: where no proof is possible
# ---------------------------------------------------------------------------------------------
def test_a_certificate_that_is_no_contraction_is_refused(tmp_path):
    """Gradient ILC on a plant with more inputs than outputs: the tracking error is proven
    non-increasing (``error_norm_2``), but T = I - beta G'G has the eigenvalue 1."""
    plant = control.ss([[-1.0, 0.0], [0.0, -2.0]], [[1.0, 0.5], [0.2, 1.0]], [[1.0, 1.0]],
                       [[0.0, 0.0]])
    pr = ILCProblem(plant, 0.2, 16, np.sin(np.linspace(0.0, 3.0, 16))[:, None], name="wide")
    law = GradientLaw(0.5 * 2.0 / np.linalg.norm(pr.lifted.G, 2) ** 2, pr.lifted)
    design = Design(pr, law).certify()
    assert design.certificate["quantity"] == "error_norm_2"
    assert design.certificate["verdict"] == "holds"
    with pytest.raises(ExportRefusedError, match=r"not make the trial-to-trial operator a "
                                                 r"contraction in the 2-norm \(norm_2 = 1 >= 1; "
                                                 r"it certifies error_norm_2\)"):
        export(design, tmp_path / "c", precision="single")
    assert not (tmp_path / "c").exists()
    export(design, tmp_path / "d", measure=False)        # double precision is fine


def test_a_margin_that_does_not_absorb_the_rounding_is_refused(tmp_path):
    pr = siso_problem()
    law = NormOptimalLaw(pr.lifted, weight_input_change=10.0)     # ||T||_2 = 1 - 5e-8
    design = Design(pr, law).certify()
    assert design.certificate["verdict"] == "holds"
    with pytest.raises(ExportRefusedError, match=r"margin 1 - tau = 5\.\d+e-08 .* does not "
                                                 r"absorb the rounding"):
        export(design, tmp_path / "m", precision="single")


def test_time_reversal_and_uncertified_designs_are_refused_in_single(tmp_path):
    pr = siso_problem()
    tr = Design(pr, LAW_FACTORIES["time-reversal"](pr)["time-reversal"]).certify()
    with pytest.raises(ExportRefusedError, match="no rounding analysis"):
        export(tr, tmp_path / "t", precision="single")
    bare = Design(pr, LAW_FACTORIES["pd"](pr)["pd"])
    with pytest.raises(ExportRefusedError, match="rests on the certificate's contraction"):
        export(bare, tmp_path / "u", precision="single", uncertified=True)
