r"""Measured frequency-response data (FRF) as a plant description, with its uncertainty.

A :class:`FrequencyResponseData` holds what a user's measurement system produces when it has no
parametric model: a frequency grid :math:`f_k` [Hz], the complex response
:math:`\hat G(e^{j\omega_k T_s})` (``(n_f, n_y, n_u)``, SISO as ``(n_f, 1, 1)``) of the *sampled*
plant (input held by the zero-order hold, output sampled, sample time :math:`T_s`), and an
uncertainty radius :math:`r_k \ge 0` per frequency. The set of plants the data describe is

.. math::

    \mathcal G = \{G :\ \|G(e^{j\omega_k T_s}) - \hat G_k\|_2 \le r_k\ \text{for every } k\},

a disc of radius :math:`r_k` about :math:`\hat G_k` for a SISO plant, a spectral-norm ball for
a MIMO one. **Nothing is said between the grid points**: :math:`\mathcal G` constrains the
response on the grid only.

The radius is either given (a column ``radius``) or estimated from :math:`n \ge 2` repeated
measurements :math:`G^{(1)}, \dots, G^{(n)}` (:meth:`FrequencyResponseData.from_measurements`)
as a **normal tolerance region**: at each frequency, with :math:`x_i = \mathrm{vec}(\mathrm{Re}\,
G^{(i)}_k, \mathrm{Im}\,G^{(i)}_k) \in \mathbb R^d` (:math:`d = 2 n_y n_u`), their mean
:math:`\bar x` and sample covariance :math:`S` (divisor n - 1),

.. math::

    \hat G_k = \frac1n\sum_i G^{(i)}_k,\qquad r_k = k(n, d, p, \gamma)\,
    \sqrt{\lambda_{\max}(S_k)},\qquad
    k = \sqrt{\frac{n-1}{\chi^2_{n-1,\,1-\sqrt\gamma}}}
    \Big(\sqrt{\chi^2_{d,\,p}} + \sqrt{\chi^2_{d,\,\sqrt\gamma}/n}\Big).

**What it states**: if the measurements at a frequency are independent draws of a normal
distribution (the machine's variation and the measurement noise together; real and imaginary
parts jointly normal, any covariance), then with confidence :math:`\gamma` the disc
:math:`\|G - \hat G_k\|_2 \le r_k` holds at least the proportion p of the machine's responses
at that frequency (:func:`tolerance_factor` proves it). It is a statement **per frequency**,
not for the whole response at once. Defaults :data:`DEFAULT_COVERAGE` = 0.95 and
:data:`DEFAULT_CONFIDENCE` = 0.95: with five measurements k = 10.5 (in units of the largest
standard deviation), with twenty k = 4.5; a content p of every response at once or a
distribution-free region would need far more measurements than an FRF campaign has (Wilks'
distribution-free p = γ = 0.95 needs n >= 59, and a centre not estimated from the same data).

Files (:func:`read_frf`): CSV with a header line — ``f_hz``, then per channel either
``re_<i>_<j>``, ``im_<i>_<j>`` or ``mag_<i>_<j>``, ``phase_deg_<i>_<j>`` (output i, input j, from
1; a SISO file may write ``re``, ``im`` / ``mag``, ``phase_deg``), optionally ``radius`` and
optionally ``repeat`` (the measurement index, several measurements in one file); or one file per
measurement; or MATLAB ``.mat`` with ``f_hz`` (n_f), ``G`` (n_f[, n_y, n_u]) or ``G_repeats``
(n_rep, n_f[, n_y, n_u]), optionally ``radius`` and ``ts``.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._validation import LARGEST_SAMPLE, positive, positive_int, real, shown
from ..exceptions import ParameterError, ShapeError
from ._repeats import refuse_repeated

__all__ = ["FrequencyResponseData", "read_frf", "write_frf_csv", "tolerance_factor",
           "DEFAULT_COVERAGE", "DEFAULT_CONFIDENCE"]

#: p, the proportion of the machine's responses the tolerance region holds (module docstring)
DEFAULT_COVERAGE = 0.95
#: gamma, the confidence with which it holds them
DEFAULT_CONFIDENCE = 0.95
#: relative tolerance for "a frequency of the grid is a DFT bin k/(N ts)"
_BIN_RTOL = 1e-9


def _as_response(value, name: str) -> np.ndarray:
    """Complex ``(n_f, n_y, n_u)`` from ``(n_f,)`` (SISO) or ``(n_f, n_y, n_u)``."""
    arr = np.asarray(value)
    if not np.issubdtype(arr.dtype, np.number):
        raise ParameterError(f"{name} must be a complex array; found dtype {arr.dtype}")
    arr = arr.astype(complex)
    if arr.ndim == 1:
        arr = arr[:, None, None]
    if arr.ndim != 3:
        raise ShapeError(f"{name} must have shape (n_f,) or (n_f, n_y, n_u); found shape "
                         f"{arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite (a NaN or inf in the response)")
    if arr.size and np.abs(arr).max() > LARGEST_SAMPLE:
        raise ParameterError(f"{name}: |G| reaches {np.abs(arr).max():.3g}, beyond "
                             f"{LARGEST_SAMPLE:.3g} (the square root of the largest float64: "
                             f"|G|^2 would overflow); rescale the data")
    return arr


def _probability(value, name: str) -> float:
    p = real(value, name)
    if not 0.0 < p < 1.0:
        raise ParameterError(f"{name} must lie in (0, 1) (e.g. 0.95); got {value!r}")
    return p


def tolerance_factor(n: int, d: int, coverage: float = DEFAULT_COVERAGE,
                     confidence: float = DEFAULT_CONFIDENCE) -> float:
    r"""k of the normal tolerance ball :math:`\|x - \bar x\| \le k\sqrt{\lambda_{\max}(S)}`.

    For n independent draws :math:`x_i \sim N(\mu, \Sigma)` in :math:`\mathbb R^d` with mean
    :math:`\bar x` and sample covariance S (divisor n - 1), the ball holds at least the
    proportion ``coverage`` = p of :math:`N(\mu, \Sigma)` with probability at least
    ``confidence`` = :math:`\gamma`, for every :math:`\mu` and :math:`\Sigma`:

    .. math::

        k = \sqrt{\frac{n-1}{\chi^2_{n-1,\,1-g}}}\Big(\sqrt{\chi^2_{d,\,p}}
        + \sqrt{\chi^2_{d,\,g}/n}\Big),\qquad g = \sqrt\gamma.

    Proof. Let :math:`\lambda = \lambda_{\max}(\Sigma)` and v its unit eigenvector. (i)
    :math:`(n-1)v^\top Sv/\lambda \sim \chi^2_{n-1}` and :math:`\lambda_{\max}(S) \ge v^\top
    Sv`, so :math:`\lambda \le B = (n-1)\lambda_{\max}(S)/\chi^2_{n-1,1-g}` with probability
    :math:`\ge g`. (ii) :math:`n\|\bar x - \mu\|^2 \le \lambda\, n(\bar x-\mu)^\top
    \Sigma^{-1}(\bar x-\mu) \sim \lambda\chi^2_d`, so :math:`\|\bar x - \mu\| \le
    \sqrt{\lambda\chi^2_{d,g}/n}` with probability g. :math:`\bar x` and S are independent,
    so both hold with probability :math:`g^2 = \gamma`. (iii) On both, the ball about
    :math:`\bar x` of radius :math:`\sqrt B(\sqrt{\chi^2_{d,p}} + \sqrt{\chi^2_{d,g}/n})`
    contains the ball about :math:`\mu` of radius :math:`\sqrt{\lambda\chi^2_{d,p}}`, which
    holds :math:`P(\|x-\mu\|^2 \le \lambda\chi^2_{d,p}) \ge P(\chi^2_d \le \chi^2_{d,p}) = p`
    of the distribution (:math:`\|x-\mu\|^2 \le \lambda (x-\mu)^\top\Sigma^{-1}(x-\mu)`).
    The bound is conservative (the ellipsoid's enclosing ball, two one-sided events), never
    optimistic.

    Parameters
    ----------
    n : int
        Number of measurements, >= 2.
    d : int
        Dimension (2 per complex entry), >= 1.
    coverage, confidence : float
        p and :math:`\gamma` in (0, 1).

    Returns
    -------
    float
    """
    from scipy import stats  # lazy: a slow import, needed only here

    n = positive_int(n, "n (measurements)", minimum=2)
    d = positive_int(d, "d (dimension)")
    p = _probability(coverage, "coverage")
    g = float(np.sqrt(_probability(confidence, "confidence")))
    scale = (n - 1) / float(stats.chi2.ppf(1.0 - g, n - 1))
    return float(np.sqrt(scale) * (np.sqrt(stats.chi2.ppf(p, d))
                                   + np.sqrt(stats.chi2.ppf(g, d) / n)))


@dataclass(frozen=True, eq=False)
class FrequencyResponseData:
    r"""A measured FRF of a sampled plant and its per-frequency uncertainty (module docstring).

    Parameters
    ----------
    frequency_hz : array_like (n_f,)
        Strictly increasing frequencies [Hz] in :math:`[0, 1/(2T_s)]`.
    response : array_like (n_f,) or (n_f, n_y, n_u), complex
        :math:`\hat G(e^{j 2\pi f_k T_s})`.
    ts : float
        Sample time [s] of the sampled plant.
    radius : array_like (n_f,) or float, optional
        :math:`r_k \ge 0`, the bound on :math:`\|G - \hat G\|_2` at each frequency (default 0:
        the nominal data taken as exact).
    uncertainty : str
        How the radius was obtained (kept with the data, written in reports).
    measurements : int
        Number of measurements averaged into ``response``.
    coverage, confidence : float, optional
        For a radius estimated as a tolerance region (:meth:`from_measurements`): the
        proportion p of the machine's responses it holds at each frequency and the confidence
        :math:`\gamma` (None for a given radius).

    Raises
    ------
    ParameterError
        Frequencies not strictly increasing, negative or above the Nyquist frequency; a
        non-finite response; a negative or non-finite radius.
    ShapeError
        Arrays of inconsistent lengths or shapes.
    """

    frequency_hz: np.ndarray = field(repr=False)
    """frequency grid [Hz], ``(n_f,)``"""
    response: np.ndarray = field(repr=False)
    """complex response ``(n_f, n_y, n_u)``"""
    ts: float
    """sample time [s]"""
    radius: np.ndarray = field(default=None, repr=False)  # type: ignore[arg-type]
    """uncertainty radius per frequency ``(n_f,)`` (spectral norm of G - G_hat)"""
    uncertainty: str = "none given (radius 0)"
    """how the radius was obtained"""
    measurements: int = 1
    """measurements averaged"""
    coverage: float | None = None
    """p of the tolerance region (None: the radius was given)"""
    confidence: float | None = None
    """gamma of the tolerance region (None: the radius was given)"""

    def __post_init__(self) -> None:
        ts = positive(self.ts, "ts (sample time)")
        f = np.asarray(self.frequency_hz, dtype=float)
        if f.ndim != 1 or f.size == 0:
            raise ShapeError(f"frequency_hz must be a non-empty 1-D array; found shape {f.shape}")
        if not np.all(np.isfinite(f)) or np.any(f < 0) or np.any(np.diff(f) <= 0):
            raise ParameterError("frequency_hz must be finite, >= 0 and strictly increasing")
        nyquist = 0.5 / ts
        if f[-1] > nyquist * (1 + 1e-12):
            raise ParameterError(f"frequency_hz reaches {f[-1]:g} Hz, above the Nyquist frequency "
                                 f"1/(2 ts) = {nyquist:g} Hz of ts = {ts:g} s")
        G = _as_response(self.response, "response")
        if G.shape[0] != f.size:
            raise ShapeError(f"response has {G.shape[0]} frequencies; frequency_hz has {f.size}")
        r = np.zeros(f.size) if self.radius is None else np.asarray(self.radius, dtype=float)
        if r.ndim == 0:
            r = np.full(f.size, float(r))
        if r.shape != (f.size,):
            raise ShapeError(f"radius must be a number or shape ({f.size},); found shape "
                             f"{r.shape}")
        if not np.all(np.isfinite(r)) or np.any(r < 0):
            raise ParameterError("radius must be finite and >= 0 at every frequency")
        if self.radius is not None and self.uncertainty == "none given (radius 0)":
            object.__setattr__(self, "uncertainty", "given radius")
        if int(self.measurements) < 1:
            raise ParameterError(f"measurements must be >= 1; got {self.measurements!r}")
        for name, value in (("frequency_hz", f), ("response", G), ("radius", r)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "ts", ts)
        object.__setattr__(self, "measurements", int(self.measurements))
        for name in ("coverage", "confidence"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _probability(value, name))

    # construction -----------------------------------------------------------------------------
    @classmethod
    def from_measurements(cls, frequency_hz, responses, ts: float, *,
                          coverage: float = DEFAULT_COVERAGE,
                          confidence: float = DEFAULT_CONFIDENCE) -> FrequencyResponseData:
        r"""Mean and normal tolerance radius of repeated measurements (module docstring).

        .. math::

            \hat G_k = \tfrac1n\textstyle\sum_i G^{(i)}_k,\qquad
            r_k = k(n, d, p, \gamma)\sqrt{\lambda_{\max}(S_k)}

        (:func:`tolerance_factor`; :math:`S_k` the sample covariance of the real and imaginary
        parts at frequency k, d = 2 n_y n_u). Since the Frobenius norm bounds the spectral
        norm, :math:`\|G - \hat G_k\|_2 \le r_k` holds wherever the tolerance ball does.

        Parameters
        ----------
        frequency_hz : array_like (n_f,)
            The common grid [Hz].
        responses : array_like (n, n_f) or (n, n_f, n_y, n_u), complex
            The n >= 2 measurements (no two the same: :func:`~ilc_analysis.model._repeats.
            refuse_repeated`).
        ts : float
            Sample time [s].
        coverage : float
            p in (0, 1): the proportion of the machine's responses the disc holds at each
            frequency (default :data:`DEFAULT_COVERAGE`).
        confidence : float
            :math:`\gamma` in (0, 1) (default :data:`DEFAULT_CONFIDENCE`).

        Raises
        ------
        ParameterError
            Fewer than two measurements (no spread to estimate), two the same, a coverage or
            confidence outside (0, 1).
        ShapeError
            ``responses`` of another shape.
        """
        arr = np.asarray(responses)
        if arr.ndim not in (2, 4):
            raise ShapeError(f"responses must have shape (n, n_f) or (n, n_f, n_y, n_u); found "
                             f"shape {arr.shape}")
        if arr.shape[0] < 2:
            raise ParameterError(f"from_measurements needs at least 2 measurements to estimate a "
                                 f"spread; got {arr.shape[0]} (give a radius instead)")
        Gs = np.stack([_as_response(a, f"responses[{i}]") for i, a in enumerate(arr)])
        refuse_repeated(list(Gs), [f"responses[{i}]" for i in range(len(Gs))], "FRF measurement")
        n = len(Gs)
        d = 2 * Gs.shape[2] * Gs.shape[3]
        k = tolerance_factor(n, d, coverage, confidence)
        mean = Gs.mean(axis=0)
        dev = (Gs - mean).reshape(n, Gs.shape[1], -1)                  # (n, n_f, n_y n_u)
        X = np.concatenate([dev.real, dev.imag], axis=2).transpose(1, 0, 2)   # (n_f, n, d)
        sigma_max = np.linalg.svd(X, compute_uv=False)[:, 0]            # sqrt((n-1) lam_max S)
        radius = k * sigma_max / np.sqrt(n - 1)
        text = (f"normal tolerance region of {n} measurements: at each frequency, with "
                f"confidence {confidence:g}, the disc holds at least {coverage:.4g} of the "
                f"machine's responses (r = {k:.4g} x sqrt(lambda_max) of their sample "
                f"covariance; measurements independent and normal)")
        return cls(frequency_hz, mean, ts, radius, text, n, coverage, confidence)

    # facts ------------------------------------------------------------------------------------
    @property
    def n_f(self) -> int:
        return int(self.frequency_hz.size)

    @property
    def n_y(self) -> int:
        return int(self.response.shape[1])

    @property
    def n_u(self) -> int:
        return int(self.response.shape[2])

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies [rad/s] of the grid."""
        return 2.0 * np.pi * self.frequency_hz

    def dft_trial_length(self) -> int | None:
        r"""N if the grid is exactly the DFT bins :math:`f_k = k/(NT_s)`, k = 0..⌊N/2⌋, of an
        N-sample trial, else None (then no periodic trial is covered by the grid).

        On such a grid a condition checked at every frequency is a statement about the
        N-periodic (circulant) trial operator, whose eigenvalues are the responses at the bins.
        """
        f = self.frequency_hz
        if f[0] != 0.0 or f.size < 2:
            return None
        df = f[1]
        N_float = 1.0 / (df * self.ts)
        N = int(round(N_float))
        if N < 2 or abs(N_float - N) > _BIN_RTOL * N or f.size != N // 2 + 1:
            return None
        if not np.allclose(f, np.arange(f.size) / (N * self.ts), rtol=_BIN_RTOL, atol=0.0):
            return None
        return N

    def inside(self, response) -> np.ndarray:
        r"""Per frequency: :math:`\|G_k - \hat G_k\|_2 \le r_k` for a candidate response.

        Parameters
        ----------
        response : array_like (n_f,) or (n_f, n_y, n_u), complex
            A plant's response on this grid.

        Returns
        -------
        ndarray of bool (n_f,)
        """
        G = _as_response(response, "response")
        if G.shape != self.response.shape:
            raise ShapeError(f"response must have shape {self.response.shape}; found {G.shape}")
        dist = np.linalg.norm(G - self.response, ord=2, axis=(-2, -1))
        return dist <= self.radius * (1 + 1e-12)

    def as_dict(self) -> dict:
        return {"n_f": self.n_f, "n_y": self.n_y, "n_u": self.n_u, "ts": self.ts,
                "f_min_hz": float(self.frequency_hz[0]), "f_max_hz": float(self.frequency_hz[-1]),
                "max_radius": float(self.radius.max()), "uncertainty": self.uncertainty,
                "measurements": self.measurements,
                **({} if self.coverage is None else
                   {"coverage": self.coverage, "confidence": self.confidence})}


# ---------------------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------------------
_CHANNEL = re.compile(r"^(re|im|mag|phase_deg)(?:_(\d+)_(\d+))?$")


def _read_csv_table(path: Path) -> tuple[list[str], np.ndarray]:
    """The header and the values of an FRF CSV file: a regular file of bounded size
    (:func:`~ilc_analysis._output.check_input_file`), UTF-8 (a byte-order mark is dropped),
    every value a finite number of magnitude at most :data:`LARGEST_SAMPLE` (a refusal names
    the file, the line and the column)."""
    from .._output import check_input_file

    check_input_file(path, "FRF file")
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            rows = [(line, row) for line, row in enumerate(csv.reader(fh), start=1)
                    if row and not row[0].startswith("#")]
    except UnicodeDecodeError as exc:
        raise ParameterError(f"FRF file {str(path)!r} is not UTF-8 text (byte {exc.start})") \
            from exc
    except (OSError, csv.Error) as exc:
        raise ParameterError(f"cannot read the FRF file {str(path)!r}: {exc}") from exc
    if len(rows) < 2:
        raise ParameterError(f"{path}: an FRF CSV needs a header line and at least one row")
    header = [h.strip().lower() for h in rows[0][1]]
    data = np.empty((len(rows) - 1, len(header)))
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ShapeError(f"FRF file {str(path)!r}, line {line}: {len(row)} value(s); every "
                             f"row must have {len(header)} (the header's columns)")
        for c, text in enumerate(row):
            try:
                value = float(text)
            except ValueError:
                value = None
            if value is None or not abs(value) <= LARGEST_SAMPLE:
                what = ("every value after the header must be a number" if value is None
                        else "every value must be a finite number" if not np.isfinite(value)
                        else f"every value must be at most {LARGEST_SAMPLE:.3g} in "
                             f"magnitude (|G|^2 would overflow float64)")
                raise ParameterError(f"FRF file {str(path)!r}, line {line}, column "
                                     f"{shown(header[c])}: {what}; found "
                                     f"{shown(text.strip(), 40)}")
            data[r, c] = value
    return header, data


def _csv_response(path: Path, header: list[str], data: np.ndarray) -> np.ndarray:
    """Complex (rows, n_y, n_u) from the channel columns of a CSV table."""
    parts: dict[tuple[int, int], dict[str, np.ndarray]] = {}
    for c, name in enumerate(header):
        if name in ("f_hz", "radius", "repeat"):
            continue
        m = _CHANNEL.match(name)
        if m is None:
            raise ParameterError(f"{path}: unknown column {name!r}; expected f_hz, radius, repeat, "
                                 f"re_<i>_<j>, im_<i>_<j>, mag_<i>_<j> or phase_deg_<i>_<j>")
        i, j = (int(m.group(2)), int(m.group(3))) if m.group(2) else (1, 1)
        if i < 1 or j < 1:
            raise ParameterError(f"{path}: column {name!r}: channels count from 1")
        parts.setdefault((i, j), {})[m.group(1)] = data[:, c]
    if not parts:
        raise ParameterError(f"{path}: no response columns (re/im or mag/phase_deg)")
    n_y = max(i for i, _ in parts)
    n_u = max(j for _, j in parts)
    G = np.empty((data.shape[0], n_y, n_u), dtype=complex)
    for i in range(1, n_y + 1):
        for j in range(1, n_u + 1):
            p = parts.get((i, j), {})
            if set(p) == {"re", "im"}:
                G[:, i - 1, j - 1] = p["re"] + 1j * p["im"]
            elif set(p) == {"mag", "phase_deg"}:
                G[:, i - 1, j - 1] = p["mag"] * np.exp(1j * np.deg2rad(p["phase_deg"]))
            else:
                raise ParameterError(f"{path}: channel (output {i}, input {j}) needs exactly the "
                                     f"columns re and im, or mag and phase_deg; found "
                                     f"{sorted(p) or 'none'}")
    return G


def _read_csv(path: Path) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
    """``(f_hz, [responses per measurement], radius or None)`` of one CSV file."""
    header, data = _read_csv_table(path)
    if "f_hz" not in header:
        raise ParameterError(f"{path}: the header must have a column f_hz (frequency [Hz])")
    G = _csv_response(path, header, data)
    f_all = data[:, header.index("f_hz")]
    r_all = data[:, header.index("radius")] if "radius" in header else None
    if "repeat" not in header:
        return f_all, [G], r_all
    rep = data[:, header.index("repeat")]
    labels = np.unique(rep)
    groups = [rep == lab for lab in labels]
    f = f_all[groups[0]]
    for lab, g in zip(labels, groups, strict=True):
        if not np.array_equal(f_all[g], f):
            raise ParameterError(f"{path}: repeat {lab:g} has another frequency grid than repeat "
                                 f"{labels[0]:g}; every repeat must use the same grid")
    radius = r_all[groups[0]] if r_all is not None else None
    return f, [G[g] for g in groups], radius


def _read_mat(path: Path) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None, float | None]:
    from .._array_files import read_mat

    # bounded and strict (ilc_analysis._array_files): numbers only, complex allowed
    mat = read_mat(path, "FRF file", error=ParameterError, complex_ok=True)
    if "f_hz" not in mat:
        raise ParameterError(f"{path}: the .mat file needs a variable f_hz (frequency [Hz])")
    f = np.asarray(mat["f_hz"], dtype=float).ravel()
    if ("G" in mat) == ("G_repeats" in mat):
        raise ParameterError(f"{path}: the .mat file needs exactly one of G (n_f[, n_y, n_u]) or "
                             f"G_repeats (n_rep, n_f[, n_y, n_u])")
    if "G" in mat:
        G = np.asarray(mat["G"])
        G = G.ravel() if G.ndim == 2 and 1 in G.shape else G
        Gs = [G]
    else:
        R = np.asarray(mat["G_repeats"])
        if R.ndim == 2 or R.ndim == 4:
            Gs = list(R)
        else:
            raise ShapeError(f"{path}: G_repeats must have shape (n_rep, n_f) or (n_rep, n_f, "
                             f"n_y, n_u); found {R.shape}")
    radius = np.asarray(mat["radius"], dtype=float).ravel() if "radius" in mat else None
    ts = float(np.asarray(mat["ts"]).ravel()[0]) if "ts" in mat else None
    return f, Gs, radius, ts


def read_frf(paths, ts: float | None = None, *, radius=None,
             coverage: float = DEFAULT_COVERAGE,
             confidence: float = DEFAULT_CONFIDENCE) -> FrequencyResponseData:
    r"""Read one or more FRF measurement files (CSV or ``.mat``, module docstring).

    One measurement in all: its response, with the file's ``radius`` column (or the
    ``radius`` argument, or 0). Several (files, or ``repeat`` groups): the mean and the normal
    tolerance radius (:meth:`FrequencyResponseData.from_measurements`), unless a radius is
    given, which then replaces the estimate. The same measurement twice is refused
    (:func:`~ilc_analysis.model._repeats.refuse_repeated`).

    Parameters
    ----------
    paths : str, Path or list of them
        The measurement files (all on one frequency grid).
    ts : float, optional
        Sample time [s]; required unless a ``.mat`` file holds ``ts``.
    radius : float or array_like (n_f,), optional
        A given uncertainty radius (overrides the file's and the estimate).
    coverage, confidence : float
        p and :math:`\gamma` of the tolerance region (several measurements).

    Returns
    -------
    FrequencyResponseData

    Raises
    ------
    ParameterError
        A missing or unreadable file, unknown columns, grids that differ, no sample time.
    """
    if isinstance(paths, str | Path):
        paths = [paths]
    paths = [Path(p) for p in paths]
    if not paths:
        raise ParameterError("read_frf needs at least one measurement file")
    grids, Gs, labels, radii = [], [], [], []
    for p in paths:
        if not p.is_file():
            raise ParameterError(f"FRF file not found: {p}")
        if p.suffix.lower() == ".mat":
            f, G, r, ts_file = _read_mat(p)
            if ts is None:
                ts = ts_file
            elif ts_file is not None and abs(ts_file - ts) > 1e-9 * ts:
                raise ParameterError(f"{p}: ts = {ts_file:g} s in the file, {ts:g} s given")
        elif p.suffix.lower() == ".csv":
            f, G, r = _read_csv(p)
        else:
            raise ParameterError(f"{p}: an FRF file must be .csv or .mat; got {p.suffix!r}")
        grids.append((p, f))
        Gs.extend(G)
        labels.extend([str(p)] if len(G) == 1 else
                      [f"{p} (measurement {k + 1} of {len(G)})" for k in range(len(G))])
        if r is not None:
            radii.append(r)
    if ts is None:
        raise ParameterError("ts (sample time) is required: give it (the CSV format does not "
                             "store it)")
    f0 = grids[0][1]
    for p, f in grids[1:]:
        if f.shape != f0.shape or not np.allclose(f, f0, rtol=1e-12, atol=0.0):
            raise ParameterError(f"{p} has another frequency grid than {grids[0][0]}; every "
                                 f"measurement must use the same grid")
    if radius is None and radii:
        radius = np.max(np.stack(radii), axis=0)
    if len(Gs) == 1:
        text = "given radius" if radius is not None else "none given (radius 0)"
        return FrequencyResponseData(f0, Gs[0], ts, radius, text, 1)
    Gs = [_as_response(G, label) for G, label in zip(Gs, labels, strict=True)]
    shapes = {G.shape for G in Gs}
    if len(shapes) != 1:
        raise ShapeError(f"the measurements have different shapes {sorted(shapes)}")
    refuse_repeated(Gs, labels, "FRF measurement")
    data = FrequencyResponseData.from_measurements(f0, np.stack(Gs), ts, coverage=coverage,
                                                   confidence=confidence)
    if radius is None:
        return data
    return FrequencyResponseData(f0, data.response, ts, radius,
                                 f"given radius, mean of {len(Gs)} measurements", len(Gs))


def write_frf_csv(path, frequency_hz, response, *, radius=None) -> Path:
    """Write one measurement as an FRF CSV (``f_hz, re_i_j, im_i_j[, radius]``).

    Parameters
    ----------
    path : str or Path
    frequency_hz : array_like (n_f,)
    response : array_like (n_f,) or (n_f, n_y, n_u), complex
    radius : array_like (n_f,), optional

    Returns
    -------
    Path
    """
    f = np.asarray(frequency_hz, dtype=float)
    G = _as_response(response, "response")
    if G.shape[0] != f.size:
        raise ShapeError(f"response has {G.shape[0]} frequencies; frequency_hz has {f.size}")
    header = ["f_hz"]
    cols = [f]
    for i in range(G.shape[1]):
        for j in range(G.shape[2]):
            header += [f"re_{i + 1}_{j + 1}", f"im_{i + 1}_{j + 1}"]
            cols += [G[:, i, j].real, G[:, i, j].imag]
    if radius is not None:
        header.append("radius")
        cols.append(np.broadcast_to(np.asarray(radius, dtype=float), f.shape))
    path = Path(path)
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(header), comments="",
               fmt="%.17g")
    return path
