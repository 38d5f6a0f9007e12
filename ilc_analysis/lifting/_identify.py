r"""The lifted model identified from recorded trials: Markov parameters with confidence bounds.

From R recorded trials (input :math:`u_r(0..N-1)`, output window :math:`y_r(s..N-1+s)`, the
index convention of :mod:`ilc_analysis.laws`), each started from rest (or with a stated free
response :math:`d_r` subtracted), the finite impulse response (FIR) model

.. math::

    y_r(s + k) = \sum_{i=0}^{M-1} h_i\,u_r(k - i) + d_r(k) + v_r(k),\qquad u_r(j) = 0
    \ \text{for}\ j < 0,

is a linear regression :math:`Y = \Phi\Theta + V` whose regressor :math:`\Phi` stacks, over the
trials, the rows :math:`[u_r(k)^\top, u_r(k-1)^\top, \dots, u_r(k-M+1)^\top]` and whose
parameter :math:`\Theta` (``(M n_u, n_y)``) stacks :math:`h_i^\top`: output channel o has the
parameter column :math:`\theta_o`. Least squares :math:`\hat\Theta = (\Phi^\top\Phi)^{-1}
\Phi^\top Y`; with :math:`p = M n_u` parameters per channel and n rows,

.. math::

    \operatorname{cov}\hat\theta_o = \sigma_o^2(\Phi^\top\Phi)^{-1},\qquad
    \hat\sigma_o^2 = \frac{\|y_o - \Phi\hat\theta_o\|^2}{n - p}\quad\text{(residuals)},

or, from trials repeated with the same input, the pure-error estimate
:math:`\hat\sigma_o^2 = \sum_g\sum_{r\in g}\|y_{r,o} - \bar y_{g,o}\|^2 / \sum_g N(|g| - 1)`,
which does not depend on the FIR model being right. Under the **assumptions** (A1) the noise
:math:`v_r(k)` is Gaussian, independent over samples and trials with variance
:math:`\sigma_o^2` per output channel (channels may be correlated) and independent of the
inputs, and (A2) :math:`h_i = 0` for :math:`i \ge M` over the trial (the FIR length M is an
assumption, not estimated; M = N needs none but estimates the late parameters from few
samples), the following hold, with :math:`\nu` the degrees of freedom of
:math:`\hat\sigma_o^2` and :math:`C = (\Phi^\top\Phi)^{-1}`:

* per parameter: :math:`|\theta_{o,j} - \hat\theta_{o,j}| \le t_{\nu, 1-\alpha/2}\,
  \hat\sigma_o\sqrt{C_{jj}}` with probability :math:`1 - \alpha` each (marginal intervals);
* all parameters at once (a box, Bonferroni over the :math:`p\,n_y` parameters):
  :math:`|\theta_{o,j} - \hat\theta_{o,j}| \le t_{\nu, 1-\alpha/(2pn_y)}\,\hat\sigma_o
  \sqrt{C_{jj}}` for every o, j with probability :math:`\ge 1 - \alpha`;
* jointly per channel (Scheffé's ellipsoid): :math:`(\theta_o - \hat\theta_o)^\top C^{-1}
  (\theta_o - \hat\theta_o) \le \rho_o^2 = p\,\hat\sigma_o^2 F_{p,\nu,1-\alpha/n_y}`, for all
  channels at once with probability :math:`\ge 1 - \alpha` (Bonferroni over the channels);
* on that event, the lifted error :math:`\Delta G = G - \hat G` (block lower-triangular
  Toeplitz of :math:`\Delta h_i`, any trial length) satisfies

  .. math::

      \|\Delta G\|_2 \le \sup_\theta\|\Delta H(\theta)\|_2 \le \sup_\theta\|\Delta H(\theta)\|_F
      \le \delta = \Big(\kappa\sum_o\rho_o^2\Big)^{1/2},\qquad
      \kappa = \min\Big(\sum_c\sum_{j,k\in I_c}|C_{jk}|,\ M n_u\lambda_{\max}(C)\Big),

  :math:`\Delta H(\theta) = \sum_i\Delta h_i e^{-\mathrm{i}i\theta}`, :math:`I_c` the
  parameters of input c: row o of :math:`\Delta H(\theta)` is :math:`W(\theta)^{\mathsf H}
  \Delta\theta_o` with unit-modulus entries in W, and :math:`\max_{\Delta^\top C^{-1}\Delta\le
  \rho^2}\|W^{\mathsf H}\Delta\|^2 = \rho^2\lambda_{\max}(W^{\mathsf H}CW) \le
  \rho^2\operatorname{tr}(W^{\mathsf H}CW) \le \rho^2\kappa`.

Where the records allow it, A1 and A2 are **tested** on the same records before anything is
claimed from the bounds (:mod:`~ilc_analysis.lifting._assumption_tests`: the FIR length against
a FIR of length N and against repeated trials, whiteness and normality of the repeat
differences, at one stated level): :attr:`IdentifiedModel.refuted` lists the tests that refute
an assumption, and a certificate resting on it is ``unknown``
(:func:`~ilc_analysis.analysis.identified_certificate`). The same record given twice is
refused (:func:`~ilc_analysis.model._repeats.refuse_repeated`).

The identified plant is a :class:`IdentifiedModel`; :meth:`IdentifiedModel.dplant` is a
state-space realisation of the FIR model (a shift register) that :class:`~ilc_analysis.problem.
ILCProblem` accepts as its plant (with ``shift=model.shift``), and :meth:`IdentifiedModel.
operator` its lifted G as a :class:`~._toeplitz.ToeplitzOperator`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .._validation import as_finite_array, check_allocation, positive, positive_int, real
from ..exceptions import ParameterError, ShapeError
from ..model import DiscretePlant
from ..model._repeats import refuse_repeated
from ._assumption_tests import DEFAULT_TEST_LEVEL, AssumptionTest, assumption_tests
from ._toeplitz import ToeplitzOperator
from ._validation import check_shift

__all__ = ["IdentifiedModel", "identify_markov", "NOISE_ESTIMATES", "AssumptionTest"]

#: How the noise variance is estimated (:func:`identify_markov`).
NOISE_ESTIMATES = ("residuals", "repeats")


@dataclass(frozen=True, eq=False)
class IdentifiedModel:
    r"""Markov parameters identified from recorded trials, with their confidence bounds.

    Built by :func:`identify_markov` (module docstring: the model, the estimates and the
    assumptions A1, A2 under which the bounds hold).

    Attributes
    ----------
    markov : ndarray, shape (M, n_y, n_u)
        :math:`\hat h_0, \dots, \hat h_{M-1}` (:math:`\hat h_i` maps u(k - i) to y(s + k)).
    shift : int
        The output-window shift s of the records.
    ts : float
        Sample time [s].
    confidence : float
        :math:`1 - \alpha`, the level of :attr:`intervals`, :attr:`ellipsoid_radius` (jointly
        over the channels) and :attr:`delta`.
    noise_std : ndarray, shape (n_y,)
        :math:`\hat\sigma_o`.
    dof : int
        :math:`\nu`, the degrees of freedom of the noise estimate.
    noise_estimate : str
        ``'residuals'`` or ``'repeats'``.
    covariance : ndarray, shape (M n_u, M n_u)
        :math:`C = (\Phi^\top\Phi)^{-1}`; the parameter covariance of channel o is
        :math:`\sigma_o^2 C`, parameter index :math:`j = i\,n_u + c` for :math:`h_i[o, c]`.
    intervals : ndarray, shape (M, n_y, n_u)
        Half-widths :math:`t_{\nu,1-\alpha/2}\hat\sigma_o\sqrt{C_{jj}}` of the marginal
        intervals (each holds with probability :math:`1-\alpha`).
    box : ndarray, shape (M, n_y, n_u)
        Half-widths :math:`t_{\nu,1-\alpha/(2pn_y)}\hat\sigma_o\sqrt{C_{jj}}` of the
        simultaneous box (all parameters inside it with probability :math:`\ge 1-\alpha`).
    ellipsoid_radius : ndarray, shape (n_y,)
        :math:`\rho_o`: :math:`(\theta_o-\hat\theta_o)^\top C^{-1}(\theta_o-\hat\theta_o) \le
        \rho_o^2` for every o, jointly with probability :math:`\ge 1-\alpha`.
    delta : float
        :math:`\delta \ge \|G - \hat G\|_2` on that event, for every trial length.
    rows : int
        n, the regression rows (samples over all trials).
    trials : int
        R, the number of records.
    assumptions : tuple of str
        What the bounds assume (A1, A2 in words, with M).
    tests : tuple of AssumptionTest
        The tests of A1 and A2 the records allowed
        (:mod:`~ilc_analysis.lifting._assumption_tests`), each at its share of
        :attr:`test_level`.
    untested : tuple of str
        A sentence for each assumption no test could reach (e.g. no repeated trials).
    test_level : float
        The level of all tests together: with probability at least 1 - test_level no true
        assumption is called refuted.
    """

    markov: np.ndarray
    shift: int
    ts: float
    confidence: float
    noise_std: np.ndarray
    dof: int
    noise_estimate: str
    covariance: np.ndarray
    intervals: np.ndarray
    box: np.ndarray
    ellipsoid_radius: np.ndarray
    delta: float
    rows: int
    trials: int
    assumptions: tuple[str, ...] = field(default=())
    tests: tuple[AssumptionTest, ...] = field(default=())
    untested: tuple[str, ...] = field(default=())
    test_level: float = DEFAULT_TEST_LEVEL

    @property
    def refuted(self) -> tuple[AssumptionTest, ...]:
        """The tests whose assumption the data refute (empty: none refuted)."""
        return tuple(t for t in self.tests if t.refuted)

    def assumption_status(self) -> str:
        """One clause per assumption: what it is, and whether the data refute it, do not
        refute it (the largest p-value's test named) or cannot test it."""
        parts = []
        for label, words in (("A1", "Gaussian white noise"),
                             ("A2", f"h_i = 0 for i >= M = {self.fir_length}")):
            mine = [t for t in self.tests if t.assumption == label]
            bad = [t for t in mine if t.refuted]
            if bad:
                state = "REFUTED by " + ", ".join(t.name for t in bad)
            elif mine:
                worst = min(mine, key=lambda t: t.p_value / t.level)
                state = (f"not refuted ({len(mine)} test(s) at level {self.test_level:g}, "
                         f"smallest p = {worst.p_value:.2g})")
            else:
                state = "not tested"
            parts.append(f"{label} ({words}): {state}")
        parts.append("trials from rest or the stated free response: not tested")
        return "; ".join(parts)

    @property
    def fir_length(self) -> int:
        """M, the number of identified Markov parameters."""
        return int(self.markov.shape[0])

    @property
    def n_u(self) -> int:
        return int(self.markov.shape[2])

    @property
    def n_y(self) -> int:
        return int(self.markov.shape[1])

    def blocks(self, N: int) -> np.ndarray:
        r"""The first block column of :math:`\hat G` on N samples, ``(N, n_y, n_u)``:
        :math:`\hat h_0, \dots, \hat h_{N-1}` (zero past M, assumption A2).

        Parameters
        ----------
        N : int
            Trial length in samples, >= 1.
        """
        N = positive_int(N, "N (trial length in samples)")
        out = np.zeros((N, self.n_y, self.n_u))
        m = min(N, self.fir_length)
        out[:m] = self.markov[:m]
        return out

    def operator(self, N: int) -> ToeplitzOperator:
        r"""The identified lifted plant :math:`\hat G` on N samples (block Toeplitz).

        Parameters
        ----------
        N : int
            Trial length in samples, >= 1.
        """
        return ToeplitzOperator(self.blocks(N), description="identified G (FIR)")

    def contains(self, markov) -> bool:
        r"""Whether Markov parameters ``(K, n_y, n_u)`` lie in the joint confidence set:
        every channel's ellipsoid holds for the first M and all later ones are zero (A2).

        Parameters
        ----------
        markov : array_like, shape (K, n_y, n_u)
            Markov parameters :math:`h_0, \dots, h_{K-1}` (e.g. the true plant's).
        """
        h = as_finite_array(markov, "markov", ndim=3)
        if h.shape[1:] != self.markov.shape[1:]:
            raise ShapeError(f"markov must have shape (K, {self.n_y}, {self.n_u}); found "
                             f"shape {h.shape}")
        M = self.fir_length
        if h.shape[0] > M and np.any(h[M:] != 0.0):
            return False
        full = np.zeros_like(self.markov)
        full[:min(M, h.shape[0])] = h[:M]
        d = _theta(full - self.markov)                    # (p, n_y)
        P = np.linalg.inv(self.covariance)
        q = np.einsum("jo,jk,ko->o", d, P, d)
        return bool(np.all(q <= self.ellipsoid_radius ** 2))

    def realization(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r"""Discrete state-space matrices (A, B, C, D) of the FIR model: the shift register
        :math:`x(k) = (u(k-1), \dots, u(k-L))`, L = max(M - 1 + s, 1), whose Markov parameter
        of lag s + i is :math:`\hat h_i` (so its lifting with shift s is :math:`\hat G`)."""
        M, n_y, n_u = self.markov.shape
        s = self.shift
        L = max(M - 1 + s, 1)
        g = np.zeros((L + 1, n_y, n_u))                   # g_j: u(k - j) -> y(k)
        g[s:s + M] = self.markov
        A = np.zeros((L * n_u, L * n_u))
        A[n_u:, :-n_u] = np.eye((L - 1) * n_u)
        B = np.zeros((L * n_u, n_u))
        B[:n_u] = np.eye(n_u)
        C = np.concatenate(list(g[1:]), axis=1)
        return A, B, C, g[0].copy()

    def dplant(self, name: str = "identified FIR") -> DiscretePlant:
        r"""The sampled plant of :meth:`realization` for :class:`ILCProblem` (with
        ``shift=self.shift``): its lifted G on N samples is :meth:`operator` (N).

        Parameters
        ----------
        name : str
            The plant's name.
        """
        import control  # lazy: python-control is not imported at package import

        A, B, C, D = self.realization()
        return DiscretePlant.from_statespace(control.ss(A, B, C, D, self.ts), name=name)

    def as_dict(self) -> dict:
        """Plain values (JSON): the estimates, bounds and assumptions (not the covariance)."""
        return {"fir_length": self.fir_length, "shift": self.shift, "ts": self.ts,
                "n_u": self.n_u, "n_y": self.n_y, "trials": self.trials, "rows": self.rows,
                "confidence": self.confidence, "noise_estimate": self.noise_estimate,
                "noise_std": self.noise_std.tolist(), "dof": self.dof,
                "delta": self.delta, "ellipsoid_radius": self.ellipsoid_radius.tolist(),
                "markov": self.markov.tolist(), "intervals": self.intervals.tolist(),
                "box": self.box.tolist(),
                "assumptions": list(self.assumptions),
                "test_level": self.test_level,
                "assumption_tests": [t.as_dict() for t in self.tests],
                "untested": list(self.untested)}

    def summary(self) -> str:
        """One paragraph: what was identified, at which confidence, and δ."""
        return (f"FIR of length M = {self.fir_length} ({self.n_y} x {self.n_u} blocks, shift "
                f"{self.shift}) from {self.trials} trial(s), {self.rows} rows; noise std "
                f"{np.array2string(self.noise_std, precision=3)} ({self.noise_estimate}, "
                f"{self.dof} dof); with confidence {self.confidence:g}: "
                f"||G - G_hat||_2 <= {self.delta:.4g}, assuming {self.assumption_status()}")


def _theta(h: np.ndarray) -> np.ndarray:
    """(M, n_y, n_u) -> (M n_u, n_y): column o holds h_i[o, c] at j = i n_u + c."""
    M, n_y, n_u = h.shape
    return h.transpose(0, 2, 1).reshape(M * n_u, n_y)


def _records(records, name: str, ndim_cols: int | None, what: str) -> list[np.ndarray]:
    if isinstance(records, np.ndarray) and records.ndim in (1, 2):
        records = [records]
    try:
        items = list(records)
    except TypeError:
        raise ParameterError(f"{name} must be a list of {what} arrays (one per trial); got "
                             f"{type(records).__name__}") from None
    if not items:
        raise ParameterError(f"{name} must hold at least one trial; got an empty list")
    out = []
    for r, item in enumerate(items):
        arr = as_finite_array(item, f"{name}[{r}]")
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim != 2 or arr.shape[0] == 0:
            raise ShapeError(f"{name}[{r}] must be a non-empty (N, {what}) array; found "
                             f"shape {arr.shape}")
        if ndim_cols is not None and arr.shape[1] != ndim_cols:
            raise ShapeError(f"{name}[{r}] must have {ndim_cols} column(s) like {name}[0]; "
                             f"found shape {arr.shape}")
        ndim_cols = arr.shape[1]
        out.append(arr)
    return out


def _regressor(u: np.ndarray, M: int) -> np.ndarray:
    """Rows [u(k), u(k-1), ..., u(k-M+1)] (zeros before the trial), ``(N, M n_u)``."""
    N, n_u = u.shape
    padded = np.concatenate([np.zeros((M - 1, n_u)), u])
    cols = [padded[M - 1 - i:M - 1 - i + N] for i in range(M)]
    return np.concatenate(cols, axis=1)


def identify_markov(inputs, outputs, *, fir_length: int, ts: float, shift: int = 1,
                    free_response=None, confidence: float = 0.95,
                    noise: str = "residuals", trial_names=None,
                    test_level: float = DEFAULT_TEST_LEVEL) -> IdentifiedModel:
    r"""Identify the Markov parameters of an LTI plant from recorded trials (module docstring).

    Parameters
    ----------
    inputs : sequence of array_like, each shape (N, n_u) (or (N,) for one input)
        The applied inputs u(0..N-1), one array per trial; all trials the same N.
    outputs : sequence of array_like, each shape (N, n_y) (or (N,))
        The measured output window y(s..N-1+s) of each trial, in the same order.
    fir_length : int
        M, the number of Markov parameters :math:`h_0..h_{M-1}`, :math:`1 \le M \le N`;
        assumption A2 is that later ones vanish.
    ts : float
        Sample time [s], > 0.
    shift : int
        s >= 0, the output window's shift (``ILCProblem.shift``).
    free_response : array_like or sequence of array_like, optional
        The response d to the initial state (and known disturbances) on the window: one
        ``(N, n_y)`` for every trial or one per trial; subtracted from the outputs. Default:
        zero (every trial starts from rest).
    confidence : float
        :math:`1 - \alpha` in (0, 1).
    noise : {'residuals', 'repeats'}
        Estimate :math:`\sigma_o^2` from the least-squares residuals (:math:`\nu = n - p`),
        or from trials repeated with identical inputs (pure error, :math:`\nu = \sum_g N
        (|g| - 1)`; needs at least two trials with the same input).
    trial_names : sequence of str, optional
        How the trials are named in messages (e.g. their files); default ``trial 0``, ...
    test_level : float
        The level in (0, 1) of the tests of the assumptions on the same records
        (:mod:`~ilc_analysis.lifting._assumption_tests`: the FIR length against a longer FIR
        and against the repeats, whiteness and normality of the repeat differences; default
        :data:`~ilc_analysis.lifting._assumption_tests.DEFAULT_TEST_LEVEL`). A refuted
        assumption is in :attr:`IdentifiedModel.refuted`, and makes the certificates that rest
        on it ``unknown``.

    Returns
    -------
    IdentifiedModel

    Raises
    ------
    ParameterError
        Bad M, confidence, noise or shift; a rank-deficient regression (the inputs do not
        excite M lags); no degrees of freedom left for the noise; no repeated input with
        ``noise='repeats'``; the same record given twice (identical input and output,
        :func:`~ilc_analysis.model._repeats.refuse_repeated`: it would be counted as two
        independent trials and shrink the bounds).
    ShapeError
        Records of different lengths or channel counts, or inputs and outputs not paired.
    """
    from scipy import stats  # lazy: a slow import, needed only here

    us = _records(inputs, "inputs", None, "n_u")
    ys = _records(outputs, "outputs", None, "n_y")
    if len(us) != len(ys):
        raise ShapeError(f"inputs and outputs must hold the same number of trials; got "
                         f"{len(us)} and {len(ys)}")
    N, n_u = us[0].shape
    n_y = ys[0].shape[1]
    for r, (u, y) in enumerate(zip(us, ys, strict=True)):
        if u.shape[0] != N or y.shape[0] != N:
            raise ShapeError(f"trial {r}: inputs[{r}] and outputs[{r}] must both have N = {N} "
                             f"rows (like trial 0); found {u.shape[0]} and {y.shape[0]}")
    names = [f"trial {r}" for r in range(len(us))] if trial_names is None else \
        [str(n) for n in trial_names]
    if len(names) != len(us):
        raise ShapeError(f"trial_names must name each of the {len(us)} trials; got "
                         f"{len(names)} names")
    refuse_repeated([np.concatenate([u, y], axis=1) for u, y in zip(us, ys, strict=True)],
                    names, "trial")
    M = positive_int(fir_length, "fir_length (M, the number of Markov parameters)", maximum=N)
    shift = check_shift(shift)
    ts = positive(ts, "ts (sample time)")
    confidence = real(confidence, "confidence")
    if not 0.0 < confidence < 1.0:
        raise ParameterError(f"confidence must lie in (0, 1) (e.g. 0.95); got {confidence!r}")
    if noise not in NOISE_ESTIMATES:
        raise ParameterError(f"noise must be one of {NOISE_ESTIMATES}; got {noise!r}")
    test_level = real(test_level, "test_level")
    if not 0.0 < test_level < 1.0:
        raise ParameterError(f"test_level must lie in (0, 1) (e.g. 0.01); got {test_level!r}")
    if free_response is not None:
        ds = _records(free_response, "free_response", n_y, "n_y")
        if len(ds) == 1:
            ds = ds * len(ys)
        if len(ds) != len(ys) or any(d.shape[0] != N for d in ds):
            raise ShapeError(f"free_response must be one (N, n_y) = ({N}, {n_y}) array or one "
                             f"per trial ({len(ys)})")
        ys = [y - d for y, d in zip(ys, ds, strict=True)]

    # the regression matrix and its QR factors, before they are built (M = N = 100 000
    # asked for 80 GB)
    rows, params = len(us) * N, M * n_u
    check_allocation(2 * rows * params + params * params,
                     f"fir_length M = {M} on {len(us)} trial(s) of N = {N} samples: the "
                     f"regression ({rows} x {params}) and its QR factors")
    Phi = np.concatenate([_regressor(u, M) for u in us])
    Y = np.concatenate(ys)
    n, p = Phi.shape
    if n < p:
        raise ParameterError(f"the regression has {n} rows for {p} parameters (fir_length M = "
                             f"{M} x {n_u} inputs): record more trials or use a smaller "
                             "fir_length")
    Q, R = np.linalg.qr(Phi)
    diag = np.abs(np.diag(R))
    if diag.min(initial=np.inf) <= 1e3 * np.finfo(float).eps * max(n, p) * diag.max(initial=0):
        raise ParameterError(f"the regression of {p} parameters (M = {M} lags x {n_u} inputs) "
                             "is rank deficient: the recorded inputs do not excite M lags; "
                             "use richer inputs, more trials or a smaller fir_length")
    Theta = scipy.linalg.solve_triangular(R, Q.T @ Y)
    Rinv = scipy.linalg.solve_triangular(R, np.eye(p))
    Cov = Rinv @ Rinv.T
    sse = np.sum((Y - Phi @ Theta) ** 2, axis=0)                       # (n_y,)
    groups: list[list[int]] = []                   # trials by identical input
    for r, u in enumerate(us):
        for g in groups:
            if np.array_equal(us[g[0]], u):
                g.append(r)
                break
        else:
            groups.append([r])
    if noise == "residuals":
        dof = n - p
        if dof < 1:
            raise ParameterError(f"no degrees of freedom left for the noise: {n} rows for {p} "
                                 "parameters; record more trials or use a smaller fir_length")
        sigma2 = sse / dof
    else:
        dof = sum(N * (len(g) - 1) for g in groups)
        if dof == 0:
            raise ParameterError("noise='repeats' needs at least two trials with identical "
                                 "inputs; none of the inputs repeats")
        ss = np.zeros(n_y)
        for g in groups:
            Yg = np.stack([ys[r] for r in g])
            ss += np.sum((Yg - Yg.mean(axis=0)) ** 2, axis=(0, 1))
        sigma2 = ss / dof
    sigma = np.sqrt(sigma2)
    alpha = 1.0 - confidence
    t = float(stats.t.ppf(1.0 - alpha / 2.0, dof))
    t_box = float(stats.t.ppf(1.0 - alpha / (2.0 * p * n_y), dof))
    F = float(stats.f.ppf(1.0 - alpha / n_y, p, dof))
    rho = np.sqrt(p * sigma2 * F)
    half = t * np.sqrt(np.diag(Cov))[:, None] * sigma[None, :]          # (p, n_y)
    markov = Theta.reshape(M, n_u, n_y).transpose(0, 2, 1)
    intervals = half.reshape(M, n_u, n_y).transpose(0, 2, 1)
    box = intervals * (t_box / t)
    absC = np.abs(Cov)
    kappa_abs = sum(float(absC[c::n_u, c::n_u].sum()) for c in range(n_u))
    kappa_eig = M * n_u * float(np.linalg.eigvalsh(Cov)[-1])
    delta = float(np.sqrt(min(kappa_abs, kappa_eig) * np.sum(rho ** 2)))
    assumptions = (
        "A1: Gaussian measurement noise, independent over samples and trials, of one variance "
        "per output channel, independent of the inputs",
        f"A2: h_i = 0 for i >= M = {M} (the FIR length is assumed; tested where the records "
        "allow)",
        "every trial starts from rest or from the stated free response",
    )
    tests, untested = assumption_tests(us, ys, sse, M, groups, test_level, _regressor)
    return IdentifiedModel(
        markov=_readonly(markov), shift=shift, ts=ts, confidence=confidence,
        noise_std=_readonly(sigma), dof=int(dof), noise_estimate=noise,
        covariance=_readonly(Cov), intervals=_readonly(intervals), box=_readonly(box),
        ellipsoid_radius=_readonly(rho), delta=delta, rows=int(n), trials=len(us),
        assumptions=assumptions, tests=tests, untested=untested, test_level=test_level)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a
