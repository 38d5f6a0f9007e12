"""The committed study reports (examples/studies/*/report.md) are what their committed data say,
and the data are those of the committed study files."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from ilc_analysis.studies import load_study, open_results
from ilc_analysis.studies._report import compare_to_baseline, study_numbers

STUDIES = Path(__file__).resolve().parents[1] / "examples" / "studies"
NAMES = ["forgetting", "uncertainty"]


@pytest.mark.parametrize("name", NAMES)
def test_committed_results_are_the_committed_study(name):
    ds = open_results(STUDIES / name / "results.zarr")
    # the committed design's [plant] is a module plant of this toolkit: the opt-in
    study = load_study(STUDIES / f"{name}.toml", allow_code=True)
    assert ds.attrs["fingerprint"] == study.fingerprint()
    assert tuple(ds["error"].dims) == study.dims and ds["error"].shape == study.shape


@pytest.mark.parametrize("name", NAMES)
def test_report_numbers_are_recomputed_from_the_data(name):
    ds = open_results(STUDIES / name / "results.zarr")
    n = study_numbers(ds)
    summary = json.loads((STUDIES / name / "summary.json").read_text())
    assert summary["numbers"]["certified"] == n["certified"]
    assert summary["numbers"]["final_max_error"] == pytest.approx(n["final_max_error"],
                                                                  rel=1e-12)
    report = (STUDIES / name / "report.md").read_text()
    assert (f"**{n['certified']} of {n['points']} = {n['certified_fraction']:.1%}**"
            in report)
    assert f"median {n['final_max_error']['median']:.4g}" in report
    worst = n["worst"]["norm_2"]["value"]
    assert f"| norm_2 | {n['verdicts']['norm_2']} | {worst:.4g} |" in report


def test_forgetting_findings_quote_the_data():
    ds = open_results(STUDIES / "forgetting" / "results.zarr")
    report = (STUDIES / "forgetting" / "report.md").read_text()
    ratio, verdict = compare_to_baseline(ds, "final_max_error", "Lambda", 0.0)
    v = verdict.values.ravel()
    assert (f"helps {np.sum(v == 'holds')}, no difference {np.sum(v == 'marginal')}, hurts "
            f"{np.sum(v == 'fails')}") in report
    # the paper's point: 0.02597 (Lambda = 6) against 0.02599 (fixed)
    fe = ds["final_max_error"].sel(delta=0.85, amplitude=0.01)
    assert f"{float(fe.sel(Lambda=6.0)):.4g} m and {float(fe.sel(Lambda=0.0)):.4g} m" in report
    # "Lambda = 6: no difference at every (delta, A)": ratios within 1 %
    assert set(verdict.sel(Lambda=6.0).values.ravel()) == {"marginal"}
    r = ratio.sel(Lambda=6.0)
    assert f"ratios {float(r.min()):.3f} – {float(r.max()):.3f}" in report
    # "Lambda = 6000 ... 0.51 - 0.79 of the fixed law's for delta <= 0.85 and A <= 0.01"
    big = ratio.sel(Lambda=6000.0, delta=[0.7, 0.85], amplitude=[0.0, 0.01])
    assert re.search(rf"{float(big.min()):.2f} – {float(big.max()):.2f} of the fixed", report)
