r"""A slow, independent reference implementation of eq (11) with scipy's ``solve_ivp``.

It shares nothing with the compiled engine except the law's parameters and the disturbance
realisation: the continuous dynamics :math:`\dot x = f(x, u, t) + \omega(k)` are integrated by
``solve_ivp`` over each sample with the input held, the current-trial feedback is evaluated in a
Python loop sample by sample, and the between-trial update of eq (11) is written out index by
index. It exists to validate :func:`~ilc_analysis.simulation.simulate` (which must agree with it
to the integrators' accuracy: a test oracle, not public) and as the baseline of the benchmark.
Do not use it for studies: it is hundreds of times slower.
"""

from __future__ import annotations

import numpy as np
import scipy.integrate

from .._validation import MAX_ITERATIONS, as_finite_array, as_vector, positive, positive_int, real
from ..exceptions import ParameterError
from ..laws import PDLaw
from ..model import Plant
from ..problem._disturbances import NO_DISTURBANCES, Disturbances

__all__ = ["simulate_reference"]


def simulate_reference(plant: Plant, law: PDLaw, y_d, iterations: int, x0, *,
                       ts: float, shift: int, t0: float = 0.0,
                       disturbances: Disturbances | None = None, rtol: float = 1e-9,
                       atol: float = 1e-11, method: str = "RK45") -> dict[str, np.ndarray]:
    r"""Simulate eq (11) on the continuous ``plant`` stepping ``solve_ivp`` sample by sample.

    Same conventions as :func:`~ilc_analysis.simulation.simulate` (lifted window, shift,
    zero-order hold, held input after the last lifted sample). No divergence handling.

    Parameters
    ----------
    plant : Plant
        The continuous plant; its ``dynamics`` and ``output`` functions are evaluated.
    law : PDLaw
        The only law implemented here (gains, lead, forgetting, Q-filter); its ``u0`` is
        required: the first trial's feed-forward and the input the forgetting pulls towards.
    y_d : array_like, shape (N, n_y)
        Reference on the lifted output window (times :func:`window_times`); finite.
    iterations : int
        Number of trials, 1 to :data:`~ilc_analysis._validation.MAX_ITERATIONS`.
    x0 : array_like, shape (n_x,)
        Initial state of every trial (before reset errors).
    ts : float
        Sample time [s] (> 0).
    shift : int
        Sampled relative degree s >= 1 (not computed here: give the engine's).
    t0 : float, optional
        Time of the first sample [s] (default 0).
    disturbances : Disturbances, optional
        State/output disturbances, noise and reset errors; none by default. The realisation
        is the engine's for the same seed.
    rtol, atol : float, optional
        Relative and absolute tolerances of ``solve_ivp`` (defaults 1e-9, 1e-11).
    method : str, optional
        Integration method of ``scipy.integrate.solve_ivp`` (default ``'RK45'``).

    Returns
    -------
    dict
        ``u`` (iterations, N, n_u), ``y``, ``e`` (iterations, N, n_y) on the window,
        ``x`` (iterations, N, n_x) on the window, ``a`` (iterations, N).

    Raises
    ------
    ParameterError, ShapeError
        A plant that is not a continuous :class:`~ilc_analysis.model.Plant`, a law that is
        not a :class:`~ilc_analysis.laws.PDLaw` with ``u0``, or inputs that do not fit the
        plant.
    """
    if not isinstance(plant, Plant):
        raise ParameterError(f"plant must be a continuous Plant; got {type(plant).__name__}")
    if not isinstance(law, PDLaw):
        raise ParameterError(f"law must be a PDLaw (the reference implements eq 11 only); got "
                             f"{type(law).__name__}")
    if law.u0 is None:
        raise ParameterError("law.u0 is required by the reference (the first trial's "
                             "feed-forward): give PDLaw(..., u0=...)")
    iterations = positive_int(iterations, "iterations", maximum=MAX_ITERATIONS)
    ts, shift = positive(ts, "ts"), positive_int(shift, "shift")
    t0 = real(t0, "t0")
    x0 = as_vector(x0, "x0", plant.n_x)
    y_d = as_finite_array(y_d, "y_d", shape=(None, plant.n_y))
    dist_model = NO_DISTURBANCES if disturbances is None else disturbances
    N, n_u, n_y, n_x = y_d.shape[0], plant.n_u, plant.n_y, plant.n_x
    law.check_trial(N, n_u, n_y)
    g = law.gains.per_sample(N)
    lead = law.gains.lead
    u0 = law.u0_trial(N, n_u)
    t = t0 + ts * np.arange(N + shift)
    f, h = plant.dynamics, plant.output
    entropy = dist_model.root_entropy()

    out = {"u": np.zeros((iterations, N, n_u)), "y": np.zeros((iterations, N, n_y)),
           "e": np.zeros((iterations, N, n_y)), "x": np.zeros((iterations, N, n_x)),
           "a": np.zeros((iterations, N))}
    ff = u0.copy()
    for i in range(iterations):
        dist = dist_model.realise(i + 1, t, n_x, n_y, entropy)
        x = x0 + dist.reset
        e_prev = np.zeros(n_y)
        u = np.zeros(n_u)
        for k in range(N + shift):
            y = np.asarray(h(x, ff[min(k, N - 1)], t[k])).ravel() + dist.nu[k]
            e = y_d[k - shift] - y if k >= shift else np.zeros(n_y)
            if k < N:
                u = ff[k] + g["Psi2"][k] @ e + g["Phi2"][k] @ ((e - e_prev) / ts)
                out["u"][i, k] = u
            if k >= shift:
                out["y"][i, k - shift], out["e"][i, k - shift] = y, e
                out["x"][i, k - shift] = x
            e_prev = e
            if k == N + shift - 1:
                break
            wk = dist.w[k]

            def rhs(tt, xx, u=u, wk=wk):
                return np.asarray(f(xx, u, tt)).ravel() + wk

            sol = scipy.integrate.solve_ivp(rhs, (t[k], t[k] + ts), x, method=method,
                                            rtol=rtol, atol=atol)
            x = sol.y[:, -1]
        # between trials, eq (11) written out sample by sample
        e_i, u_i = out["e"][i], out["u"][i]
        ff = np.zeros((N, n_u))
        for k in range(N):
            a = float(law.forgetting.factor(e_i[k][None, :])[0])
            out["a"][i, k] = a
            j = k + lead
            ej = e_i[j] if j < N else np.zeros(n_y)
            ejm = e_i[j - 1] if 0 <= j - 1 < N else np.zeros(n_y)
            ff[k] = (a * u0[k] + (1 - a) * u_i[k] + g["Psi1"][k] @ ej
                     + g["Phi1"][k] @ ((ej - ejm) / ts))
        if law.q_filter is not None:
            ff = law.q_filter.apply(ff, ts)
    return out
