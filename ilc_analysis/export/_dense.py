r"""Stages of the generated update that apply a lifted matrix: norm-optimal and gradient ILC.

* :class:`DenseStage` — :math:`x = Q_{no}(u + L_{no}e)` of norm-optimal ILC on its lifted
  model (:attr:`~ilc_analysis.laws.NormOptimalLaw.gains`, as ``learn`` computes it: two
  matrix-vector products with the stored matrices);
* :class:`GradientStage` — :math:`x = u + \beta\,\hat G^\top e` of gradient ILC: for a model
  lifted from an LTI system :math:`\hat G` is block Toeplitz, so only its first block column
  (the Markov parameters :math:`h_0..h_{N-1}`) is stored and
  :math:`(\hat G^\top e)(k) = \sum_{i \ge k} h_{i-k}^\top e(i)`; an LTV lifting stores
  :math:`\hat G^\top`.

Rounding: a product of a stored matrix M (each entry held rounded) with a vector of length n
is within :math:`\gamma_{n+1}|M||x|` of the exact one (Higham, eq. 3.13), so in the 2-norm
within :math:`\gamma_{n+1}\,\||M|\|_2\,\|x\|_2`; for block Toeplitz
:math:`\||G|\|_2 \le \sum_k \||h_k|\|_2`.
"""

from __future__ import annotations

import numpy as np

from ._c import CArray
from ._signals import abs_norm, spectral_norm
from ._stage import Operations, Sig, Stage, WorkArray, gamma, linear

__all__ = ["DenseStage", "GradientStage"]


class DenseStage(Stage):
    """x = Q_no (u + L_no e): norm-optimal ILC with its stored lifted matrices."""

    function_name = "ilc_norm_optimal"
    inputs = ("u", "e")
    output = "x"

    def __init__(self, L: np.ndarray, Q: np.ndarray | None, applied: str):
        self.L = np.asarray(L, dtype=float)
        self.Q = None if Q is None else np.asarray(Q, dtype=float)
        self.q, self.p = self.L.shape
        self.applied = applied

    def constants(self):
        out = [CArray("ilc_no_l", self.L, f"L_no = a H_a^-1 G' W_e, ({self.q} x {self.p}) "
                                          f"[row][column], rows (k, i), columns (k, j)")]
        if self.Q is not None:
            out.append(CArray("ilc_no_q", self.Q, f"Q_no = (H + W_u)^-1 H_a, ({self.q} x "
                                                  f"{self.q}) [row][column]"))
        return out

    def work(self):
        return [] if self.Q is None else [WorkArray("no_v", self.q, "u + L_no e, the input of "
                                                                    "Q_no")]

    def function(self) -> str:
        target = "work->no_v" if self.Q is not None else "x"
        q_part = """
    for (r = 0u; r < ILC_N * ILC_NU; ++r) {     /* x = Q_no v */
        ilc_real acc = ILC_0;
        for (c = 0u; c < ILC_N * ILC_NU; ++c) {
            acc += ilc_no_q[r * (ILC_N * ILC_NU) + c] * work->no_v[c];
        }
        x[r] = acc;
    }""" if self.Q is not None else ""
        work = "ilc_work_t *work, " if self.Q is not None else ""
        return """\
static void ilc_norm_optimal(const ilc_real u[], const ilc_real e[], WORKilc_real x[])
{
    size_t r, c;
    for (r = 0u; r < ILC_N * ILC_NU; ++r) {     /* v = u + L_no e */
        ilc_real acc = ILC_0;
        for (c = 0u; c < ILC_N * ILC_NY; ++c) {
            acc += ilc_no_l[r * (ILC_N * ILC_NY) + c] * e[c];
        }
        TARGET[r] = u[r] + acc;
    }QPART
}
""".replace("WORK", work).replace("TARGET", target).replace("QPART", q_part)

    def call(self):
        if self.Q is None:
            return f"ilc_norm_optimal({self.applied}, work->e, next);"
        return f"ilc_norm_optimal({self.applied}, work->e, work, next);"

    def operations(self):
        n = self.q * self.p + (0 if self.Q is None else self.q * self.q)
        return Operations(mul=n, add=n + self.q)

    def bound(self, sigs, u):
        c = gamma(self.p + 2, u)
        v = linear((sigs["u"], 1.0, c), (sigs["e"], spectral_norm(self.L),
                                         c * abs_norm(self.L)))
        if "L1e" in sigs:                       # the exact run's L_no e, bounded a priori
            v = Sig(sigs["u"].mag + sigs["L1e"].mag, v.err)
        if self.Q is None:
            return v
        return linear((v, spectral_norm(self.Q), gamma(self.q + 1, u) * abs_norm(self.Q)))


class GradientStage(Stage):
    """x = u + beta G' e: gradient ILC with its lifted model (Markov parameters or G')."""

    function_name = "ilc_gradient"
    inputs = ("u", "e")
    output = "x"

    def __init__(self, beta: float, G: np.ndarray, N: int, n_u: int, n_y: int,
                 toeplitz: bool, applied: str):
        self.beta = float(beta)
        self.N, self.n_u, self.n_y = N, n_u, n_y
        self.toeplitz = toeplitz
        G = np.asarray(G, dtype=float)
        self.G = G
        if toeplitz:
            self.markov = np.ascontiguousarray(G[:, :n_u].reshape(N, n_y, n_u))
        self.applied = applied

    def constants(self):
        if self.toeplitz:
            return [CArray("ilc_markov", self.markov, "the model's Markov parameters h_0.."
                           "h_{N-1} (first block column of its lifted G), [lag][j][i]")]
        return [CArray("ilc_model_gt", self.G.T, f"the model's lifted G transposed, "
                       f"({self.N * self.n_u} x {self.N * self.n_y}) [row][column]")]

    def function(self) -> str:
        if self.toeplitz:
            body = """\
    size_t k, i, m, j;
    for (k = 0u; k < ILC_N; ++k) {
        for (i = 0u; i < ILC_NU; ++i) {
            ilc_real acc = ILC_0;          /* (G' e)(k, i) = sum_{m >= k} h_{m-k}' e(m) */
            for (m = k; m < ILC_N; ++m) {
                for (j = 0u; j < ILC_NY; ++j) {
                    acc += ilc_markov[((m - k) * ILC_NY + j) * ILC_NU + i] * e[m * ILC_NY + j];
                }
            }
            x[k * ILC_NU + i] = u[k * ILC_NU + i] + ILC_BETA * acc;
        }
    }"""
        else:
            body = """\
    size_t r, c;
    for (r = 0u; r < ILC_N * ILC_NU; ++r) {
        ilc_real acc = ILC_0;
        for (c = 0u; c < ILC_N * ILC_NY; ++c) {
            acc += ilc_model_gt[r * (ILC_N * ILC_NY) + c] * e[c];
        }
        x[r] = u[r] + ILC_BETA * acc;
    }"""
        return f"""\
static void ilc_gradient(const ilc_real u[], const ilc_real e[], ilc_real x[])
{{
{body}
}}
"""

    def call(self):
        return f"ilc_gradient({self.applied}, work->e, next);"

    def operations(self):
        if self.toeplitz:
            n = self.N * (self.N + 1) // 2 * self.n_u * self.n_y
        else:
            n = self.N * self.n_u * self.N * self.n_y
        return Operations(mul=n + self.N * self.n_u, add=n + self.N * self.n_u)

    def _norms(self) -> tuple[float, float]:
        if self.toeplitz:
            blocks = self.markov
            n = sum(spectral_norm(b) for b in blocks) * (1.0 + 1e-9)
            a = sum(abs_norm(b) for b in blocks) * (1.0 + 1e-9)
            return n, a
        return spectral_norm(self.G), abs_norm(self.G)

    def bound(self, sigs, u):
        n, a = self._norms()
        c = gamma(self.N * self.n_y + 3, u)   # the products, beta held rounded, its product,
        out = linear((sigs["u"], 1.0, c),     # the sum with u
                     (sigs["e"], self.beta * n, c * self.beta * a))
        if "L1e" in sigs:                       # the exact run's beta G' e, bounded a priori
            out = Sig(sigs["u"].mag + sigs["L1e"].mag, out.err)
        return out
