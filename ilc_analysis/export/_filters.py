r"""Stages of the generated update that filter the trial: Q-filters and the Q/L learning filter.

* :class:`TwoPassStage` — a :class:`~ilc_analysis.laws.QFilter` of a two-pass kind
  (``butterworth``, ``first-order``: second-order sections in direct form II transposed;
  ``fir``), per input channel, exactly as :meth:`QFilter.apply` runs it: the odd extension of
  ``pad`` samples at each end and each pass started at the filter's steady state for its first
  sample (scipy's ``sosfiltfilt`` / ``filtfilt``), or two passes from rest
  (``ends='zero-state'``); backward-forward as :math:`J Q J`;
* :class:`DCTStage` — the ``dct`` kind: the Butterworth magnitude on the orthonormal DCT-II
  coefficients, :math:`y_n = \sum_k s_k^2 g_k X_k \cos(\pi k(2n+1)/2N)`,
  :math:`X_k = \sum_m x_m \cos(\pi k(2m+1)/2N)`, with a table of :math:`\cos(\pi m/2N)`;
* :class:`LTIQStage` — an LTI Q of a Q/L law (state space, from rest; forward and backward
  when ``zero_phase``);
* :class:`LearningFilterStage` — :math:`x = u + (L'e)(k + m)` of a Q/L law.

Rounding (:func:`pass_bound`): a recursion :math:`z_{k+1} = Az_k + Bw_k`, :math:`y_k = Cz_k +
Dw_k` computed in floating point is the exact recursion with local errors injected at every
step, :math:`|\xi_k| \le \gamma_c(|A|_p|\hat z_k| + |B|_p|w_k|)` (c the roundings of the
longest path within one step, :math:`|A|_p` the sum over paths of the absolute products of the
coefficients: the step computed with absolute values), which the exact recursion carries to the
output: by Young's inequality for the block Toeplitz maps,

.. math::

    \|\hat y - y\|_2 \le \Big(\sum_j\|CA^j\|_2\Big)(\|\xi\|_2 + \|\xi_0\|_2) + \|\zeta\|_2,
    \qquad \|\xi\|_2 \le \frac{\gamma_c(\||A|_p\|_2(X + P\|\xi_0\|_2)
    + \||B|_p\|_2 W)}{1 - \gamma_c\||A|_p\|_2 P},

with :math:`W = \|w\|_2`, :math:`X \le (\sum_j\|A^jB\|_2 + \|(A^kZ)_k\|_2)W` the exact states'
norm (Z the steady-state start per unit first sample), :math:`P = \sum_j\|A^j\|_2`,
:math:`\xi_0` the rounding of the start and ζ that of the outputs. Every sum runs over the
pass's samples.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.signal
import scipy.sparse

from ..exceptions import InternalError, ParameterError
from ._c import CArray
from ._signals import spectral_norm
from ._stage import Operations, Sig, Stage, WorkArray, gamma, linear

__all__ = ["TwoPassStage", "DCTStage", "LTIQStage", "LearningFilterStage", "pass_bound",
           "q_stage"]


# ---------------------------------------------------------------------------------------------
# the rounding of one recursive pass
# ---------------------------------------------------------------------------------------------
def _norm(M) -> float:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    return spectral_norm(M)


def pass_bound(A, B, C, D, Aa, Ba, Ca, Da, Z, depth: int, length: int,
               u: float) -> tuple[float, float]:
    r"""``(n, eta)`` of one pass of a recursion over ``length`` samples (module docstring):
    the exact pass has norm at most n, and the computed one is within
    :math:`\eta\,\|w\|_2` of the exact pass of its own input. ``Z`` ``(n_z, n_in)``: the start
    state per unit first input sample (zeros: from rest)."""
    A, B, C, D = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (A, B, C, D))
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    nA, nB, nC, nD = (_norm(m) for m in (Aa, Ba, Ca, Da))
    n_z = A.shape[0]
    power = np.eye(n_z)
    hB = P = hC = hD = 0.0
    free_state = free_out = 0.0
    hD += _norm(D)
    for j in range(length):
        P += _norm(power)
        hB += _norm(power @ B)
        hC += _norm(C @ power)
        if j + 1 < length:
            hD += _norm(C @ power @ B)
        free_state += _norm(power @ Z) ** 2
        free_out += _norm(C @ power @ Z) ** 2
        power = A @ power
        if not np.all(np.isfinite(power)):
            raise ParameterError("a filter of the law is unstable over the trial (its powers "
                                 "overflow): no rounding bound")
    widen = 1.0 + 1e-9
    hB, P, hC, hD = hB * widen, P * widen, hC * widen, hD * widen
    free_state, free_out = math.sqrt(free_state) * widen, math.sqrt(free_out) * widen
    g, g2 = gamma(depth, u), gamma(2, u)
    X = hB + free_state                      # per unit ||w||
    xi0 = g2 * _norm(Z)
    den = 1.0 - g * nA * P
    if den <= 0.0:
        raise ParameterError("the rounding of a recursive filter of the law grows without "
                             "bound in this precision (gamma * |||A||| * sum ||A^j|| >= 1): "
                             "no rounding bound; export in double")
    xi = g * (nA * (X + P * xi0) + nB) / den
    X_hat = X + P * (xi + xi0)
    zeta = g * (nC * X_hat + nD)
    return hD + free_out, hC * (xi + xi0) + zeta


def _step_matrices(step, n_z: int, n_in: int):
    """The one-step map of a recursion as matrices: ``step(z, w)`` -> ``(z', y)`` (linear),
    evaluated on the unit vectors."""
    cols_z = [step(np.eye(n_z)[:, i], np.zeros(n_in)) for i in range(n_z)]
    cols_w = [step(np.zeros(n_z), np.eye(n_in)[:, i]) for i in range(n_in)]
    A = np.column_stack([c[0] for c in cols_z]) if n_z else np.zeros((0, 0))
    C = np.column_stack([c[1] for c in cols_z]) if n_z else np.zeros((len(cols_w[0][1]), 0))
    B = np.column_stack([c[0] for c in cols_w])
    D = np.column_stack([c[1] for c in cols_w])
    return A, B, C, D


def _sos_step(sos: np.ndarray, absolute: bool):
    """One sample of the cascade of sections (direct form II transposed), as scipy's sosfilt
    computes it; with absolute values of the coefficients and sums for ``absolute``."""
    c = np.abs(sos) if absolute else sos
    sign = 1.0 if absolute else -1.0

    def step(z, w):
        z = np.array(z, dtype=float)
        v = float(w[0])
        for s in range(len(c)):
            y = c[s, 0] * v + z[2 * s]
            z[2 * s] = (c[s, 1] * v + sign * c[s, 4] * y) + z[2 * s + 1]
            z[2 * s + 1] = c[s, 2] * v + sign * c[s, 5] * y
            v = y
        return z, np.array([v])
    return step


def _fir_step(b: np.ndarray, absolute: bool):
    c = np.abs(b) if absolute else b

    def step(z, w):
        v = float(w[0])
        y = z[0] + c[0] * v
        out = np.empty_like(z)
        out[:-1] = z[1:] + v * c[1:-1]
        out[-1] = v * c[-1]
        return out, np.array([y])
    return step


# ---------------------------------------------------------------------------------------------
# the two-pass Q-filters
# ---------------------------------------------------------------------------------------------
class TwoPassStage(Stage):
    """Q-filter (two passes, per input channel), as QFilter.apply runs it."""

    function_name = "ilc_q_filter"
    inputs = ("x",)
    output = "x"

    def __init__(self, q_filter, N: int, n_u: int, ts: float):
        self.q = q_filter
        self.N, self.n_u, self.ts = N, n_u, ts
        coeffs, pad = q_filter._design(1.0 / ts)
        self.sos = q_filter.kind in ("butterworth", "first-order")
        self.coeffs = np.asarray(coeffs, dtype=float)
        self.zero_state = q_filter.ends == "zero-state"
        self.pad = 0 if self.zero_state else int(pad)
        if not self.zero_state and N <= self.pad:
            raise ParameterError(f"the trial is too short for this Q-filter: N must exceed the "
                                 f"padding {self.pad}")
        self.reverse = q_filter.passes == "backward-forward"
        if self.sos:
            if np.any(self.coeffs[:, 3] != 1.0):
                raise InternalError("second-order sections must have a0 = 1")
            self.zi = np.asarray(scipy.signal.sosfilt_zi(self.coeffs), dtype=float)
            self.n_state = 2 * len(self.coeffs)
        else:
            self.zi = np.asarray(scipy.signal.lfilter_zi(self.coeffs, [1.0]), dtype=float)
            self.n_state = len(self.coeffs) - 1
        self.M = N + 2 * self.pad

    def constants(self):
        if self.sos:
            out = [CArray("ilc_q_sos", self.coeffs, f"Q-filter ({self.q.kind}, "
                          f"{self.q.cutoff:g} Hz, order {self.q.order}): second-order "
                          f"sections [b0 b1 b2 1 a1 a2] per section")]
        else:
            out = [CArray("ilc_q_fir", self.coeffs, f"Q-filter (FIR, {self.q.cutoff:g} Hz, "
                          f"{len(self.coeffs)} taps): the taps b0..b{len(self.coeffs) - 1}")]
        if not self.zero_state:
            out.append(CArray("ilc_q_zi", self.zi, "the filter's steady state per unit "
                                                   "input (each pass starts at it times its "
                                                   "first sample)"))
        return out

    def work(self):
        return [WorkArray("q_ext", self.M, f"one channel of the next input, odd-extended by "
                          f"{self.pad} samples at each end (the Q-filter runs on it)"),
                WorkArray("q_state", self.n_state, "the Q-filter's state")]

    def macros(self, precision: str) -> dict[str, str]:
        out = {"ILC_Q_PAD": f"{self.pad}u", "ILC_Q_LEN": f"{self.M}u",
               "ILC_Q_STATES": f"{self.n_state}u"}
        if self.sos:
            out["ILC_Q_SECTIONS"] = f"{len(self.coeffs)}u"
        else:
            out["ILC_Q_TAPS"] = f"{len(self.coeffs)}u"
        return out

    def _pass_function(self) -> str:
        if self.sos:
            return """\
/* one causal pass of the second-order sections over z[0..len-1], in place, from the state st
 * (direct form II transposed, as scipy.signal.sosfilt) */
static void ilc_q_pass(ilc_real z[], size_t len, ilc_real st[])
{
    size_t n, s;
    for (n = 0u; n < len; ++n) {
        ilc_real v = z[n];
        for (s = 0u; s < ILC_Q_SECTIONS; ++s) {
            const ilc_real *c = &ilc_q_sos[6u * s];
            const ilc_real y = c[0] * v + st[2u * s];
            st[2u * s] = (c[1] * v - c[4] * y) + st[2u * s + 1u];
            st[2u * s + 1u] = c[2] * v - c[5] * y;
            v = y;
        }
        z[n] = v;
    }
}
"""
        return """\
/* one causal pass of the FIR filter over z[0..len-1], in place, from the state st
 * (direct form II transposed, as scipy.signal.lfilter) */
static void ilc_q_pass(ilc_real z[], size_t len, ilc_real st[])
{
    size_t n, t;
    for (n = 0u; n < len; ++n) {
        const ilc_real v = z[n];
        z[n] = st[0] + ilc_q_fir[0] * v;
        for (t = 0u; t + 2u < ILC_Q_TAPS; ++t) {
            st[t] = st[t + 1u] + v * ilc_q_fir[t + 1u];
        }
        st[ILC_Q_TAPS - 2u] = v * ilc_q_fir[ILC_Q_TAPS - 1u];
    }
}
"""

    def function(self) -> str:
        sample = "(ILC_N - 1u - n)" if self.reverse else "n"
        if self.zero_state:
            start = """\
        for (s = 0u; s < ILC_Q_STATES; ++s) {
            st[s] = ILC_0;
        }"""
            start2 = start
            extend = ""
        else:
            start = """\
        for (s = 0u; s < ILC_Q_STATES; ++s) {
            st[s] = ilc_q_zi[s] * z[0];
        }"""
            start2 = start
            extend = """\
        for (n = 0u; n < ILC_Q_PAD; ++n) {        /* odd extension, as scipy's odd_ext */
            z[n] = ILC_2 * z[ILC_Q_PAD] - z[2u * ILC_Q_PAD - n];
            z[ILC_Q_PAD + ILC_N + n] = ILC_2 * z[ILC_Q_PAD + ILC_N - 1u]
                - z[ILC_Q_PAD + ILC_N - 2u - n];
        }
"""
        return self._pass_function() + f"""
static void ilc_q_reverse(ilc_real z[], size_t len)
{{
    size_t i;
    for (i = 0u; i < len / 2u; ++i) {{
        const ilc_real t = z[i];
        z[i] = z[len - 1u - i];
        z[len - 1u - i] = t;
    }}
}}

/* the Q-filter on each channel of x, in place: {self.q.passes}, {self.q.ends} ends */
static void ilc_q_filter(ilc_real x[], ilc_work_t *work)
{{
    ilc_real *z = work->q_ext;
    ilc_real *st = work->q_state;
    size_t i, n, s;
    for (i = 0u; i < ILC_NU; ++i) {{
        for (n = 0u; n < ILC_N; ++n) {{
            z[ILC_Q_PAD + n] = x[{sample} * ILC_NU + i];
        }}
{extend}{start}
        ilc_q_pass(z, ILC_Q_LEN, st);             /* forward */
        ilc_q_reverse(z, ILC_Q_LEN);
{start2}
        ilc_q_pass(z, ILC_Q_LEN, st);             /* backward */
        ilc_q_reverse(z, ILC_Q_LEN);
        for (n = 0u; n < ILC_N; ++n) {{
            x[{sample} * ILC_NU + i] = z[ILC_Q_PAD + n];
        }}
    }}
}}
"""

    def call(self):
        return "ilc_q_filter(next, work);"

    def operations(self):
        per_sample = (Operations(mul=5 * len(self.coeffs), add=4 * len(self.coeffs))
                      if self.sos else
                      Operations(mul=len(self.coeffs), add=len(self.coeffs) - 1))
        ops = Operations()
        for kind, count in per_sample.items():
            ops[kind] = 2 * self.M * count * self.n_u
        ops["add"] += 2 * self.pad * self.n_u
        ops["mul"] += (2 * self.pad + (0 if self.zero_state else 2 * self.n_state)) * self.n_u
        return ops

    def _recursion(self):
        if self.sos:
            exact, absolute = _sos_step(self.coeffs, False), _sos_step(self.coeffs, True)
            depth = 3 * len(self.coeffs) + 5
        else:
            exact, absolute = _fir_step(self.coeffs, False), _fir_step(self.coeffs, True)
            depth = 4
        A, B, C, D = _step_matrices(exact, self.n_state, 1)
        Aa, Ba, Ca, Da = _step_matrices(absolute, self.n_state, 1)
        Z = np.zeros((self.n_state, 1)) if self.zero_state else self.zi.reshape(-1, 1)
        return A, B, C, D, Aa, Ba, Ca, Da, Z, depth

    def _extension_norms(self) -> tuple[float, float]:
        """``(||E||_2, || |E| ||_2)`` of the odd extension (1, 1 without one): from the Gram
        matrix of its end columns (the rest of E is an identity)."""
        if self.pad == 0:
            return 1.0, 1.0
        N, p = self.N, self.pad
        i = np.arange(p)
        rows = np.concatenate([i, i, p + np.arange(N), p + N + i, p + N + i])
        cols = np.concatenate([np.zeros(p, int), p - i, np.arange(N), np.full(p, N - 1),
                               N - 2 - i])
        vals = np.concatenate([np.full(p, 2.0), -np.ones(p), np.ones(N), np.full(p, 2.0),
                               -np.ones(p)])
        E = scipy.sparse.csr_array((vals, (rows, cols)), shape=(N + 2 * p, N))
        ends = np.unique(np.concatenate([np.arange(min(p + 1, N)),
                                         np.arange(max(N - p - 1, 0), N)]))
        out = []
        for M in (E, abs(E)):
            sub = M[:, ends].toarray()
            out.append(math.sqrt(max(1.0, float(np.linalg.eigvalsh(sub.T @ sub)[-1])))
                       * (1.0 + 1e-9))
        return out[0], out[1]

    def norm(self) -> float:
        """A bound of the exact filter's norm on the trial (the product of its parts')."""
        nE, _ = self._extension_norms()
        A, B, C, D, Aa, Ba, Ca, Da, Z, _ = self._recursion()
        n1, _ = pass_bound(A, B, C, D, Aa, Ba, Ca, Da, Z, 1, self.M, 2.0 ** -53)
        return nE * n1 * n1

    def bound(self, sigs, u):
        nE, nEa = self._extension_norms()
        n1, eta = pass_bound(*self._recursion(), self.M, u)
        s = linear((sigs["x"], nE, u * nEa if self.pad else 0.0))
        s = linear((s, n1, eta))
        return linear((s, n1, eta))


class DCTStage(Stage):
    """Q-filter of kind dct: Butterworth magnitude on the orthonormal DCT-II coefficients."""

    function_name = "ilc_q_filter"
    inputs = ("x",)
    output = "x"

    def __init__(self, q_filter, N: int, n_u: int, ts: float):
        self.q, self.N, self.n_u, self.ts = q_filter, N, n_u, ts
        g = q_filter.magnitude(np.arange(N) / (2.0 * N * ts), ts)
        s2 = np.full(N, 2.0 / N)
        s2[0] = 1.0 / N
        self.g = np.asarray(g, dtype=float)
        self.gain = s2 * self.g                       # s_k^2 g_k
        self.table = np.cos(np.pi * np.arange(4 * N) / (2.0 * N))

    def constants(self):
        return [CArray("ilc_q_gain", self.gain, f"Q-filter (DCT, {self.q.cutoff:g} Hz, order "
                       f"{self.q.order}): s_k^2 g_k, g_k = 1/(1 + (f_k/f_c)^(2 n)) at "
                       f"f_k = k/(2 N ts), s_k^2 = 1/N (k = 0), 2/N"),
                CArray("ilc_q_cos", self.table, "cos(pi m / (2 N)), m = 0..4N-1")]

    def work(self):
        return [WorkArray("q_in", self.N, "one channel of the input of the Q-filter"),
                WorkArray("q_coef", self.N, "its DCT coefficients, scaled by the gain")]

    def function(self) -> str:
        return """\
/* the DCT Q-filter on each channel of x, in place: y = C' diag(s^2 g) C x */
static void ilc_q_filter(ilc_real x[], ilc_work_t *work)
{
    size_t i, k, m;
    for (i = 0u; i < ILC_NU; ++i) {
        for (m = 0u; m < ILC_N; ++m) {
            work->q_in[m] = x[m * ILC_NU + i];
        }
        for (k = 0u; k < ILC_N; ++k) {          /* X_k = sum_m x_m cos(pi k (2m+1) / 2N) */
            ilc_real acc = ILC_0;
            unsigned long idx = (unsigned long)k;
            const unsigned long step = (2UL * (unsigned long)k) % (4UL * ILC_N);
            for (m = 0u; m < ILC_N; ++m) {
                acc += work->q_in[m] * ilc_q_cos[idx];
                idx += step;
                if (idx >= 4UL * ILC_N) {
                    idx -= 4UL * ILC_N;
                }
            }
            work->q_coef[k] = ilc_q_gain[k] * acc;
        }
        for (m = 0u; m < ILC_N; ++m) {          /* y_m = sum_k c_k cos(pi k (2m+1) / 2N) */
            ilc_real acc = ILC_0;
            unsigned long idx = 0UL;
            const unsigned long step = (2UL * (unsigned long)m + 1UL) % (4UL * ILC_N);
            for (k = 0u; k < ILC_N; ++k) {
                acc += work->q_coef[k] * ilc_q_cos[idx];
                idx += step;
                if (idx >= 4UL * ILC_N) {
                    idx -= 4UL * ILC_N;
                }
            }
            x[m * ILC_NU + i] = acc;
        }
    }
}
"""

    def call(self):
        return "ilc_q_filter(next, work);"

    def operations(self):
        n = self.N * self.N * self.n_u
        return Operations(mul=2 * n + self.N * self.n_u, add=2 * n)

    def _abs_cos_norm(self) -> float:
        r"""A bound of :math:`\||C_u|\|_2` (the unscaled cosine matrix's absolute values):
        :math:`\sqrt{\|\cdot\|_1\|\cdot\|_\infty}`, its largest row and column sums (equal:
        the matrix of :math:`|\cos(\pi k(2m+1)/2N)|` has them computed here exactly)."""
        N = self.N
        best = 0.0
        m = 2 * np.arange(N) + 1
        for k in range(N):
            row = np.abs(self.table[(k * m) % (4 * N)]).sum()
            best = max(best, float(row))
        cols = 0.0
        ks = np.arange(N)
        for j in range(N):
            cols = max(cols, float(np.abs(self.table[(ks * (2 * j + 1)) % (4 * N)]).sum()))
        return math.sqrt(best * cols) * (1.0 + 1e-9)

    def norm(self) -> float:
        return float(np.max(self.g))

    def bound(self, sigs, u):
        s = sigs["x"]
        N = self.N
        cu = self._abs_cos_norm()
        gN = gamma(N + 1, u)                       # N products and sums, the table rounded
        sqrtN = math.sqrt(N)
        # X' = C_u x: ||C_u|| = sqrt(N)
        errX = sqrtN * s.err + gN * cu * (s.mag + s.err)
        magX = sqrtN * s.mag
        gmax = float(np.max(self.gain))
        errZ = gmax * errX + gamma(2, u) * gmax * (magX + errX)
        # y = C_u' Z: the error of X' reaches y through C_o' diag(s g), norm max s_k g_k
        sg = float(np.max(np.sqrt(np.where(np.arange(N) == 0, 1.0 / N, 2.0 / N)) * self.g))
        magZ = sg * s.mag
        err = (sg * (sqrtN * s.err + gN * cu * (s.mag + s.err))
               + sqrtN * (gamma(2, u) * gmax * (magX + errX))
               + gN * cu * (magZ + errZ))
        return Sig(self.norm() * s.mag, err)


# ---------------------------------------------------------------------------------------------
# the LTI filters of a Q/L law
# ---------------------------------------------------------------------------------------------
def _state_space(table: dict):
    A = np.asarray(table.get("A", []), dtype=float)
    D = np.atleast_2d(np.asarray(table["D"], dtype=float))
    n = A.shape[0] if A.size else 0
    A = A.reshape(n, n)
    B = np.asarray(table.get("B", []), dtype=float).reshape(n, D.shape[1])
    C = np.asarray(table.get("C", []), dtype=float).reshape(D.shape[0], n)
    return A, B, C, D


class _LTIRun:
    """C of one run of an LTI filter from rest over the samples of a signal."""

    def __init__(self, prefix: str, table: dict):
        self.prefix = prefix
        self.A, self.B, self.C, self.D = _state_space(table)
        self.n = self.A.shape[0]
        self.n_out, self.n_in = self.D.shape

    def constants(self, what: str) -> list[CArray]:
        out = [CArray(f"{self.prefix}_d", self.D, f"{what}: D [out][in]")]
        if self.n:
            out += [CArray(f"{self.prefix}_a", self.A, f"{what}: A [state][state]"),
                    CArray(f"{self.prefix}_b", self.B, f"{what}: B [state][in]"),
                    CArray(f"{self.prefix}_c", self.C, f"{what}: C [out][state]")]
        return out

    def work(self, what: str) -> list[WorkArray]:
        if not self.n:
            return []
        return [WorkArray(f"{self.prefix}_x", self.n, f"{what}: the state"),
                WorkArray(f"{self.prefix}_xn", self.n, f"{what}: the next state")]

    def out_rows(self, v: str, out: str) -> str:
        """``out[o] = (C x)[o] + (D v)[o]`` (numpy's C @ x + D @ v)."""
        p = self.prefix
        cx = (f"""
            for (s = 0u; s < {self.n}u; ++s) {{
                acc_c += {p}_c[o * {self.n}u + s] * work->{p}_x[s];
            }}""" if self.n else "")
        return f"""\
        for (o = 0u; o < {self.n_out}u; ++o) {{
            ilc_real acc_c = ILC_0;
            ilc_real acc_d = ILC_0;{cx}
            for (s = 0u; s < {self.n_in}u; ++s) {{
                acc_d += {p}_d[o * {self.n_in}u + s] * {v}[s];
            }}
            {out} = acc_c + acc_d;
        }}"""

    def state_rows(self, v: str) -> str:
        """``x = A x + B v`` (numpy's A @ x + B @ v), through the next-state buffer."""
        if not self.n:
            return ""
        p = self.prefix
        return f"""
        for (o = 0u; o < {self.n}u; ++o) {{
            ilc_real acc_a = ILC_0;
            ilc_real acc_b = ILC_0;
            for (s = 0u; s < {self.n}u; ++s) {{
                acc_a += {p}_a[o * {self.n}u + s] * work->{p}_x[s];
            }}
            for (s = 0u; s < {self.n_in}u; ++s) {{
                acc_b += {p}_b[o * {self.n_in}u + s] * {v}[s];
            }}
            work->{p}_xn[o] = acc_a + acc_b;
        }}
        for (o = 0u; o < {self.n}u; ++o) {{
            work->{p}_x[o] = work->{p}_xn[o];
        }}"""

    def reset(self) -> str:
        if not self.n:
            return ""
        return f"""
    for (o = 0u; o < {self.n}u; ++o) {{
        work->{self.prefix}_x[o] = ILC_0;
    }}"""

    def operations(self, samples: int) -> Operations:
        per = (self.n_out * (self.n + self.n_in) + self.n * (self.n + self.n_in))
        return Operations(mul=samples * per, add=samples * per)

    def bound(self, length: int, u: float) -> tuple[float, float]:
        depth = max(self.n, 0) + self.n_in + 2
        A = self.A if self.n else np.zeros((1, 1))
        B = self.B if self.n else np.zeros((1, self.n_in))
        C = self.C if self.n else np.zeros((self.n_out, 1))
        return pass_bound(A, B, C, self.D, abs(A), abs(B), abs(C), abs(self.D),
                          np.zeros((A.shape[0], self.n_in)), depth, length, u)


class LTIQStage(Stage):
    """Q-filter of a Q/L law: an LTI filter from rest (forward, then backward: zero phase)."""

    function_name = "ilc_q_filter"
    inputs = ("x",)
    output = "x"

    def __init__(self, table: dict, zero_phase: bool, N: int):
        self.run = _LTIRun("ilc_qf", table)
        self.zero_phase, self.N = zero_phase, N

    def constants(self):
        return self.run.constants("the Q-filter of the Q/L law")

    def work(self):
        return self.run.work("the Q-filter") + [
            WorkArray("q_v", self.run.n_in, "the Q-filter's input at one sample"),
            WorkArray("q_y", self.run.n_out, "the Q-filter's output at one sample")]

    def function(self) -> str:
        r = self.run
        forward = f"""\
    {r.reset().strip()}
    for (k = 0u; k < ILC_N; ++k) {{
        for (o = 0u; o < ILC_NU; ++o) {{
            work->q_v[o] = x[k * ILC_NU + o];
        }}
{r.out_rows("work->q_v", "work->q_y[o]")}{r.state_rows("work->q_v")}
        for (o = 0u; o < ILC_NU; ++o) {{
            x[k * ILC_NU + o] = work->q_y[o];
        }}
    }}"""
        backward = forward.replace("for (k = 0u; k < ILC_N; ++k) {",
                                   "for (k = ILC_N; k-- > 0u;) {", 1) if self.zero_phase else ""
        how = " (forward, then backward: zero phase)" if self.zero_phase else ""
        return f"""\
/* the LTI Q-filter of the Q/L law on x, in place, from rest{how} */
static void ilc_q_filter(ilc_real x[], ilc_work_t *work)
{{
    size_t k, o, s;
{forward}
{backward}
}}
"""

    def call(self):
        return "ilc_q_filter(next, work);"

    def operations(self):
        ops = self.run.operations(self.N)
        if self.zero_phase:
            ops = Operations({k: 2 * v for k, v in ops.items()})
        return ops

    def bound(self, sigs, u):
        n, eta = self.run.bound(self.N, u)
        s = linear((sigs["x"], n, eta))
        return linear((s, n, eta)) if self.zero_phase else s


class LearningFilterStage(Stage):
    """x = u + (L' e)(k + m): the learning filter of a Q/L law, read ahead by its advance m."""

    function_name = "ilc_learning_filter"
    inputs = ("u", "e")
    output = "x"

    def __init__(self, table: dict, advance: int, N: int, applied: str):
        self.run = _LTIRun("ilc_lf", table)
        self.advance, self.N, self.applied = advance, N, applied

    def constants(self):
        return self.run.constants("the learning filter L' of the Q/L law")

    def work(self):
        return self.run.work("the learning filter") + [
            WorkArray("lf_v", self.run.n_in, "the learning filter's input at one sample"),
            WorkArray("lf_y", self.run.n_out, "the learning filter's output at one sample")]

    def function(self) -> str:
        r = self.run
        store = """\
        for (o = 0u; o < ILC_NU; ++o) {
            x[(k - ILC_ADVANCE) * ILC_NU + o] = u[(k - ILC_ADVANCE) * ILC_NU + o]
                + work->lf_y[o];
        }"""
        if self.advance:
            store = ("        if (k >= ILC_ADVANCE) {\n"
                     + "\n".join("    " + line for line in store.splitlines()) + "\n        }")
        return f"""\
/* x(k) = u(k) + (L' e)(k + m), the filter run from rest over N + m samples (e zero past N) */
static void ilc_learning_filter(const ilc_real u[], const ilc_real e[], ilc_work_t *work,
                                ilc_real x[])
{{
    size_t k, o, s;
    {r.reset().strip()}
    for (k = 0u; k < ILC_N + ILC_ADVANCE; ++k) {{
        for (o = 0u; o < ILC_NY; ++o) {{
            work->lf_v[o] = (k < ILC_N) ? e[k * ILC_NY + o] : ILC_0;
        }}
{r.out_rows("work->lf_v", "work->lf_y[o]")}
{store}{r.state_rows("work->lf_v")}
    }}
}}
"""

    def call(self):
        return f"ilc_learning_filter({self.applied}, work->e, work, next);"

    def operations(self):
        ops = self.run.operations(self.N + self.advance)
        ops["add"] += self.N * self.run.n_out
        return ops

    def bound(self, sigs, u):
        n, eta = self.run.bound(self.N + self.advance, u)
        v = linear((sigs["e"], n, eta))
        if "L1e" in sigs:                       # the exact run's (L' e)(k + m), a priori
            v = Sig(sigs["L1e"].mag, v.err)
        return linear((sigs["u"], 1.0, gamma(1, u)), (v, 1.0, gamma(1, u)))


def q_stage(q_filter, N: int, n_u: int, ts: float) -> Stage:
    """The stage of a :class:`~ilc_analysis.laws.QFilter` (two-pass kinds or DCT)."""
    if q_filter.kind == "dct":
        return DCTStage(q_filter, N, n_u, ts)
    return TwoPassStage(q_filter, N, n_u, ts)
