"""The old call form ``simulate(dplant, law, y_d, iterations, x0)`` and the old law
``OpenClosedLoopPDLaw``: for one release they still run (the same trials as ``simulate_plant``
with a PDLaw and as ``simulate(problem, law, iterations)``) and warn ILCDeprecationWarning naming
the new form."""

from __future__ import annotations

import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ILCDeprecationWarning
from ilc_analysis.laws import PDGains, PDLaw
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._laws import OpenClosedLoopPDLaw

N, TS = 30, 0.05


def _problem() -> ILCProblem:
    t = TS * np.arange(N)
    return ILCProblem(control.tf([1.0], [1.0, 1.0, 1.0]), ts=TS, N=N,
                      reference=np.sin(2 * np.pi * t / (N * TS))[:, None])


def test_old_form_warns_naming_the_new_form_and_forwards():
    pr = _problem()
    law = PDLaw.p_type([[0.8]], [0.0])
    with pytest.warns(ILCDeprecationWarning, match=r"simulate\(problem, law, iterations\)"):
        old = simulate(pr.dplant, law, pr.reference, 3, pr.x0, shift=pr.shift)
    plant_form = simulate_plant(pr.dplant, law, pr.reference, 3, pr.x0, shift=pr.shift)
    np.testing.assert_array_equal(old.dataset["u"].values, plant_form.dataset["u"].values)
    np.testing.assert_array_equal(old.dataset["e"].values, plant_form.dataset["e"].values)


def test_old_signature_is_unchanged_and_counts_one_run_per_iteration():
    pr = _problem()
    with pytest.warns(ILCDeprecationWarning, match=r"OpenClosedLoopPDLaw is deprecated.*"
                      r"ilc_analysis\.laws\.PDLaw") as caught:
        old = OpenClosedLoopPDLaw.p_type([[0.8]], [0.0])
    assert len(caught) == 1                     # the classmethod warns once, through __init__
    with pytest.warns(ILCDeprecationWarning):
        res = simulate(pr.dplant, old, pr.reference, 3, pr.x0, shift=pr.shift)
    new = simulate(pr, PDLaw(PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.8]], Psi2=[[0.0]])),
                   3)
    np.testing.assert_array_equal(res.dataset["u"].values, new.dataset["u"].values)
    np.testing.assert_array_equal(res.dataset["experiments"].values, [1, 1, 1])


def test_old_form_accepts_the_one_pd_law():
    """PDLaw (with u0) runs in the plant form exactly as the old OpenClosedLoopPDLaw did."""
    pr = _problem()
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.2]], Psi1=[[0.8]], Psi2=[[0.1]])
    with pytest.warns(ILCDeprecationWarning):
        a = simulate(pr.dplant, PDLaw(gains, u0=[0.3]), pr.reference, 3, pr.x0)
    with pytest.warns(ILCDeprecationWarning, match="OpenClosedLoopPDLaw"):
        old = OpenClosedLoopPDLaw(gains, PDLaw(gains).forgetting, [0.3])
    b = simulate_plant(pr.dplant, old, pr.reference, 3, pr.x0)
    np.testing.assert_array_equal(a.dataset["u"].values, b.dataset["u"].values)
