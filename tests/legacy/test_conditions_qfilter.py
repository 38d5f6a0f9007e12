"""The analysis includes the law's Q-filter: its T and error floor are what the simulation does."""

import control
import numpy as np
import pytest
from legacy_form import analyse

from ilc_analysis.exceptions import DegenerateConditionWarning
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import Plant, discretize
from ilc_analysis.simulation._engine import simulate_plant


def _plant():
    # a stable two-mass-like SISO plant, relative degree 2
    A = np.array([[0.0, 1.0], [-4.0, -1.2]])
    return Plant.from_statespace(control.ss(A, [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]]))


def test_filtered_floor_and_norm_match_simulation():
    plant, ts, N, a = _plant(), 0.05, 60, 0.1
    q = QFilter.dct(2.0)
    gains = PDGains([[0.0]], [[0.0]], [[1.0]], [[0.0]], lead=3)  # norm_2 = 0.89 here
    u_d = 0.5 + 0.3 * np.sin(np.linspace(0, 3, N))[:, None]
    u0 = np.zeros((N, 1))
    dp = discretize(plant, ts)
    # the reference produced by u_d (realisable by construction)
    lifted = lift(dp, N, x0=np.zeros(2))
    y_d = lifted.predict(u_d).reshape(N, 1)
    with pytest.warns(DegenerateConditionWarning, match="relative degree y\\[0\\]: 2"):
        rep = analyse(plant, gains, FixedForgetting(a), ts=ts, N=N, x0=np.zeros(2),
                      u_nominal=u_d, delta_u0=u_d - u0, q_filter=q, lifted=lifted)
    cond = {c.name: c for c in rep.conditions}
    assert cond["norm_2"].verdict == "holds"
    law = PDLaw(gains, FixedForgetting(a), q_filter=q, u0=u0)
    res = simulate_plant(dp, law, y_d, 400, np.zeros(2))
    e_last = res.dataset["e"].isel(iteration=-1).values.ravel()
    np.testing.assert_allclose(np.linalg.norm(e_last), cond["error_floor"].value, rtol=1e-6)
    # monotone in the 2-norm of the input error to the fixed point, as norm_2 < 1 promises
    u = res.dataset["u"].values.reshape(res.dataset.sizes["iteration"], -1)
    dist = np.linalg.norm(u - u[-1], axis=1)[:-1]
    assert np.all(np.diff(dist) <= 1e-12 * dist[0])
