r"""Stored N = 200 synthesis results of an earlier implementation (tests only).

The speed work of issue 16 replaces the solvers behind :func:`ilc_analysis.synthesis.
synthesize_lifted`; the certificates at N = 200 must agree with the previous implementation's to
1e-6 where both exist. The numbers are computed by the code, never typed in: this module is
both the definition of the cases (used by ``tests/test_synthesis_speed.py`` with the current
code) and their generator. Run it against a checkout of the implementation to record::

    git archive <commit> | tar -x -C /tmp/old
    PYTHONPATH=/tmp/old .venv/bin/python tests/synthesis_speed_reference.py <commit> CASE...

which merges the cases' numbers into ``tests/synthesis_speed_reference.json`` with the commit.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

REFERENCE_FILE = Path(__file__).with_name("synthesis_speed_reference.json")
TS = 0.01


def circle_lifting(N: int):
    """The balanced robot lifted along the paper's circle (as ``benchmarks/bench_synthesis``)."""
    from ilc_analysis.lifting import lift
    from ilc_analysis.model import balanced_mobile_robot, discretize
    from ilc_analysis.paper import circle_nominal

    plant = balanced_mobile_robot()
    nominal = circle_nominal(plant, N, TS)
    return lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)


def scenario_lifting():
    """The packaged paper scenario, its lifted model and realisable input."""
    from ilc_analysis.paper._config import paper_scenario
    from ilc_analysis.paper._pipeline import scenario_lifting as lifting
    from ilc_analysis.paper._pipeline import scenario_model

    sc = paper_scenario()
    dplant, x0, shift, y_d = scenario_model(sc)
    reference, lifted = lifting(sc, dplant, x0, shift, y_d)
    return sc, lifted, reference.u_d


def _numbers(res) -> dict:
    cert, det = res.certificate, res.details
    return {"status": res.status, "value": cert.get("value"),
            "lower_bound": cert.get("lower_bound"), "mean_square": det.get("mean_square"),
            "psi1_sup": float(np.max(np.abs(res.gains.Psi1))) if res.gains else None,
            "phi1_sup": float(np.max(np.abs(res.gains.Phi1))) if res.gains else None}


def case_scenario_N200() -> dict:
    """The paper scenario's synthesis (time-varying, DCT Q, bounds, overshoot 0.5), with its
    gains (the test evaluates the mean-square objective at both solutions)."""
    from ilc_analysis.paper._synthesis_step import synthesize_scenario_gains

    sc, lifted, _ = scenario_lifting()
    res = synthesize_scenario_gains(sc, lifted).result
    return {**_numbers(res), "Psi1": res.gains.Psi1.tolist(), "Phi1": res.gains.Phi1.tolist()}


def case_ti_worst_N200() -> dict:
    """Time-invariant minimax on the circle lifting, forgetting 0.15 (``synth_lifted_N200``)."""
    from ilc_analysis.synthesis._lifted import synthesize_lifted

    return _numbers(synthesize_lifted(circle_lifting(200), forgetting=0.15))


def case_tv_mean_N200() -> dict:
    """Time-varying mean-square under max ||T||_2 <= 0.99, no Q-filter, forgetting 0.15."""
    import warnings

    from ilc_analysis.synthesis._lifted import synthesize_lifted

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = synthesize_lifted(circle_lifting(200), forgetting=0.15, time_varying=True,
                                objective="mean", target=0.99)
    return _numbers(res)


def case_lead_scan() -> dict:
    """The scenario's full lead scan: certificate and predicted ratio per lead, the best."""
    from ilc_analysis.paper._lead_scan import DEFAULT_LEADS, scenario_lead_scan

    scan = scenario_lead_scan()
    return {"leads": list(DEFAULT_LEADS),
            "values": [r.certificate.get("value") for r in scan.results],
            "ratios": list(scan.ratios), "best_lead": scan.best_lead}


CASES = {"scenario_N200": case_scenario_N200, "ti_worst_N200": case_ti_worst_N200,
         "tv_mean_N200": case_tv_mean_N200, "lead_scan": case_lead_scan}


def load_reference() -> dict:
    """The stored numbers ({} if none are stored)."""
    return json.loads(REFERENCE_FILE.read_text()) if REFERENCE_FILE.exists() else {}


def main(argv: list[str]) -> None:
    commit, names = argv[0], argv[1:] or list(CASES)
    for name in names:
        t0 = time.perf_counter()
        numbers = CASES[name]()
        numbers["seconds"] = round(time.perf_counter() - t0, 2)
        numbers["commit"] = commit
        stored = load_reference()
        stored[name] = numbers
        REFERENCE_FILE.write_text(json.dumps(stored, indent=1, sort_keys=True) + "\n")
        sys.stdout.write(f"{name}: {numbers}\n")


if __name__ == "__main__":
    main(sys.argv[1:])
