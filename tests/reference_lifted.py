r"""An independent dense reference for the lifted PD-ILC law (tests only).

Nothing here imports :mod:`ilc_analysis`: every quantity is rebuilt from the plant matrices and
the gains with plain numpy/scipy, following the index convention documented in
:mod:`ilc_analysis.laws`:

* zero-order hold: :math:`\exp\left(\begin{bmatrix}A & B\\0 & 0\end{bmatrix}T_s\right)
  = \begin{bmatrix}A_d & B_d\\0 & I\end{bmatrix}`;
* Markov parameters :math:`h_0 = D`, :math:`h_m = C A_d^{m-1} B_d` (direct matrix powers), the
  shift s = the first m with :math:`h_m \ne 0`;
* lifted plant: input :math:`u = [u(0);\dots;u(N-1)]`, output :math:`y = [y(s);\dots;y(N-1+s)]`,
  block (i, j) of G is :math:`h_{s+i-j}` for :math:`i \ge j`, zero above;
* open-loop term at input sample k reads lifted error index :math:`k+\ell` (lead
  :math:`\ell`) and its backward difference, closed-loop term reads index :math:`k-s` and its
  backward difference; every index outside ``0..N-1`` reads zero;
* Q-filter: forward-backward Butterworth (second-order sections) or Hamming FIR with odd
  padding (scipy's ``sosfiltfilt``/``filtfilt`` on the columns of I), or the DCT-II domain
  gain :math:`1/(1+(f/f_c)^{2n})` at :math:`f_k = k/(2NT_s)` (an explicit cosine matrix); on
  ``n_u`` channels :math:`Q\otimes I_{n_u}`;
* :math:`T = (I + L_2G)^{-1}\,Q\,((1-a)I - L_1G)` by block forward substitution.

:class:`DenseReference` then gives ρ(T), ‖T‖₂ (dense SVD), ‖T‖∞ (row sums) and
:math:`\|T^k\|_2` by dense powers, computed lazily. Its spectral radius is **certified**, not
read off a dense eigen-solver (which is off by :math:`\varepsilon^{1/N}` for a defective T):

* block lower-triangular T: the eigenvalues of the diagonal blocks (exact up to rounding of
  small matrices);
* otherwise: only :math:`\rho(T) \le \min_k \|T^k\|_2^{1/k}` (an upper bound from the
  powers) is trusted; the dense eigenvalues are a diagnostic.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.signal

#: Relative size below which a Markov parameter counts as zero (the shift).
SHIFT_RTOL = 1e-10


# ---------------------------------------------------------------------------------------------
# plant
# ---------------------------------------------------------------------------------------------
def zoh(A, B, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold matrices (Ad, Bd) from one matrix exponential."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.atleast_2d(np.asarray(B, dtype=float))
    n, m = A.shape[0], B.shape[1]
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = scipy.linalg.expm(M * ts)
    return E[:n, :n], E[:n, n:]


def markov(Ad, Bd, C, D, m: int) -> np.ndarray:
    """h_m = C Ad^(m-1) Bd (m >= 1), h_0 = D, by a direct matrix power."""
    if m == 0:
        return np.asarray(D, dtype=float)
    return C @ np.linalg.matrix_power(Ad, m - 1) @ Bd


def shift_of(Ad, Bd, C, D) -> int:
    """The first m with h_m != 0 (relative to the largest of the first n_x + 1)."""
    hs = [markov(Ad, Bd, C, D, m) for m in range(Ad.shape[0] + 2)]
    scale = max(np.max(np.abs(h)) for h in hs)
    for m, h in enumerate(hs):
        if np.max(np.abs(h)) > SHIFT_RTOL * scale:
            return m
    raise ValueError("no output responds to the input")


def lifted_plant(Ad, Bd, C, D, N: int, s: int) -> np.ndarray:
    """G with block (i, j) = h_{s+i-j} for i >= j (N n_y x N n_u)."""
    n_y, n_u = C.shape[0], Bd.shape[1]
    G = np.zeros((N * n_y, N * n_u))
    # h_{s+m} for m = 0..N-1 by repeated multiplication of the state-transition power
    blocks = []
    if s == 0:
        blocks.append(np.asarray(D, dtype=float))
        P = Bd.copy()
        start = 1
    else:
        P = np.linalg.matrix_power(Ad, s - 1) @ Bd
        start = 0
    for _ in range(start, N):
        blocks.append(C @ P)
        P = Ad @ P
    for i in range(N):
        for j in range(i + 1):
            G[i * n_y:(i + 1) * n_y, j * n_u:(j + 1) * n_u] = blocks[i - j]
    return G


# ---------------------------------------------------------------------------------------------
# law
# ---------------------------------------------------------------------------------------------
def _per_sample(K, N: int) -> np.ndarray:
    K = np.asarray(K, dtype=float)
    return K if K.ndim == 3 else np.broadcast_to(K, (N,) + K.shape)


def pd_operators(Phi1, Phi2, Psi1, Psi2, lead: int, N: int, s: int, ts: float):
    """Dense L1, L2 (N n_u x N n_y), entry by entry from the index convention."""
    P1, P2, S1, S2 = (_per_sample(K, N) for K in (Phi1, Phi2, Psi1, Psi2))
    n_u, n_y = P1.shape[1:]
    L1 = np.zeros((N * n_u, N * n_y))
    L2 = np.zeros((N * n_u, N * n_y))

    def add(L, k, j, M):
        if 0 <= j < N:
            L[k * n_u:(k + 1) * n_u, j * n_y:(j + 1) * n_y] += M

    for k in range(N):
        # open loop: Psi1 e(k+l) + Phi1 (e(k+l) - e(k+l-1))/ts
        add(L1, k, k + lead, S1[k] + P1[k] / ts)
        add(L1, k, k + lead - 1, -P1[k] / ts)
        # closed loop: the error measured at sample k is lifted index k - s
        add(L2, k, k - s, S2[k] + P2[k] / ts)
        add(L2, k, k - s - 1, -P2[k] / ts)
    return L1, L2


def dct_matrix(N: int) -> np.ndarray:
    """Orthonormal DCT-II matrix: C[k, n] = sqrt(2/N) c_k cos(pi k (2n+1) / (2N))."""
    k = np.arange(N)[:, None]
    n = np.arange(N)[None, :]
    C = np.sqrt(2.0 / N) * np.cos(np.pi * k * (2 * n + 1) / (2 * N))
    C[0] /= np.sqrt(2.0)
    return C


def q_single(kind: str, cutoff: float, order: int, N: int, ts: float) -> np.ndarray:
    """The N x N filter on one channel."""
    fs = 1.0 / ts
    eye = np.eye(N)
    if kind == "dct":
        f = np.arange(N) / (2.0 * N * ts)
        gain = 1.0 / (1.0 + (f / cutoff) ** (2 * order))
        C = dct_matrix(N)
        return C.T @ (gain[:, None] * C)
    if kind == "butterworth":
        sos = scipy.signal.butter(order, cutoff, fs=fs, output="sos")
        return scipy.signal.sosfiltfilt(sos, eye, axis=0, padtype="odd")
    if kind == "fir":
        b = scipy.signal.firwin(order + 1, cutoff, fs=fs)
        return scipy.signal.filtfilt(b, [1.0], eye, axis=0, padtype="odd", padlen=3 * len(b))
    raise ValueError(kind)


def q_lifted(kind, cutoff, order, N, n_u, ts) -> np.ndarray:
    return np.kron(q_single(kind, cutoff, order, N, ts), np.eye(n_u))


def learning_operator(G, L1, L2, a: float, Q=None, block: int = 1):
    r"""T = (I + L2 G)^-1 Q ((1-a) I - L1 G) by block forward substitution.

    L2 G is strictly block lower-triangular (the closed-loop term reads errors before the
    current sample), so :math:`T_k = M_k - \sum_{j<k}(L_2G)_{kj}T_j` row block by row block,
    with :math:`M = Q((1-a)I - L_1G)`. When M is block lower-triangular (no lead, no Q) the
    result is exactly so too (exact zeros above, diagonal blocks exactly those of M), which
    keeps rounding out of the triangular structure the spectral radius is read from.
    Returns ``(T, triangular)``.
    """
    n = G.shape[1]
    M = (1.0 - a) * np.eye(n) - L1 @ G
    if Q is not None:
        M = Q @ M
    L2G = L2 @ G
    N = n // block
    for k in range(N):
        if np.any(L2G[k * block:(k + 1) * block, k * block:] != 0.0):
            raise ValueError("L2 G is not strictly block lower-triangular")
    triangular = all(not np.any(M[k * block:(k + 1) * block, (k + 1) * block:])
                     for k in range(N))
    T = np.array(M, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, N):
            rows = slice(k * block, (k + 1) * block)
            T[rows] -= L2G[rows, :k * block] @ T[:k * block]
    return T, triangular


def input_error_offset(G, L1, L2, a, Q, u_d, u0) -> np.ndarray:
    r"""c of :math:`\Delta u_{i+1} = T\Delta u_i + c` (realisable reference y_d = G u_d,
    no free response): :math:`c = S(u_d - Q((1-a)u_d + a u_0))`."""
    n = G.shape[1]
    Qm = np.eye(n) if Q is None else Q
    return np.linalg.solve(np.eye(n) + L2 @ G, u_d - Qm @ ((1.0 - a) * u_d + a * u0))


# ---------------------------------------------------------------------------------------------
# verdict quantities
# ---------------------------------------------------------------------------------------------
def diagonal_blocks(T: np.ndarray, b: int):
    """The b x b diagonal blocks of T."""
    return [T[i * b:(i + 1) * b, i * b:(i + 1) * b] for i in range(T.shape[0] // b)]


class DenseReference:
    """Dense verdict quantities of T, powers computed lazily (see module docstring)."""

    def __init__(self, T: np.ndarray, block: int, triangular: bool):
        self.T = np.asarray(T, dtype=float)
        self.n = T.shape[0]
        self.blocks = diagonal_blocks(self.T, block) if triangular else None
        self._norms = {}          # k -> ||T^k||_2
        self._power = (0, np.eye(self.n))
        self._norm2 = None

    # plain quantities -----------------------------------------------------------------------
    @property
    def triangular(self) -> bool:
        return self.blocks is not None

    @property
    def block_scale(self) -> float:
        return max(np.linalg.norm(B, 2) for B in self.blocks)

    def rho_exact(self) -> float | None:
        """Largest |eigenvalue| of the diagonal blocks (block-triangular T only)."""
        if self.blocks is None:
            return None
        return float(max(np.max(np.abs(np.linalg.eigvals(B))) for B in self.blocks))

    def rho_dense(self) -> float:
        """Dense eigen-solver estimate (unreliable for non-normal T; diagnostics only)."""
        return float(np.max(np.abs(np.linalg.eigvals(self.T))))

    def norm_2(self) -> float:
        if self._norm2 is None:
            self._norm2 = float(np.linalg.svd(self.T, compute_uv=False)[0])
            self._norms[1] = self._norm2
        return self._norm2

    def norm_inf(self) -> float:
        return float(np.max(np.sum(np.abs(self.T), axis=1)))

    # powers ---------------------------------------------------------------------------------
    def power_norm(self, k: int) -> float:
        """||T^k||_2 by dense products from the last computed power (k increasing)."""
        if k in self._norms:
            return self._norms[k]
        j, P = self._power
        if k < j:
            P, j = np.eye(self.n), 0
        with np.errstate(over="ignore", invalid="ignore"):
            while j < k:
                P = P @ self.T
                j += 1
                if not np.all(np.isfinite(P)):
                    self._norms[j] = math.inf
                    self._power = (j, P)
                    return math.inf
                if j not in self._norms and (j == k or j < 4):
                    self._norms[j] = float(np.linalg.svd(P, compute_uv=False)[0])
        self._power = (j, P)
        return self._norms[k]

    def walk(self, k_max: int, *, stop_below: float | None = None,
             stop_above: float = 1e300) -> list[float]:
        """||T^k||_2 for k = 1..K, K <= k_max: stops at the first value below ``stop_below``
        or above ``stop_above``."""
        out = []
        for k in range(1, k_max + 1):
            v = self.power_norm(k)
            out.append(v)
            if stop_below is not None and v < stop_below:
                break
            if not math.isfinite(v) or v > stop_above:
                break
        return out

    def transient_peak(self, k_max: int, band: float):
        """(peak over every k, settled) from the dense powers: once ||T^k0|| < 1 - band no
        later power exceeds the maximum of the earlier ones."""
        norms = self.walk(k_max, stop_below=1.0 - band)
        settled = norms[-1] < 1.0 - band
        return float(max(norms)), settled

    def rho_upper(self, k_max: int) -> float:
        """min_k ||T^k||_2^(1/k) over k <= k_max (an upper bound of rho)."""
        norms = self.walk(k_max, stop_below=0.5)
        return float(min(v ** (1.0 / k) for k, v in enumerate(norms, start=1)))
