r"""The frequency-domain picture of a time-invariant PD law on an LTI plant: T on a grid.

For a sampled LTI plant G(z) and time-invariant gains the law (11) has the transfer matrices
(index convention of :mod:`ilc_analysis.laws`, as in
:func:`ilc_analysis.analysis.frequency_condition`)

.. math::

    L_1(z) = z^{s+\ell}\big(\Psi_1 + \Phi_1 d(z)\big),\qquad
    L_2(z) = \Psi_2 + \Phi_2 d(z),\qquad d(z) = (1 - z^{-1})/T_s,

and trial to trial, with the zero-phase Q-filter's real response q,

.. math::

    T(e^{j\theta}) = q(\theta)\,S(e^{j\theta})\big((1-a)I - L_1(e^{j\theta})G(e^{j\theta})\big),
    \qquad S = (I + L_2G)^{-1}.

With :math:`L_2` fixed, T is **affine** in the free gains :math:`x = (\mathrm{vec}\,\Psi_1,
\mathrm{vec}\,\Phi_1)` (the order of :class:`~.structure.PDStructure`):
:math:`T_k(x) = A_k - \sum_p x_p C_{k,p}` at each grid point :math:`\theta_k`
(:func:`response_family`). This is the symbol of the lifted operator :math:`T_N` of a long
trial: for a causal, time-invariant law :math:`T_N` is a compression of the Laurent operator of
this symbol, and in general the bulk of :math:`T_N`, away from the trial's two ends, acts on a
sinusoid of frequency :math:`\theta` as :math:`T(e^{j\theta})`. The ends (a lead reads past the
trial; the plant starts at rest; a zero-phase filter reflects the signal) are not in it: the
design that uses it (:mod:`.trial_design`) adds them from the trial's own operator.

The DCT Q-filter (:meth:`~ilc_analysis.laws.QFilter.dct`) has no transfer function (it is
defined on the finite trial), but it multiplies the DCT component of frequency f by
:math:`1/(1 + (f/f_c)^{2n})`; :func:`design_q_response` takes that gain as its response on the
grid. That is a model for the design, not a certificate: the certificate is always computed on
the trial (:mod:`.trial_design`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ParameterError

__all__ = ["plant_response", "response_family", "design_grid", "design_q_response",
           "DESIGN_FREQUENCIES", "LOW_FREQUENCY_POINTS", "LOW_FREQUENCY_DECADE"]

#: Grid points of the design (uniform cell midpoints of [0, pi]; fewer for a short trial: its
#: DFT resolution, N // 2 + 1).
DESIGN_FREQUENCIES = 256
#: Log-spaced points added below the uniform grid (towards theta = 0): an integrating plant
#: makes T grow like 1/theta there unless the gains cancel it.
LOW_FREQUENCY_POINTS = 16
#: They reach this factor below the first uniform point, divided by four.
LOW_FREQUENCY_DECADE = 10.0


def design_grid(n_points: int) -> np.ndarray:
    r"""The grid :math:`\theta_k` [rad/sample]: ``n_points`` cell midpoints
    :math:`\pi(k + 1/2)/K` of :math:`[0, \pi]` (the grid of
    :func:`~ilc_analysis.analysis.frequency_condition`) and :data:`LOW_FREQUENCY_POINTS`
    log-spaced points below the first one, down to :math:`\theta_0 / (4\cdot`
    :data:`LOW_FREQUENCY_DECADE` :math:`)`.

    Parameters
    ----------
    n_points : int
        The uniform points K (>= 1).

    Returns
    -------
    ndarray
        Increasing angles, ``(LOW_FREQUENCY_POINTS + K,)``.
    """
    theta = np.pi * (np.arange(n_points) + 0.5) / n_points
    low = np.geomspace(theta[0] / (4 * LOW_FREQUENCY_DECADE), theta[0], LOW_FREQUENCY_POINTS,
                       endpoint=False)
    return np.concatenate([low, theta])


def plant_response(dsys, theta) -> np.ndarray:
    r""":math:`G(e^{j\theta})` of a discrete state-space system at every grid angle.

    Parameters
    ----------
    dsys : control.StateSpace
        Discrete-time LTI system (A, B, C, D).
    theta : ndarray
        Angles [rad/sample].

    Returns
    -------
    ndarray
        ``(K, n_y, n_u)`` complex.
    """
    A, B, C, D = (np.asarray(M, dtype=float) for M in (dsys.A, dsys.B, dsys.C, dsys.D))
    z = np.exp(1j * np.asarray(theta, dtype=float))
    if A.shape[0] == 0:
        return np.broadcast_to(D.astype(complex), (len(z),) + D.shape).copy()
    X = np.linalg.solve(z[:, None, None] * np.eye(A.shape[0]) - A,
                        np.broadcast_to(B, (len(z),) + B.shape))
    return C @ X + D


def response_family(G, theta, ts: float, shift: int, lead: int, Psi2, Phi2, a: float, q):
    r""":math:`T_k(x) = A_k - \sum_p x_p C_{k,p}` on the grid (module docstring).

    Parameters
    ----------
    G : ndarray
        :math:`G(e^{j\theta_k})`, ``(K, n_y, n_u)`` (:func:`plant_response`).
    theta : ndarray
        The angles ``(K,)``.
    ts : float
        Sample time [s] (the derivative gain enters as :math:`\Phi/T_s`).
    shift, lead : int
        Output-window shift s and lead :math:`\ell` [samples].
    Psi2, Phi2 : ndarray
        The fixed current-trial gains ``(n_u, n_y)``.
    a : float
        Constant forgetting factor.
    q : ndarray
        The Q-filter's real response ``(K,)`` (ones for none).

    Returns
    -------
    offsets : ndarray
        :math:`A_k = q_k(1-a)S_k`, ``(K, n_u, n_u)`` complex.
    coefficients : ndarray
        :math:`C_{k,p}`, ``(K, P, n_u, n_u)`` complex, P = 2 n_u n_y, the parameters ordered as
        :class:`~.structure.PDStructure` (vec Psi1, vec Phi1).
    """
    K, n_y, n_u = G.shape
    z = np.exp(1j * np.asarray(theta, dtype=float))
    d = (1.0 - 1.0 / z) / ts
    L2 = Psi2[None] + d[:, None, None] * Phi2[None]
    S = np.linalg.inv(np.eye(n_u)[None] + L2 @ G)
    pre = (q * z ** (shift + lead))[:, None, None] * S                  # (K, n_u, n_u)
    offsets = (q * (1.0 - a))[:, None, None] * S
    coef = np.zeros((K, 2 * n_u * n_y, n_u, n_u), dtype=complex)
    for i in range(n_u):
        for j in range(n_y):
            # E_ij G = e_i (row j of G)
            outer = pre[:, :, i][:, :, None] * G[:, j, :][:, None, :]      # (K, n_u, n_u)
            coef[:, i * n_y + j] = outer
            coef[:, n_u * n_y + i * n_y + j] = d[:, None, None] * outer
    return offsets, coef


def design_q_response(q_filter, theta, ts: float) -> np.ndarray:
    r"""The Q-filter's real response on the grid for the design: the two-pass filter's
    :math:`|H(e^{j\theta})|^2`, the DCT filter's gain at :math:`f = \theta/(2\pi T_s)`
    (module docstring), ones for none.

    Parameters
    ----------
    q_filter : QFilter or None
        The filter.
    theta : ndarray
        The angles [rad/sample].
    ts : float
        Sample time [s].

    Raises
    ------
    ParameterError
        For a filter given as a matrix (it has no frequency response).
    """
    theta = np.asarray(theta, dtype=float)
    if q_filter is None:
        return np.ones_like(theta)
    if not (hasattr(q_filter, "magnitude") and hasattr(q_filter, "cutoff")):
        raise ParameterError("the frequency-domain design needs a QFilter (it has a response "
                             "on the grid); a Q-filter given as a matrix has none: use the "
                             "dense lifted synthesis (a nonlinear problem, or time-varying "
                             "gains)")
    return q_filter.magnitude(theta / (2.0 * np.pi * ts), ts)
