r"""The N-periodic (circulant) trial: the setting a robust frequency verdict on the DFT bins of
an N-sample trial proves (ilc_analysis.analysis._robust_frequency).

On a periodic trial every LTI operator is a circulant, diagonal in the DFT: at bin k the plant
is :math:`G_k`, the law :math:`L_k` (its frequency response, the shift folded in) and
:math:`Q_k`, so one trial of :math:`u_{i+1} = Q(u_i + L e_i)`, :math:`e_i = r - G u_i` is a
product per bin. Real signals need real :math:`G, L, Q` at DC and Nyquist (the callers make
them so). Test helper, not part of the package.
"""

from __future__ import annotations

import numpy as np


def periodic_run(G, L, Q, r, trials: int) -> tuple[np.ndarray, np.ndarray]:
    """Errors of ``trials`` periodic trials from u_0 = 0, and the fixed-point error e_inf.

    Parameters
    ----------
    G, L, Q : ndarray (N//2 + 1,), complex (Q real or None)
        Responses on the bins k = 0..N//2.
    r : ndarray (N,)
        Reference (one period).
    trials : int

    Returns
    -------
    (ndarray (trials, N), ndarray (N,))
    """
    N = r.size
    Q = np.ones(G.size) if Q is None else Q
    R = np.fft.rfft(r)
    U = np.zeros_like(R)
    errors = []
    for _ in range(trials):
        E = R - G * U
        errors.append(np.fft.irfft(E, n=N))
        U = Q * (U + L * E)
    U_inf = Q * L * R / (1.0 - Q + Q * L * G)
    return np.array(errors), np.fft.irfft(R - G * U_inf, n=N)
