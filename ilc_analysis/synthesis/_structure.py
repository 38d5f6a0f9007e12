r"""The PD structure of the lifted learning operators as a linear map of the free gains.

The lifted open-loop operator of eq (11) (:mod:`ilc_analysis.laws`, index convention there) is

.. math::

    L_1 = \Psi_1 S_{\ell} + \Phi_1 (S_{\ell} - S_{\ell-1})/T_s,
    \qquad (S_m e)_k = e_{k+m}\ \text{(zero outside } 0 \dots N-1),

so it is **linear** in the gains. Synthesis writes it as :math:`L_1(\theta) = \sum_p \theta_p
B_p` with one parameter per free gain entry: :math:`\theta = [\mathrm{vec}\,\Psi_1,
\mathrm{vec}\,\Phi_1]` (row-major, ``2 n_u n_y`` parameters) for time-invariant gains, or
:math:`\theta = [\mathrm{vec}\,\Psi_1(k), \mathrm{vec}\,\Phi_1(k)]_{k=0}^{N-1}` (``2 N n_u
n_y`` parameters) for time-varying ones. The matrices :math:`B_p` share one sparsity pattern;
the map is stored as the pattern ``(rows, cols)`` and a sparse matrix ``E`` with
:math:`\mathrm{vals}(L_1) = E\theta`.

**Piecewise-linear time-varying gains** (``knot_spacing`` M). The gains are linear in time
between knots :math:`k_0 = 0, M, 2M, \dots, N-1` and :math:`\theta` holds their values at the
knots (``2 K n_u n_y`` parameters for K knots): :math:`\Psi_1(k) = \sum_j h_j(k)\Psi_1(k_j)`
with the hat functions :math:`h_j \ge 0`, :math:`\sum_j h_j = 1` (:func:`hat_basis`). So a
bound on the knot values is exactly the bound on every sample's gain. Linear interpolation
filters the knot sequence with the response
:math:`\big(\sin(\pi f M T_s)/(M\sin(\pi f T_s))\big)^2`, zero at the non-zero multiples of
:math:`1/(M T_s)` (uniform knots; the last interval may be shorter): a gain free per sample can
multiply a periodic disturbance of those frequencies down into the Q-filter's band, one on
these knots (almost) cannot.

The same entries are written here from the convention of :mod:`ilc_analysis.laws`,
independently of :func:`ilc_analysis.lifting.learning_operators`; the tests check that both
give the same matrix, so gains synthesised here run unchanged in the simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse

from .._validation import positive, positive_int
from ..exceptions import ParameterError
from ..laws._gains import PDGains

__all__ = ["PDStructure", "pd_structure", "closed_loop_operator", "hat_basis"]


def _entries(N: int, n_u: int, n_y: int, ts: float, offset: int):
    r"""Entries of a lifted PD operator reading error index k + offset (and its difference).

    Returns arrays ``(k, a, b, kind, row, col, value)`` for every nonzero entry: ``kind`` 0 is
    the proportional gain (value 1), 1 the derivative gain (values :math:`\pm 1/T_s`).
    """
    k = np.arange(N)
    a, b = np.arange(n_u), np.arange(n_y)
    K, A, Bc = (grid.ravel() for grid in np.meshgrid(k, a, b, indexing="ij"))
    parts = []
    for kind, shift_in, value in ((0, 0, 1.0), (1, 0, 1.0 / ts), (1, -1, -1.0 / ts)):
        j = K + offset + shift_in
        ok = (j >= 0) & (j < N)
        parts.append((K[ok], A[ok], Bc[ok], np.full(ok.sum(), kind), K[ok] * n_u + A[ok],
                      j[ok] * n_y + Bc[ok], np.full(ok.sum(), value)))
    return tuple(np.concatenate(arrs) for arrs in zip(*parts, strict=True))


@dataclass(frozen=True, eq=False)
class PDStructure:
    r"""The open-loop operator :math:`L_1(\theta)` as a linear map (module docstring).

    Attributes
    ----------
    N, n_u, n_y : int
    ts : float
    lead : int
    time_varying : bool
    rows, cols : ndarray of int
        The sparsity pattern of :math:`L_1` (unique positions).
    E : scipy.sparse.csr_array
        ``(len(rows), n_params)``: values of :math:`L_1` at the pattern are ``E @ theta``.
    """

    N: int
    n_u: int
    n_y: int
    ts: float
    lead: int
    time_varying: bool
    rows: np.ndarray
    cols: np.ndarray
    E: scipy.sparse.csr_array
    knot_spacing: int | None = None
    """samples between knots of piecewise-linear time-varying gains (None: free per sample)"""

    @property
    def n_params(self) -> int:
        """Number of free gain entries."""
        return self.E.shape[1]

    @property
    def basis(self) -> np.ndarray | None:
        """``(N, K)`` hat functions of piecewise-linear gains (None unless ``knot_spacing``)."""
        return None if self.knot_spacing is None else hat_basis(self.N, self.knot_spacing)

    @property
    def shape(self) -> tuple[int, int]:
        """Shape of :math:`L_1`: ``(N*n_u, N*n_y)``."""
        return (self.N * self.n_u, self.N * self.n_y)

    def operator(self, theta) -> scipy.sparse.csr_array:
        r""":math:`L_1(\theta)` as a CSR matrix.

        Parameters
        ----------
        theta : array_like
            ``(n_params,)`` free gain entries (:attr:`n_params`).

        Returns
        -------
        scipy.sparse.csr_array
            ``(N n_u, N n_y)``: the values ``E @ theta`` at the pattern ``(rows, cols)``.
        """
        vals = self.E @ np.asarray(theta, dtype=float)
        return scipy.sparse.csr_array((vals, (self.rows, self.cols)), shape=self.shape)

    def gains(self, theta) -> tuple[np.ndarray, np.ndarray]:
        r"""``(Psi1, Phi1)`` from :math:`\theta`: ``(n_u, n_y)`` each, or ``(N, n_u, n_y)``.

        Parameters
        ----------
        theta : array_like
            ``(n_params,)``: per sample (time-varying) or per knot (``knot_spacing``), the
            ``n_u n_y`` entries of :math:`\Psi_1` then those of :math:`\Phi_1`, row-major.

        Returns
        -------
        Psi1, Phi1 : ndarray
            Time-varying: ``(N, n_u, n_y)`` each (interpolated between knots); else
            ``(n_u, n_y)``.

        Raises
        ------
        ParameterError
            If ``theta`` does not have ``n_params`` entries.
        """
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (self.n_params,):
            raise ParameterError(f"theta must have {self.n_params} entries; found shape "
                                 f"{theta.shape}")
        if self.time_varying:
            per = theta.reshape(-1, 2 * self.n_u * self.n_y)
            if self.knot_spacing is not None:
                per = self.basis @ per
            per = per.reshape(self.N, 2, self.n_u, self.n_y)
            return per[:, 0].copy(), per[:, 1].copy()
        per = theta.reshape(2, self.n_u, self.n_y)
        return per[0].copy(), per[1].copy()

    def parameters(self, Psi1, Phi1) -> np.ndarray:
        r""":math:`\theta` from ``(Psi1, Phi1)`` (the inverse of :meth:`gains`).

        Parameters
        ----------
        Psi1, Phi1 : array_like
            ``(n_u, n_y)`` (broadcast over the samples when time-varying) or ``(N, n_u, n_y)``.

        Returns
        -------
        ndarray
            ``(n_params,)``.

        Raises
        ------
        ParameterError
            If the shapes do not fit the structure, or, with ``knot_spacing``, if the gains are
            not piecewise linear between the knots.
        """
        Psi1, Phi1 = np.asarray(Psi1, dtype=float), np.asarray(Phi1, dtype=float)
        per_sample = (self.N, self.n_u, self.n_y)
        allowed = [(self.n_u, self.n_y)] + ([per_sample] if self.time_varying else [])
        if Psi1.shape not in allowed or Phi1.shape not in allowed:
            form = (f"({self.n_u}, {self.n_y}) or {per_sample}" if self.time_varying
                    else f"({self.n_u}, {self.n_y}) (time-invariant gains)")
            raise ParameterError(f"gains must have Psi1, Phi1 of shape {form}; found "
                                 f"{Psi1.shape} and {Phi1.shape}")
        if self.time_varying:
            Psi1 = np.broadcast_to(Psi1, (self.N, self.n_u, self.n_y))
            Phi1 = np.broadcast_to(Phi1, (self.N, self.n_u, self.n_y))
            per = np.stack([Psi1, Phi1], axis=1).reshape(self.N, -1)
            if self.knot_spacing is None:
                return per.ravel()
            basis = hat_basis(self.N, self.knot_spacing)
            knots = per[basis.argmax(axis=0)]
            if not np.allclose(basis @ knots, per, rtol=1e-12, atol=1e-12):
                raise ParameterError(f"the gains are not piecewise linear between knots every "
                                     f"{self.knot_spacing} samples (knot_spacing)")
            return knots.ravel()
        return np.stack([Psi1, Phi1]).ravel()


def hat_basis(N: int, knot_spacing: int) -> np.ndarray:
    r"""Hat functions of linear interpolation between knots every ``knot_spacing`` samples.

    Knots :math:`k_j = 0, M, 2M, \dots` and always :math:`N-1`; column j is the hat
    :math:`h_j` (1 at :math:`k_j`, 0 at the neighbouring knots). Rows are convex weights
    (non-negative, sum 1), and :math:`h_j(k_i) = \delta_{ij}`.

    Parameters
    ----------
    N : int
        Trial length in samples.
    knot_spacing : int
        Samples between knots, ``1 <= knot_spacing < N``.

    Returns
    -------
    ndarray
        ``(N, K)`` with K the number of knots.
    """
    N = positive_int(N, "N (trial length in samples)")
    M = positive_int(knot_spacing, "knot_spacing (samples between gain knots)")
    if M >= N:
        raise ParameterError(f"knot_spacing must be below N = {N} samples; got {M}")
    knots = np.unique(np.append(np.arange(0, N, M), N - 1))
    eye = np.eye(knots.size)
    return np.column_stack([np.interp(np.arange(N), knots, eye[j]) for j in range(knots.size)])


def pd_structure(N: int, n_u: int, n_y: int, ts: float, lead: int = 0,
                 time_varying: bool = False, knot_spacing: int | None = None) -> PDStructure:
    r"""The linear map :math:`\theta \mapsto L_1(\theta)` of the open-loop PD term with lead.

    ``knot_spacing`` (time-varying gains only) makes the gains piecewise linear in time between
    knots every ``knot_spacing`` samples (module docstring); None leaves one free gain per sample.

    Entries (input sample k, channel a; lifted error index j, channel b):

    .. math::

        (L_1)_{(k,a),(k+\ell,b)} = \Psi_1(k)_{ab} + \Phi_1(k)_{ab}/T_s,\qquad
        (L_1)_{(k,a),(k+\ell-1,b)} = -\Phi_1(k)_{ab}/T_s,

    each only if the error index lies in :math:`0 \dots N-1`.

    Parameters
    ----------
    N : int
        Trial length in samples.
    n_u, n_y : int
        Numbers of inputs and outputs.
    ts : float
        Sample time (s); the derivative gain enters as :math:`\Phi_1/T_s`.
    lead : int
        Samples of anticipation :math:`\ell`, ``0 <= lead < N``.
    time_varying : bool
        One gain pair per sample (``2 N n_u n_y`` parameters) instead of one for the trial
        (``2 n_u n_y``).
    knot_spacing : int, optional
        Time-varying only: gains piecewise linear between knots this many samples apart
        (:func:`hat_basis`); the knot values are the parameters.

    Returns
    -------
    PDStructure
        The pattern of :math:`L_1` and the map ``E`` from the parameters to its values.

    Raises
    ------
    ParameterError
        For a non-integer or out-of-range ``lead``, a non-boolean ``time_varying``, or
        ``knot_spacing`` without ``time_varying``.
    """
    N = positive_int(N, "N (trial length in samples)")
    n_u, n_y = positive_int(n_u, "n_u"), positive_int(n_y, "n_y")
    ts = positive(ts, "ts (sample time)")
    if isinstance(lead, bool) or not isinstance(lead, int | np.integer) or not 0 <= lead < N:
        raise ParameterError(f"lead must be an integer in [0, N-1] = [0, {N - 1}] samples; "
                             f"got {lead!r}")
    if not isinstance(time_varying, bool | np.bool_):
        raise ParameterError(f"time_varying must be True or False; got {time_varying!r}")
    if knot_spacing is not None and not time_varying:
        raise ParameterError("knot_spacing needs time_varying=True (it shapes gains in time)")
    k, a, b, kind, row, col, val = _entries(N, n_u, n_y, ts, int(lead))
    per = 2 * n_u * n_y
    local = kind * n_u * n_y + a * n_y + b
    param = k * per + local if time_varying else local
    flat = row * (N * n_y) + col
    uniq, pos = np.unique(flat, return_inverse=True)
    n_params = per * N if time_varying else per
    E = scipy.sparse.csr_array((val, (pos, param)), shape=(uniq.size, n_params))
    if knot_spacing is not None:
        # theta_sample = kron(basis, I_per) theta_knot (sample-major, as above)
        knot_spacing = positive_int(knot_spacing, "knot_spacing (samples between gain knots)")
        to_knots = scipy.sparse.kron(scipy.sparse.csr_array(hat_basis(N, knot_spacing)),
                                     scipy.sparse.eye_array(per), format="csr")
        E = scipy.sparse.csr_array(E @ to_knots)
    E.sum_duplicates()
    return PDStructure(N=N, n_u=n_u, n_y=n_y, ts=ts, lead=int(lead),
                       time_varying=bool(time_varying), rows=uniq // (N * n_y),
                       cols=uniq % (N * n_y), E=E, knot_spacing=knot_spacing)


def closed_loop_operator(Psi2, Phi2, N: int, shift: int, ts: float) -> scipy.sparse.csr_array:
    r"""The lifted current-trial operator :math:`L_2` (time-invariant or per-sample gains).

    .. math::

        (L_2)_{(k,a),(k-s,b)} = \Psi_2(k)_{ab} + \Phi_2(k)_{ab}/T_s,\qquad
        (L_2)_{(k,a),(k-s-1,b)} = -\Phi_2(k)_{ab}/T_s
    """
    Psi2, Phi2 = np.asarray(Psi2, dtype=float), np.asarray(Phi2, dtype=float)
    n_u, n_y = Psi2.shape[-2:]
    Psi2 = np.broadcast_to(Psi2, (N, n_u, n_y))
    Phi2 = np.broadcast_to(Phi2, (N, n_u, n_y))
    k, a, b, kind, row, col, val = _entries(N, n_u, n_y, ts, -int(shift))
    gain = np.where(kind == 0, Psi2[k, a, b], Phi2[k, a, b])
    out = scipy.sparse.csr_array((val * gain, (row, col)), shape=(N * n_u, N * n_y))
    out.sum_duplicates()
    return out


def gains_with_feedback(Psi1, Phi1, Psi2, Phi2, lead: int) -> PDGains:
    """A PDGains from synthesised open-loop and fixed closed-loop gains (broadcast to match)."""
    Psi1, Phi1 = np.asarray(Psi1), np.asarray(Phi1)
    Psi2 = np.broadcast_to(Psi2, Psi1.shape).copy()
    Phi2 = np.broadcast_to(Phi2, Psi1.shape).copy()
    return PDGains(Phi1=Phi1, Phi2=Phi2, Psi1=Psi1, Psi2=Psi2, lead=lead)
