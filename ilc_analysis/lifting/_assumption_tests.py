r"""Tests of an identification's assumptions on the data it was identified from.

The confidence bounds of :func:`~ilc_analysis.lifting.identify_markov` hold under (A1) Gaussian
noise, independent over samples and trials, and (A2) an impulse response that vanishes after
the FIR length M. Where the records allow it, both are **tested** before anything is claimed
from the bounds (:func:`assumption_tests`); a refuted assumption makes every certificate that
rests on them ``unknown`` (:func:`~ilc_analysis.analysis.identified_certificate`).

A2, the FIR length, against a longer FIR (F-test of nested regressions)
    The FIR model of length M is the longer one of length M' > M (default M' = N, every lag a
    trial of N samples can show) with :math:`h_M = \dots = h_{M'-1} = 0`. Under A1 and A2,
    with :math:`\mathrm{SSE}_m` the residual sum of squares of the fit of length m (one output
    channel),

    .. math::

        F = \frac{(\mathrm{SSE}_M - \mathrm{SSE}_{M'})/((M'-M)n_u)}
                 {\mathrm{SSE}_{M'}/(n - M'n_u)} \sim F_{(M'-M)n_u,\ n - M'n_u}.

    M' is the largest of N, what leaves a quarter of the n rows for the noise, and what keeps
    the regressor below :data:`MAX_TEST_ENTRIES` entries; when M' <= M the test is not
    possible (said so). A refutation suggests the smallest m >= M the same test (against M')
    does not refute — computed from one QR factorisation: :math:`\mathrm{SSE}_m =
    \mathrm{SSE}_{M'} + \sum_{j \ge m n_u} z_j^2`, z = Q^T y.

A2 (and linearity, time invariance), lack of fit against the repeats (needs repeated inputs)
    Trials repeated with the same input give a pure-error sum of squares
    :math:`\mathrm{SS}_{PE}` with :math:`\nu_{PE} = \sum_g N(|g| - 1)` degrees of freedom that
    does not depend on any model; the classical lack-of-fit test

    .. math::

        F = \frac{(\mathrm{SSE}_M - \mathrm{SS}_{PE})/(n - M n_u - \nu_{PE})}
                 {\mathrm{SS}_{PE}/\nu_{PE}} \sim F_{n - Mn_u - \nu_{PE},\ \nu_{PE}}

    compares the residual noise estimate with the repeats' (docs/identification.md names that
    comparison as the check of M).

A1, whiteness and normality of the repeat differences (needs repeated inputs)
    Within a group of m trials with the same input, the Helmert contrasts
    :math:`c_j = (y_1 + \dots + y_j - j\,y_{j+1})/\sqrt{j(j+1)}`, j = 1..m-1, are, under A1,
    independent white Gaussian sequences of the noise variance, whatever the plant. Whiteness:
    the Ljung-Box statistic :math:`Q = n(n+2)\sum_{l=1}^{h}\hat\rho_l^2/(n-l)` of each
    contrast, summed over the contrasts, against :math:`\chi^2_{hC}` (h = min(20, N/10) lags);
    normality: D'Agostino and Pearson's :math:`K^2` of all contrast values
    (``scipy.stats.normaltest``; at least 20 values). Both are asymptotic tests. Without
    repeated inputs A1 is not tested (the regression residuals are neither independent nor of
    one variance).

The tests share one stated level (default :data:`DEFAULT_TEST_LEVEL`): each of the K tests
(per output channel) runs at level/K (Bonferroni), so with probability at least 1 - level no
true assumption is called refuted.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

__all__ = ["AssumptionTest", "assumption_tests", "DEFAULT_TEST_LEVEL", "MAX_TEST_ENTRIES"]

#: the level of the assumption tests together (module docstring)
DEFAULT_TEST_LEVEL = 0.01
#: largest regressor (rows x parameters) the longer-FIR test builds (8 bytes each)
MAX_TEST_ENTRIES = 10_000_000
#: Ljung-Box lags at most
_LJUNG_BOX_LAGS = 20
#: fewest values the normality test is run on (scipy's kurtosis test needs 20)
_NORMALITY_MIN = 20


@dataclass(frozen=True)
class AssumptionTest:
    """One test of an identification assumption on the data (module docstring)."""

    assumption: str
    """``'A1'`` (noise) or ``'A2'`` (FIR length)"""
    name: str
    """the test, in words"""
    channel: int
    """the output channel it was run on"""
    statistic: float
    """the test statistic"""
    dof: tuple[int, ...]
    """its degrees of freedom"""
    p_value: float
    """the probability, under the assumption, of a statistic at least this large"""
    level: float
    """the level this test is judged at (the stated level over the number of tests)"""
    detail: str
    """what the data show, in words and numbers"""
    remedy: str = ""
    """what to do when the assumption is refuted"""

    @property
    def refuted(self) -> bool:
        """The data refute the assumption at :attr:`level` (p-value below it)."""
        return bool(self.p_value < self.level)

    def text(self) -> str:
        """One line: the assumption, the test, the outcome and the numbers."""
        verdict = "REFUTED" if self.refuted else "not refuted"
        p = f"p = {self.p_value:.3g}" if self.p_value >= 1e-300 else "p < 1e-300"
        return (f"{self.assumption} {verdict} by {self.name} (output {self.channel}): "
                f"{self.detail}; statistic {self.statistic:.4g} on {self.dof} dof, {p}, "
                f"level {self.level:.3g}" + (f"; {self.remedy}" if self.refuted and self.remedy
                                             else ""))

    def as_dict(self) -> dict:
        return {"assumption": self.assumption, "test": self.name, "channel": self.channel,
                "statistic": float(self.statistic), "dof": list(self.dof),
                "p_value": float(self.p_value), "level": float(self.level),
                "refuted": self.refuted, "detail": self.detail, "remedy": self.remedy}


def _helmert_contrasts(ys: Sequence[np.ndarray], groups: Sequence[Sequence[int]]) -> np.ndarray:
    """``(C, N, n_y)``: the Helmert contrasts of every repeat group (module docstring)."""
    out = []
    for g in groups:
        Yg = np.stack([ys[r] for r in g])                 # (m, N, n_y)
        for j in range(1, len(g)):
            out.append((Yg[:j].sum(axis=0) - j * Yg[j]) / np.sqrt(j * (j + 1)))
    return np.stack(out) if out else np.zeros((0,) + ys[0].shape)


def _sf(dist, x: float, *args) -> float:
    return float(dist.sf(x, *args)) if np.isfinite(x) else 0.0


def _ratio(a: float, b: float) -> str:
    return "inf" if b == 0.0 else f"{a / b:.3g}"


def _longer_fir(Phi_long: np.ndarray, Y: np.ndarray, M: int, n_u: int,
                level: float) -> list[AssumptionTest]:
    """The nested F-test of FIR length M against M' (the regressor's lags), per channel."""
    from scipy import stats

    n, p_long = Phi_long.shape
    n_y = Y.shape[1]
    # R of [Phi' Y] = [[R11, Z], [0, R22]]: Z = Q^T Y, and R22^T R22 the residuals' Gram matrix
    R = cast(np.ndarray, np.linalg.qr(np.concatenate([Phi_long, Y], axis=1), mode="r"))
    diag = np.abs(np.diag(R)[:p_long])
    weak = np.flatnonzero(diag <= 1e3 * np.finfo(float).eps * max(n, p_long) * diag.max())
    if weak.size:                       # lags the inputs do not excite: test up to the first
        p_cut = int(weak[0]) // n_u * n_u
        if p_cut <= M * n_u:
            return []
        R = cast(np.ndarray,
                 np.linalg.qr(np.concatenate([Phi_long[:, :p_cut], Y], axis=1), mode="r"))
        p_long = p_cut
    M_long, p = p_long // n_u, M * n_u
    Z = R[:p_long, p_long:p_long + n_y]                    # (p', n_y)
    sse_long = np.sum(R[p_long:p_long + n_y, p_long:p_long + n_y] ** 2, axis=0)   # (n_y,)
    dof_long = n - p_long
    tail = np.cumsum((Z ** 2)[::-1], axis=0)[::-1]         # tail[j] = sum_{i >= j} z_i^2
    tests = []
    for o in range(Y.shape[1]):
        s2 = sse_long[o] / dof_long
        lags = np.arange(M, M_long)                        # candidate lengths m
        extra = tail[lags * n_u, o]                        # SSE_m - SSE_M'
        df1 = (M_long - lags) * n_u
        with np.errstate(divide="ignore", invalid="ignore"):
            F_all = np.where(s2 > 0, extra / df1 / s2, np.where(extra > 0, np.inf, 0.0))
        p_all = stats.f.sf(F_all, df1, dof_long)
        passing = lags[p_all >= level]
        suggest = int(passing[0]) if passing.size else M_long
        F, pv = float(F_all[0]), float(p_all[0])
        resid_std = np.sqrt((sse_long[o] + extra[0]) / (n - p))
        remedy = (f"the FIR length M = {M} is too short: try fir_length >= {suggest} (the "
                  f"shortest this test does not refute)" if suggest < M_long else
                  f"the FIR length M = {M} is too short, and so is every length below "
                  f"{M_long}: try fir_length = {M_long}")
        tests.append(AssumptionTest(
            "A2", f"an F-test against a FIR of length {M_long}", o, F,
            (int(df1[0]), int(dof_long)), pv, level,
            f"the residual noise std is {resid_std:.4g} with {M} lags, {np.sqrt(s2):.4g} with "
            f"{M_long}", remedy))
    return tests


def _lack_of_fit(sse: np.ndarray, ss_pe: np.ndarray, nu_pe: int, n: int, p: int,
                 level: float, remedy: str) -> list[AssumptionTest]:
    """The lack-of-fit F-test of the FIR model against the pure error, per channel."""
    from scipy import stats

    nu_lof = n - p - nu_pe
    tests = []
    for o in range(sse.size):
        resid = np.sqrt(sse[o] / (n - p))
        pure = np.sqrt(ss_pe[o] / nu_pe)
        lof = max(float(sse[o] - ss_pe[o]), 0.0)
        F = (lof / nu_lof) / (ss_pe[o] / nu_pe) if ss_pe[o] > 0 else \
            (np.inf if lof > 0 else 0.0)
        tests.append(AssumptionTest(
            "A2", "the lack-of-fit F-test against the repeated trials", o, float(F),
            (int(nu_lof), int(nu_pe)), _sf(stats.f, F, nu_lof, nu_pe), level,
            f"the residual noise std {resid:.4g} is {_ratio(resid, pure)} x the repeats' "
            f"{pure:.4g}", remedy))
    return tests


def _whiteness(C: np.ndarray, level: float) -> list[AssumptionTest]:
    """Ljung-Box on each contrast, summed over the contrasts, per channel."""
    from scipy import stats

    n_c, N, n_y = C.shape
    h = max(1, min(_LJUNG_BOX_LAGS, N // 10))
    tests = []
    for o in range(n_y):
        Q = 0.0
        for c in C[:, :, o]:
            c0 = float(c @ c)
            if c0 == 0.0:
                continue
            rho = np.array([float(c[:-lag] @ c[lag:]) for lag in range(1, h + 1)]) / c0
            Q += N * (N + 2) * float(np.sum(rho ** 2 / (N - np.arange(1, h + 1))))
        dof = h * n_c
        tests.append(AssumptionTest(
            "A1", f"the Ljung-Box test ({h} lags) of the repeat differences", o, Q, (dof,),
            _sf(stats.chi2, Q, dof), level,
            f"{n_c} difference sequence(s) of {N} samples",
            "the noise is correlated over samples: the bounds, which assume white noise, "
            "are too narrow; record trials with more time between samples, or model the "
            "noise"))
    return tests


def _normality(C: np.ndarray, level: float) -> list[AssumptionTest]:
    """D'Agostino-Pearson K^2 of the pooled contrasts, per channel."""
    from scipy import stats

    tests = []
    for o in range(C.shape[2]):
        values = C[:, :, o].ravel()
        K2, pv = stats.normaltest(values)
        tests.append(AssumptionTest(
            "A1", "D'Agostino and Pearson's normality test of the repeat differences", o,
            float(K2), (2,), float(pv), level, f"{values.size} values",
            "the noise is not Gaussian (outliers, quantisation or a non-Gaussian "
            "disturbance): the t and F bounds do not hold as stated"))
    return tests


def assumption_tests(us: Sequence[np.ndarray], ys: Sequence[np.ndarray], sse: np.ndarray,
                     M: int, groups: Sequence[Sequence[int]], level: float,
                     regressor: Callable[[np.ndarray, int], np.ndarray]
                     ) -> tuple[tuple[AssumptionTest, ...], tuple[str, ...]]:
    """Every test of A1 and A2 the records allow (module docstring).

    Parameters
    ----------
    us, ys : sequence of ndarray
        The inputs ``(N, n_u)`` and outputs ``(N, n_y)`` of the trials (free response removed).
    sse : ndarray (n_y,)
        The residual sum of squares of the fit of length M.
    M : int
        The FIR length.
    groups : sequence of sequence of int
        The trials grouped by identical input.
    level : float
        The level of all tests together, in (0, 1).
    regressor : callable
        ``regressor(u, m)``: the ``(N, m n_u)`` regressor rows of one trial for length m.

    Returns
    -------
    (tests, untested) : (tuple of AssumptionTest, tuple of str)
        The tests run, and a sentence for each assumption no test could reach.
    """
    N, n_u = us[0].shape
    n_y = ys[0].shape[1]
    n = N * len(us)
    p = M * n_u
    M_long = min(N, (n - max(1, -(-n // 4))) // n_u, MAX_TEST_ENTRIES // (n * n_u))
    repeats = [g for g in groups if len(g) > 1]
    nu_pe = sum(N * (len(g) - 1) for g in repeats)
    C = _helmert_contrasts(ys, repeats)
    plan = {"longer": M_long > M, "lof": nu_pe > 0 and n - p - nu_pe >= 1,
            "white": nu_pe > 0 and N >= 2, "normal": nu_pe > 0 and C[:, :, 0].size
            >= _NORMALITY_MIN}
    count = sum(plan.values()) * n_y
    untested = []
    if not plan["longer"] and not plan["lof"]:
        untested.append(f"A2 (FIR length M = {M}) is not tested: the records leave no room "
                        f"for a longer FIR" + ("" if M < N else " (M = N: every lag of the "
                                                            "trial is identified)")
                        + " and repeat no input")
    if not plan["white"]:
        untested.append("A1 (white Gaussian noise) is not tested: no two trials have the same "
                        "input (the test needs repeated trials)")
    elif not plan["normal"]:
        untested.append(f"A1: normality is not tested (fewer than {_NORMALITY_MIN} repeat "
                        "differences)")
    if count == 0:
        return (), tuple(untested)
    each = level / count
    Y = np.concatenate(ys)
    tests: list[AssumptionTest] = []
    if plan["longer"]:
        Phi_long = np.concatenate([regressor(u, M_long) for u in us])
        tests += _longer_fir(Phi_long, Y, M, n_u, each)
        if not tests and not plan["lof"]:
            untested.append(f"A2 (FIR length M = {M}) is not tested: the inputs do not excite "
                            f"lags beyond M, and no input repeats")
    if plan["lof"]:
        ss_pe = np.sum(C ** 2, axis=(0, 1))
        suggested = next((t.remedy for t in tests if t.assumption == "A2" and t.refuted),
                         f"the FIR model of length M = {M} does not explain the repeated "
                         f"responses: a longer fir_length (up to N = {N}), or the plant is not "
                         "linear and time-invariant")
        tests += _lack_of_fit(sse, ss_pe, nu_pe, n, p, each, suggested)
    if plan["white"]:
        tests += _whiteness(C, each)
    if plan["normal"]:
        tests += _normality(C, each)
    return tuple(tests), tuple(untested)
