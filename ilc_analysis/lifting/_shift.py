r"""The sampled relative degree: the shift s of the lifted output window.

For a sampled plant :math:`x(k+1) = F(x,u,w,t)`, :math:`y = h(x,u,t)` linearised to
:math:`(A_d, B_d, C, D)`, the Markov parameters are :math:`h_0 = D`,
:math:`h_m = C A_d^{m-1} B_d`. The shift is

.. math::

    s = \min\{m \ge 0 : h_m \ne 0\},

the first sample at which any output responds to the input. Zero-order-hold sampling of a
continuous plant of any relative degree gives s = 1 (e.g. :math:`C B_d \approx C A B\,T_s^2/2
\ne 0` for the robot, whose continuous :math:`CB = 0`); s = 0 means direct feedthrough.
"""

from __future__ import annotations

import casadi as ca
import control
import numpy as np

from .._validation import as_vector
from ..exceptions import ParameterError
from ..model import DiscretePlant, relative_degree
from ._validation import check_dplant

__all__ = ["sampled_shift", "discrete_linearization"]

#: Relative tolerance below which a Markov row counts as zero (as in ``relative_degree``).
SHIFT_RTOL = 1e-10


def discrete_linearization(dplant: DiscretePlant, x=None, u=None, t: float = 0.0):
    r"""The matrices :math:`(A_d, B_d, C, D)` of ``dplant`` at ``(x, u, t)`` (w = 0).

    Exact stored matrices for linear plants; CasADi Jacobians of the compiled step and output
    map otherwise: :math:`A_d = \partial F/\partial x`, :math:`B_d = \partial F/\partial u`,
    :math:`C = \partial h/\partial x`, :math:`D = \partial h/\partial u`.

    Parameters
    ----------
    dplant : ~ilc_analysis.model.DiscretePlant
        The sampled plant.
    x : array_like, shape (n_x,), optional
        State (default: zero).
    u : array_like, shape (n_u,), optional
        Input (default: zero).
    t : float, optional
        Time [s].
    """
    dplant = check_dplant(dplant)
    if dplant.matrices is not None:
        Ad, Bd, C, D, _ = dplant.matrices
        return Ad, Bd, C, D
    x = np.zeros(dplant.n_x) if x is None else as_vector(x, "x", dplant.n_x)
    u = np.zeros(dplant.n_u) if u is None else as_vector(u, "u", dplant.n_u)
    xs = ca.MX.sym("x", dplant.n_x)
    us = ca.MX.sym("u", dplant.n_u)
    w0 = ca.DM.zeros(dplant.n_x)
    xn = dplant.step(xs, us, w0, float(t))
    y = dplant.output(xs, us, float(t))
    jac = ca.Function("discrete_jacobians", [xs, us], [ca.jacobian(xn, xs), ca.jacobian(xn, us),
                                        ca.jacobian(y, xs), ca.jacobian(y, us)])
    return tuple(np.asarray(M, dtype=float) for M in jac(x, u))


def sampled_shift(dplant: DiscretePlant, *, x=None, u=None, t: float = 0.0,
                  rtol: float = SHIFT_RTOL) -> int:
    r"""The sampled relative degree s of ``dplant`` (smallest over the outputs).

    Parameters
    ----------
    dplant : DiscretePlant
    x, u : array_like, optional
        Point of the linearisation for nonlinear plants (default: zero).
    t : float
        Time of that point.
    rtol : float
        A Markov row counts as zero below ``rtol`` times its scale (see
        :func:`ilc_analysis.model.relative_degree`).

    Returns
    -------
    int
        s >= 1 for strictly proper plants, 0 with direct feedthrough.

    Raises
    ------
    ParameterError
        If no output responds to the input within ``n_x`` samples (s undefined).
    """
    Ad, Bd, C, D = discrete_linearization(dplant, x, u, t)
    sys = control.ss(Ad, Bd, C, D, dplant.ts)
    degrees = [r for r in relative_degree(sys, rtol) if r is not None]
    if not degrees:
        raise ParameterError(f"no output of {dplant.name} responds to the input within "
                             f"{dplant.n_x} samples at this point; the shift is undefined "
                             "(pass shift= explicitly, or linearise at another point)")
    return int(min(degrees))
