r"""Lifted operators in state-space form over the trial, and the finite-horizon norm tests.

A lifted map of a trial that is *causal up to a latency* d (output sample k depends on input
samples up to k + d: a lead, an advance) is a causal system on a clock once its samples are
placed there: input sample k at clock ``offset + k``, output sample k at clock
``offset + d + k`` (:class:`CausalForm`; its :meth:`~CausalForm.clock` is a
:class:`~._clock_system.ClockSystem` that reads its input on the trial's window only, so the
zeros outside the window are part of the map). Products of such maps are series connections
at the right offsets (:class:`SeriesForm`), sums parallel ones with delays to a common latency
(:class:`SumForm`).

Non-causal operators of a learning law (a zero-phase filter :math:`J\tilde T^\top JT`, the
adjoint :math:`\beta G^\top` of gradient ILC) are sums of an anti-causal times a causal map,

.. math::

    T = \sum_i c_i\,a_i^\top b_i\qquad(a_i, b_i\ \text{causal up to a latency}),

(:class:`TwoSided`; a causal T is the single pair :math:`(I, T)`). Products keep the form
(:meth:`TwoSided.compose`): factors that meet as :math:`a^\top(b\,b')` or
:math:`(a'a)^\top b` are series connections, and a causal map after an anti-causal one,
:math:`b\,a^\top`, splits into a causal and an anti-causal system over the trial
(:func:`causal_times_anticausal`: the cross-Gramian recursion

.. math::

    P_{t+1} = A^b_tP_tA^{a\top}_t + B^b_tB^{a\top}_t,\qquad P_0 = 0,

gives :math:`b\,a^\top = L + U^\top` with L causal with states of b and input map
:math:`A^b_tP_tC^{a\top}_t + B^b_tD^{a\top}_t` and U strictly causal with states of a; the
same states, time-varying input maps: :class:`ClockForm`).

**The norm test** (:func:`norm_below`). :math:`\|T\|_2 < \gamma` iff the symmetric matrix
:math:`\begin{bmatrix}I & T^\top/\gamma\\ T/\gamma & I\end{bmatrix}` is positive definite
(Schur complement), i.e. iff

.. math::

    q(u, v) = \|u\|^2 + \|v\|^2 + \frac{2}{\gamma}\sum_i c_i\,\langle a_iv,\ b_iu\rangle > 0
    \qquad\text{for all } (u, v) \ne 0,

and every term of q is a stage cost of the causal systems :math:`a_i` (driven by v) and
:math:`b_i` (driven by u) running side by side on one clock, with v placed so that the two
outputs of each pair meet at the same steps. The dissipation certificate
(:func:`~._dissipation.certify_positive`) proves :math:`q \ge \delta(\|u\|^2 + \|v\|^2)`, hence
:math:`\|T\|_2 \le \gamma(1 - \delta)`: exactly the finite-horizon bounded-real lemma for a
causal T, and for the two-sided ones the same recursion on the joint form (O(K n^3), K the
clock, n the states of all the systems). It is a proof about the operator of the realisations;
the realisations are those of the factors the analysis multiplies with (docs/theory.md §12).

**The spectral radius** (:func:`radius_below`): :math:`\rho(T) = \rho(DTD^{-1})
\le \|DTD^{-1}\|_2` for :math:`D = \operatorname{diag}(r^k)`; on the clock the weighting is
:math:`(rA, rB, C, D)` for the systems driven by u and :math:`(A/r, B/r, C, D)` for those
driven by v (:meth:`~._clock_system.ClockSystem.weighted`), so the same test decides
:math:`\rho(T) < \gamma r^{-\Delta}` (Δ the offset of v against u).

**A Gram form** (:func:`gram_above`): :math:`G^\top W_eG + \operatorname{diag}(w) \succ cI`
for a causal G, the stage cost :math:`\|W_e^{1/2}(Gu)_t\|^2 + (w - c)\|u_t\|^2`: the
definiteness test of the norm-optimal law's Hessian, which bounds
:math:`\sigma_{\min}` of the finite trial's G even for a non-minimum-phase plant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import ParameterError, ShapeError
from ._clock_system import ClockSystem, shift_register
from ._dissipation import Certificate, certify_positive

__all__ = ["CausalForm", "LTIForm", "IdentityForm", "DelayForm", "SeriesForm", "SumForm",
           "ClockForm", "causal_times_anticausal", "time_varying_form", "Pair", "TwoSided",
           "norm_below", "radius_below", "gram_above", "banded_form", "fir_form", "lti_form",
           "NORM_DELTA", "MAX_BAND"]

#: The margin δ of the norm test: :math:`\|T\|_2 \le \gamma(1 - \delta)` when proven.
NORM_DELTA = 1e-10
#: Most lags (block diagonals) of a sparse matrix taken as an FIR filter (:func:`banded_form`).
MAX_BAND = 64


class CausalForm:
    r"""A lifted map ``(N_out n_out) x (N_in n_in)`` causal up to ``latency`` (module
    docstring). Subclasses give :meth:`clock`."""

    n_in: int
    n_out: int
    N_in: int
    N_out: int
    latency: int = 0
    is_identity: bool = False

    def clock(self, offset: int, K: int) -> ClockSystem:
        """The map on a clock of K steps: input sample k at ``offset + k`` (other steps'
        inputs ignored), output sample k at ``offset + latency + k``."""
        raise NotImplementedError

    def dense(self) -> np.ndarray:
        """The lifted matrix (by running :meth:`clock` on unit inputs; small trials)."""
        K = self.N_in + self.latency + self.N_out + 1
        sys = self.clock(0, K)
        W = np.zeros((K, self.n_in, self.N_in * self.n_in))
        cols = np.arange(self.N_in * self.n_in)
        W[cols // self.n_in, cols % self.n_in, cols] = 1.0
        Y = sys.respond(W)[self.latency:self.latency + self.N_out]
        return Y.reshape(self.N_out * self.n_out, -1)

    def then(self, outer: CausalForm) -> CausalForm:
        """``outer`` applied after this map."""
        return SeriesForm(outer, self)


class LTIForm(CausalForm):
    r"""A time-invariant causal system ``(A, B, C, D)`` started at rest at the first input
    sample, its input zero outside the trial, read with a latency d: output sample k is the
    system's output at its step k + d (an advance of d samples)."""

    def __init__(self, A, B, C, D, N_in: int, N_out: int | None = None, latency: int = 0,
                 label: str = "LTI system"):
        self.A, self.B, self.C, self.D = (np.atleast_2d(np.asarray(x, dtype=float))
                                          for x in (A, B, C, D))
        n = self.A.shape[0] if self.A.size else 0
        self.A = self.A.reshape(n, n)
        self.B = self.B.reshape(n, -1) if n else np.zeros((0, self.D.shape[1]))
        self.C = self.C.reshape(-1, n) if n else np.zeros((self.D.shape[0], 0))
        self.n_out, self.n_in = self.D.shape
        if self.B.shape[1] != self.n_in or self.C.shape[0] != self.n_out:
            raise ShapeError(f"{label}: realisation (A, B, C, D) of shapes {self.A.shape}, "
                             f"{self.B.shape}, {self.C.shape}, {self.D.shape} does not fit")
        self.N_in = int(N_in)
        self.N_out = int(N_in if N_out is None else N_out)
        self.latency = int(latency)
        self.label = label

    def clock(self, offset, K):
        return ClockSystem.gated(K, (offset, offset + self.N_in), self.A, self.B, self.C,
                                 self.D)

    def transposed_system(self) -> LTIForm:
        r"""The system :math:`(A^\top, C^\top, B^\top, D^\top)`: its lifted matrix is
        :math:`J T^\top J` of this one's (latency 0, same trial)."""
        return LTIForm(self.A.T, self.C.T, self.B.T, self.D.T, self.N_in, self.N_out, 0,
                       f"({self.label}) transposed")


class IdentityForm(LTIForm):
    """The identity on ``n`` channels over N samples."""

    is_identity = True

    def __init__(self, n: int, N: int):
        super().__init__(np.zeros((0, 0)), np.zeros((0, n)), np.zeros((n, 0)), np.eye(n), N,
                         N, 0, "I")


class DelayForm(LTIForm):
    """The identity read ``d`` clock steps later (a shift register of d samples)."""

    def __init__(self, n: int, N: int, d: int):
        A, B, C, D = shift_register(n, d)
        super().__init__(A, B, C, D, N, N, d, f"delay {d}")


class SeriesForm(CausalForm):
    """``outer`` after ``inner``: latencies add."""

    def __init__(self, outer: CausalForm, inner: CausalForm):
        if outer.N_in != inner.N_out or outer.n_in != inner.n_out:
            raise ShapeError(f"cannot compose a form of {outer.N_in} x {outer.n_in} inputs "
                             f"after one of {inner.N_out} x {inner.n_out} outputs")
        self.outer, self.inner = outer, inner
        self.n_in, self.N_in = inner.n_in, inner.N_in
        self.n_out, self.N_out = outer.n_out, outer.N_out
        self.latency = inner.latency + outer.latency

    def clock(self, offset, K):
        return self.inner.clock(offset, K).series(
            self.outer.clock(offset + self.inner.latency, K))


class SumForm(CausalForm):
    """:math:`\\sum_j c_j F_j` of maps with the same trials; the ones of smaller latency are
    delayed to the largest (:class:`DelayForm`)."""

    def __init__(self, terms: list[tuple[float, CausalForm]]):
        if not terms:
            raise ParameterError("a sum of forms needs a term")
        f0 = terms[0][1]
        for _, f in terms:
            if (f.n_in, f.n_out, f.N_in, f.N_out) != (f0.n_in, f0.n_out, f0.N_in, f0.N_out):
                raise ShapeError("a sum of forms needs the same trials and channels")
        self.latency = max(f.latency for _, f in terms)
        self.terms = [(float(c), f if f.latency == self.latency else
                       SeriesForm(DelayForm(f.n_out, f.N_out, self.latency - f.latency), f))
                      for c, f in terms]
        self.n_in, self.n_out, self.N_in, self.N_out = f0.n_in, f0.n_out, f0.N_in, f0.N_out

    def clock(self, offset, K):
        c0, f0 = self.terms[0]
        out = f0.clock(offset, K).scaled(c0)
        for c, f in self.terms[1:]:
            out = out.plus(f.clock(offset, K), c)
        return out


class ClockForm(CausalForm):
    r"""A causal map given by one clock system on a reference clock: input sample k read at
    step ``start + k``, output sample k at ``start + latency + k``; the system's input maps
    are zero outside the input samples and its state is zero before them, so on any other
    clock it is the same system shifted (:meth:`clock`). The time-varying parts of a product
    :math:`b\,a^\top` (:func:`causal_times_anticausal`) are such forms."""

    def __init__(self, system: ClockSystem, start: int, N_in: int, N_out: int, latency: int):
        if latency < 0 or start < 0:
            raise ParameterError(f"a clock form needs start >= 0 and latency >= 0; got "
                                 f"{start}, {latency}")
        self.system, self.start = system, int(start)
        self.n_in, self.n_out = system.m, system.p
        self.N_in, self.N_out, self.latency = int(N_in), int(N_out), int(latency)

    def clock(self, offset, K):
        s = self.system
        shift = int(offset) - self.start
        starts = s.starts + shift
        # the steps before the reference clock: zero state, nothing read (the first
        # segment's matrices with its input maps zeroed); after it, its last segment goes on
        keep = (starts < K) & (np.append(starts[1:], s.K + shift) > 0)
        idx = np.flatnonzero(keep)
        first = np.maximum(starts[idx], 0)
        A, B, C, D = (x[idx] for x in (s.A, s.B, s.C, s.D))
        if first[0] > 0:
            first = np.concatenate([[0], first])
            A, C = np.concatenate([A[:1], A]), np.concatenate([C[:1], C])
            B = np.concatenate([np.zeros_like(B[:1]), B])
            D = np.concatenate([np.zeros_like(D[:1]), D])
        return ClockSystem(K, first, A, B, C, D)


def _steps(system: ClockSystem) -> tuple[np.ndarray, ...]:
    """The system's matrices at every step of its clock ``(K, ., .)``."""
    seg = np.searchsorted(system.starts, np.arange(system.K), side="right") - 1
    return system.A[seg], system.B[seg], system.C[seg], system.D[seg]


def _segments(K: int, A, B, C, D, window: tuple[int, int]) -> ClockSystem:
    """A clock system from per-step matrices, input maps zero outside ``window``; runs of
    steps with the same matrices (bit for bit) are one segment."""
    B, D = B.copy(), D.copy()
    outside = np.ones(K, dtype=bool)
    outside[max(0, window[0]):max(0, min(K, window[1]))] = False
    B[outside] = 0.0
    D[outside] = 0.0
    same = np.ones(K, dtype=bool)
    same[0] = False
    for X in (A, B, C, D):
        same[1:] &= np.all((X[1:] == X[:-1]).reshape(K - 1, -1), axis=1)
    starts = np.flatnonzero(~same)
    return ClockSystem(K, starts, A[starts], B[starts], C[starts], D[starts])


def _delayed(system: ClockSystem, d: int) -> ClockSystem:
    """The system's output read d steps later (a shift register after it)."""
    if d == 0:
        return system
    Ad, Bd, Cd, Dd = shift_register(system.p, d)
    return system.series(ClockSystem.pieces(system.K, [(0, Ad, Bd, Cd, Dd)]))


def causal_times_anticausal(b: CausalForm, a: CausalForm) -> TwoSided:
    r""":math:`b\,a^\top` of two causal forms reading the same signal (``b.N_in == a.N_in``)
    as a two-sided form :math:`L + U^\top` (module docstring).

    On a clock with the common input sample k at step k, with the clock systems
    :math:`(A^b_t, B^b_t, C^b_t, D^b_t)` of b and :math:`(A^a_t, \dots)` of a and the
    cross-Gramian :math:`P_t = \sum_{s<t}\Phi_b(t, s+1)B^b_sB^{a\top}_s\Phi_a(t, s+1)^\top`
    (:math:`P_{t+1} = A^b_tP_tA^{a\top}_t + B^b_tB^{a\top}_t`), the entry of
    :math:`b\,a^\top` between b's output at step t and a's output at step τ is

    .. math::

        \sum_{s\le\min(t,\tau)} h_b(t, s)h_a(\tau, s)^\top =
        \begin{cases}
        C^b_t\Phi_b(t, \tau+1)(A^b_\tau P_\tau C^{a\top}_\tau + B^b_\tau D^{a\top}_\tau)
            & t > \tau\\
        C^b_tP_tC^{a\top}_t + D^b_tD^{a\top}_t & t = \tau\\
        \bigl(C^a_\tau\Phi_a(\tau, t+1)(A^a_tP_t^\top C^{b\top}_t
            + B^a_tD^{b\top}_t)\bigr)^\top & t < \tau
        \end{cases}

    (h the impulse responses, Φ the state transitions): the impulse responses of L (states of
    b, the first two cases) and of a strictly causal U (states of a, the third) read at the
    output samples. A latency of L or U below 0 (the two forms' latencies differ) is made 0 by
    reading the output later. O(K n_a n_b (n_a + n_b)) for K clock steps.
    """
    if (b.N_in, b.n_in) != (a.N_in, a.n_in):
        raise ShapeError("b a^T needs two forms reading the same signal")
    d_b, d_a = b.latency, a.latency
    K = max(b.N_in, d_b + b.N_out, d_a + a.N_out) + 1
    Ab, Bb, Cb, Db = _steps(b.clock(0, K))
    Aa, Ba, Ca, Da = _steps(a.clock(0, K))
    P = np.zeros((K, Ab.shape[1], Aa.shape[1]))
    for t in range(K - 1):
        P[t + 1] = Ab[t] @ P[t] @ Aa[t].T + Bb[t] @ Ba[t].T
    CaT, CbT = np.swapaxes(Ca, 1, 2), np.swapaxes(Cb, 1, 2)
    L = _segments(K, Ab, Ab @ P @ CaT + Bb @ np.swapaxes(Da, 1, 2), Cb,
                  Cb @ P @ CaT + Db @ np.swapaxes(Da, 1, 2), (d_a, d_a + a.N_out))
    U = _segments(K, Aa, Aa @ np.swapaxes(P, 1, 2) @ CbT + Ba @ np.swapaxes(Db, 1, 2), Ca,
                  np.zeros((K, a.n_out, b.n_out)), (d_b, d_b + b.N_out))
    lat_L, lat_U = d_b - d_a, d_a - d_b
    L_form = ClockForm(_delayed(L, max(0, -lat_L)), d_a, a.N_out, b.N_out, max(0, lat_L))
    U_form = ClockForm(_delayed(U, max(0, -lat_U)), d_b, b.N_out, a.N_out, max(0, lat_U))
    return TwoSided([Pair(IdentityForm(b.n_out, b.N_out), L_form),
                     Pair(U_form, IdentityForm(a.n_out, a.N_out))])


def time_varying_form(A, B, C, D, *, reverse: bool = False) -> ClockForm:
    r"""The causal map of the system :math:`x_{k+1} = A_kx_k + B_kw_k`,
    :math:`y_k = C_kx_k + D_kw_k`, :math:`x_0 = 0`, over the N samples of its per-sample
    matrices ``(N, ., .)`` (latency 0); ``reverse``: the map :math:`JX^\top J` instead (J the
    time reversal), the system :math:`(A_{N-1-k}^\top, C_{N-1-k}^\top, B_{N-1-k}^\top,
    D_{N-1-k}^\top)`, whose impulse response from sample k to j > k is
    :math:`B_{N-1-j}^\top A_{N-j}^\top\cdots A_{N-2-k}^\top C_{N-1-k}^\top`, the transpose
    of X's from N-1-j to N-1-k. Runs of samples with the same matrices (bit for bit) are one
    segment."""
    A, B, C, D = (np.asarray(x, dtype=float) for x in (A, B, C, D))
    if reverse:
        A, B, C, D = (np.swapaxes(x[::-1], 1, 2) for x in (A, C, B, D))
    N = A.shape[0]
    # one step past the trial (input maps zero there): the form's clock goes on from it
    A, B, C, D = (np.concatenate([x, x[-1:]]) for x in (A, B, C, D))
    return ClockForm(_segments(N + 1, A, B, C, D, (0, N)), 0, N, N, 0)


def lti_form(state_space, shift: int, N: int, label: str = "G") -> LTIForm | None:
    r"""The causal form of a time-invariant lifted plant from its per-sample arrays
    ``(A, B, C, D)`` (broadcast views) and output shift s: the lifted G has blocks
    :math:`h_{s+m}`, realised by :math:`(A, B, CA^s, CA^{s-1}B)` for s >= 1 and
    :math:`(A, B, C, D)` for s = 0. None when an array varies along the trial (LTV)."""
    mats = [np.asarray(x, dtype=float) for x in state_space]
    if any(x.ndim != 3 or (x.shape[0] > 1 and x.strides[0] != 0
                           and not np.all(x == x[:1])) for x in mats):
        return None
    A, B, C, D = (x[0] for x in mats)
    if shift:
        Cs = C @ np.linalg.matrix_power(A, shift)
        Ds = C @ np.linalg.matrix_power(A, shift - 1) @ B
    else:
        Cs, Ds = C, D
    if not (np.all(np.isfinite(Cs)) and np.all(np.isfinite(Ds))):
        return None
    return LTIForm(A, B, Cs, Ds, N, N, 0, label)


def banded_form(M, N: int, p: int, q: int) -> tuple[list[int], np.ndarray] | None:
    r"""``(lags, blocks)`` of a sparse ``(N p, N q)`` matrix that is exactly the N-sample
    section of a banded block-Toeplitz operator, :math:`M_{kj} = l_{k-j}` for every k, j in the
    trial (each block diagonal constant, bit for bit), with at most :data:`MAX_BAND` lags;
    else None."""
    import scipy.sparse

    coo = scipy.sparse.coo_array(M)
    keep = coo.data != 0
    rows, cols, vals = coo.row[keep], coo.col[keep], coo.data[keep]
    if vals.size == 0:
        return [0], np.zeros((1, p, q))
    lag = rows // p - cols // q
    lags = np.unique(lag)
    if lags.size > MAX_BAND:
        return None
    blocks = np.zeros((lags.size, p, q))
    which = np.searchsorted(lags, lag)
    ri, ci = rows % p, cols % q
    for i, L in enumerate(lags):
        sel = which == i
        for a, b in {(int(x), int(y)) for x, y in zip(ri[sel], ci[sel], strict=True)}:
            here = sel & (ri == a) & (ci == b)
            v = vals[here]
            if v.size != N - abs(int(L)) or np.any(v != v[0]):
                return None
            blocks[i, a, b] = v[0]
    return [int(x) for x in lags], blocks


def fir_form(lags, blocks, N: int) -> LTIForm:
    r"""The banded block-Toeplitz section :math:`(Mx)_k = \sum_\ell l_\ell x_{k-\ell}`
    (x zero outside the trial) as a causal FIR filter with latency
    :math:`d = \max(0, -\min\ell)` (the read-ahead): taps :math:`c_\tau = l_{\tau-d}`."""
    from ._clock_system import fir_realisation

    lags = [int(x) for x in lags]
    blocks = np.asarray(blocks, dtype=float)
    d = max(0, -min(lags))
    taps = np.zeros((max(lags) + d + 1, *blocks.shape[1:]))
    for L, blk in zip(lags, blocks, strict=True):
        taps[L + d] = blk
    A, B, C, D = fir_realisation(taps)
    return LTIForm(A, B, C, D, N, N, d, f"banded filter (lags {min(lags)}..{max(lags)})")


# ---------------------------------------------------------------------------------------------
# two-sided operators
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Pair:
    r""":math:`c\,a^\top b`: b maps the operator's input, a its output space, into the same
    intermediate signal (``a.N_out == b.N_out``)."""

    a: CausalForm
    b: CausalForm
    c: float = 1.0

    def __post_init__(self) -> None:
        if self.a.N_out != self.b.N_out or self.a.n_out != self.b.n_out:
            raise ShapeError("the two sides of a pair must meet in the same signal")


class TwoSided:
    r""":math:`T = \sum_i c_i a_i^\top b_i` (module docstring)."""

    def __init__(self, pairs):
        self.pairs = tuple(pairs)
        if not self.pairs:
            raise ParameterError("a two-sided form needs a pair")
        p0 = self.pairs[0]
        for p in self.pairs:
            if (p.a.N_in, p.a.n_in, p.b.N_in, p.b.n_in) != (p0.a.N_in, p0.a.n_in, p0.b.N_in,
                                                              p0.b.n_in):
                raise ShapeError("the pairs of a two-sided form must map the same spaces")
        self.N_out, self.n_out = p0.a.N_in, p0.a.n_in
        self.N_in, self.n_in = p0.b.N_in, p0.b.n_in

    @classmethod
    def causal(cls, form: CausalForm) -> TwoSided:
        """A causal map (up to its latency) as the pair :math:`(I, F)`."""
        return cls([Pair(IdentityForm(form.n_out, form.N_out), form)])

    @classmethod
    def anticausal(cls, form: CausalForm) -> TwoSided:
        r""":math:`F^\top` of a causal F as the pair :math:`(F, I)`."""
        return cls([Pair(form, IdentityForm(form.n_out, form.N_out))])

    @property
    def causal_form(self) -> CausalForm | None:
        """The map as one causal form when every pair's a is the identity, else None."""
        if not all(p.a.is_identity for p in self.pairs):
            return None
        if len(self.pairs) == 1 and self.pairs[0].c == 1.0:
            return self.pairs[0].b
        return SumForm([(p.c, p.b) for p in self.pairs])

    # algebra -------------------------------------------------------------------------------
    def scaled(self, c: float) -> TwoSided:
        return TwoSided([Pair(p.a, p.b, c * p.c) for p in self.pairs])

    def plus(self, other: TwoSided, c: float = 1.0) -> TwoSided:
        return TwoSided([*self.pairs, *(Pair(p.a, p.b, c * p.c) for p in other.pairs)])

    def transpose(self) -> TwoSided:
        return TwoSided([Pair(p.b, p.a, p.c) for p in self.pairs])

    def compose(self, right: TwoSided) -> TwoSided:
        r"""``self @ right``, pair by pair:
        :math:`a^\top b\,a'^\top b' = (a'a)^\top b'` when b is the identity,
        :math:`a^\top(bb')` when a' is, and otherwise
        :math:`a^\top(L + U^\top)b' = a^\top(Lb') + (Ua)^\top b'` with
        :math:`b\,a'^\top = L + U^\top` (:func:`causal_times_anticausal`)."""
        out = []
        for p in self.pairs:
            for q in right.pairs:
                if p.b.is_identity:
                    out.append(Pair(SeriesForm(q.a, p.a), q.b, p.c * q.c))
                elif q.a.is_identity:
                    out.append(Pair(p.a, SeriesForm(p.b, q.b), p.c * q.c))
                else:
                    lower, upper = causal_times_anticausal(p.b, q.a).pairs
                    out.append(Pair(p.a, SeriesForm(lower.b, q.b), p.c * q.c))
                    out.append(Pair(SeriesForm(upper.a, p.a), q.b, p.c * q.c))
        return TwoSided(out).merged()

    def merged(self) -> TwoSided:
        """Pairs with the same a (the object) summed into one: fewer systems on the clock."""
        groups: dict[object, list[Pair]] = {}
        for p in self.pairs:
            key = ("I", p.a.n_in, p.a.N_in) if p.a.is_identity else id(p.a)
            groups.setdefault(key, []).append(p)
        out = []
        for group in groups.values():
            if len(group) == 1:
                out.append(group[0])
            else:
                out.append(Pair(group[0].a, SumForm([(p.c, p.b) for p in group]), 1.0))
        return TwoSided(out)

    def dense(self) -> np.ndarray:
        """The lifted matrix :math:`\\sum c_ia_i^\\top b_i` (small trials; tests)."""
        return sum(p.c * p.a.dense().T @ p.b.dense() for p in self.pairs)

    # on the clock --------------------------------------------------------------------------
    def layout(self) -> tuple[list[Pair], int, int, int]:
        r"""The pairs with the b sides delayed to a common offset difference, the offsets of
        u and v on the clock and the clock's length."""
        diffs = [p.b.latency - p.a.latency for p in self.pairs]
        gap = max(diffs)
        pairs = [p if d == gap else Pair(p.a, SeriesForm(
                     DelayForm(p.b.n_out, p.b.N_out, gap - d), p.b), p.c)
                 for p, d in zip(self.pairs, diffs, strict=True)]
        off_u = max(0, -gap)
        off_v = off_u + gap
        K = max([off_u + self.N_in, off_v + self.N_out]
                + [off_u + p.b.latency + p.b.N_out for p in pairs])
        return pairs, off_u, off_v, K

    def form_stages(self, gamma: float, weight: float = 1.0):
        r"""The stages of :math:`q(u, v)` (module docstring) for the certificate:
        ``(starts, stops, A, B, R, Omega)`` and the offset difference Δ of v against u."""
        pairs, off_u, off_v, K = self.layout()
        m_u, m_v = self.n_in, self.n_out
        m = m_u + m_v
        Eu = np.eye(m)[:, :m_u]
        Ev = np.eye(m)[:, m_u:]
        systems, selections, blocks, windows = [], [], [], []
        for p in pairs:
            sa = p.a.clock(off_v, K)
            sb = p.b.clock(off_u, K)
            if weight != 1.0:
                sa, sb = sa.weighted(1.0 / weight), sb.weighted(weight)
            systems += [sa, sb]
            selections += [Ev, Eu]
            start = off_u + p.b.latency
            blocks.append((p.c, p.b.n_out))
            windows.append((start, start + p.b.N_out))
        joint = ClockSystem.stack(systems, selections, m)
        bounds = set(joint.starts.tolist())
        inputs = ((off_u, off_u + self.N_in), (off_v, off_v + self.N_out))
        for a, b in [*windows, *inputs]:
            bounds.update(x for x in (a, b) if 0 <= x < K)
        joint = joint.refine(np.asarray(sorted(bounds)))
        starts, stops = joint.starts, joint.stops
        A, B, R, Om = [], [], [], []
        for s in range(starts.size):
            # an input outside its trial is a dummy: it reaches nothing (only its own weight)
            live = np.zeros(m, dtype=bool)
            live[:m_u] = inputs[0][0] <= starts[s] < inputs[0][1]
            live[m_u:] = inputs[1][0] <= starts[s] < inputs[1][1]
            joint.B[s][:, ~live] = 0.0
            joint.D[s][:, ~live] = 0.0
            R.append(np.block([[joint.C[s], joint.D[s]],
                               [np.zeros((m, joint.n)), np.eye(m)]]))
            omega = np.zeros((joint.p + m, joint.p + m))
            omega[joint.p:, joint.p:] = np.eye(m)
            row = 0
            for (c, width), (a, b) in zip(blocks, windows, strict=True):
                if a <= starts[s] < b:
                    ia, ib = row, row + width
                    omega[ia:ia + width, ib:ib + width] += (c / gamma) * np.eye(width)
                    omega[ib:ib + width, ia:ia + width] += (c / gamma) * np.eye(width)
                row += 2 * width
            A.append(joint.A[s])
            B.append(joint.B[s])
            Om.append(omega)
        return (starts, stops, A, B, R, Om), off_v - off_u


def norm_below(form: TwoSided, gamma: float, *, delta: float = NORM_DELTA) -> Certificate:
    r"""Prove :math:`\|T\|_2 \le \gamma(1 - \delta) < \gamma` (module docstring).

    Parameters
    ----------
    form : TwoSided
    gamma : float
        > 0.
    delta : float
        The certificate's margin.

    Returns
    -------
    Certificate
    """
    if not gamma > 0.0:
        raise ParameterError(f"gamma must be > 0; got {gamma!r}")
    stages, _ = form.form_stages(float(gamma))
    return certify_positive(*stages, delta=delta)


def radius_below(form: TwoSided, gamma: float, weight: float, *,
                 delta: float = NORM_DELTA) -> tuple[Certificate, float]:
    r"""Prove :math:`\rho(T) < \gamma\,r^{-\Delta}` through :math:`\|DTD^{-1}\|_2` with
    :math:`D = \operatorname{diag}(r^k)` (module docstring); returns the certificate and the
    bound :math:`\gamma(1-\delta)r^{-\Delta}` it proves. T must be square."""
    if form.N_in * form.n_in != form.N_out * form.n_out:
        raise ShapeError("the spectral radius needs a square operator")
    stages, gap = form.form_stages(float(gamma), float(weight))
    cert = certify_positive(*stages, delta=delta)
    return cert, float(gamma) * (1.0 - delta) * float(weight) ** (-gap)


def gram_above(form: CausalForm, weight_error, weight_input, c: float, *,
               delta: float) -> Certificate:
    r"""Prove :math:`G^\top W_eG + \operatorname{diag}(w) \succeq (c + \delta)I` for a causal
    G (latency 0) with constant diagonal weights per channel (module docstring).

    Parameters
    ----------
    form : CausalForm
        G, latency 0.
    weight_error : ndarray (n_out,)
        :math:`W_e` per output channel (>= 0).
    weight_input : ndarray (n_in,)
        w per input channel.
    c : float
        The level.
    delta : float
        The margin.
    """
    if form.latency != 0:
        raise ParameterError("gram_above needs a causal G (latency 0)")
    K = form.N_in
    sys = form.clock(0, K)
    m = sys.m
    R = [np.block([[sys.C[s], sys.D[s]], [np.zeros((m, sys.n)), np.eye(m)]])
         for s in range(sys.starts.size)]
    omega = np.diag(np.concatenate([np.asarray(weight_error, float),
                                    np.asarray(weight_input, float) - c]))
    return certify_positive(sys.starts, sys.stops, list(sys.A), list(sys.B), R,
                            [omega] * sys.starts.size, delta=delta)
