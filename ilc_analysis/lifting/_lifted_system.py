r"""The lifted (trial-domain) description :math:`y = G u + d` of one trial.

Index convention (fixed in :mod:`ilc_analysis.laws`): with sample time :math:`T_s`, trial length
N and shift s (the sampled relative degree),

.. math::

    u = \begin{bmatrix} u(0)\\ \vdots\\ u(N-1)\end{bmatrix},\qquad
    y = \begin{bmatrix} y(s)\\ \vdots\\ y(N-1+s)\end{bmatrix},\qquad y = G u + d .

A lifted vector is the row-major flattening of the time-major array: ``u.reshape(-1)`` of a
``(N, n_u)`` array gives :math:`u` above, and ``y.reshape(N, n_y)`` undoes it. Block
:math:`G_{ij}` (``n_y x n_u``) is :math:`\partial y(i+s)/\partial u(j)`; it is zero for
:math:`j > i` (causality with the documented shift), so G is block lower-triangular.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io
import scipy.sparse

from .._validation import as_finite_array, positive, positive_int
from ..exceptions import ParameterError, ShapeError

__all__ = ["LiftedSystem"]

#: Largest N * n_y * N * n_u shown as the full matrix norm in ``_repr_html_`` (dense norm cost).
_HTML_NORM_MAX_ENTRIES = 250_000
#: Number of leading Markov blocks shown by ``_repr_html_``.
_HTML_BLOCKS_SHOWN = 3


@dataclass(frozen=True, eq=False)
class LiftedSystem:
    r"""One trial in lifted form, :math:`y = G u + d` (docs/theory.md §8). Frozen.

    Built by :func:`ilc_analysis.lifting.lift`; arrays are read-only.
    """

    G: np.ndarray
    """lifted input-output matrix, shape ``(N*n_y, N*n_u)``, block lower-triangular"""
    d: np.ndarray
    """free response (initial state, disturbances, linearisation offset), shape ``(N*n_y,)``"""
    shift: int
    """sampled relative degree s >= 0: the output window is y(s) ... y(N-1+s)"""
    ts: float
    """sample time [s]"""
    N: int
    """trial length in samples"""
    n_u: int
    """number of inputs"""
    n_y: int
    """number of outputs"""
    input_names: tuple[str, ...] = ()
    """input channel names (default u0, u1, ...)"""
    output_names: tuple[str, ...] = ()
    """output channel names (default y0, y1, ...)"""
    t0: float = 0.0
    """time of sample 0 [s]"""
    kind: str = "lti"
    """``'lti'`` (Toeplitz of Markov parameters) or ``'ltv'`` (Jacobian along a nominal trial)"""
    u_nominal: np.ndarray | None = field(default=None)
    """the nominal input ``(N, n_u)`` an ``'ltv'`` lifting was taken along, else None"""

    def __post_init__(self) -> None:
        N = positive_int(self.N, "N")
        n_u = positive_int(self.n_u, "n_u")
        n_y = positive_int(self.n_y, "n_y")
        object.__setattr__(self, "N", N)
        object.__setattr__(self, "n_u", n_u)
        object.__setattr__(self, "n_y", n_y)
        object.__setattr__(self, "ts", positive(self.ts, "ts"))
        if isinstance(self.shift, bool) or not isinstance(self.shift, int | np.integer) \
                or self.shift < 0:
            raise ParameterError(f"shift must be an integer >= 0 (samples); got {self.shift!r}")
        object.__setattr__(self, "shift", int(self.shift))
        G = as_finite_array(self.G, "G", shape=(N * n_y, N * n_u))
        d = as_finite_array(self.d, "d", shape=(N * n_y,))
        for arr in (G, d):
            arr.setflags(write=False)
        object.__setattr__(self, "G", G)
        object.__setattr__(self, "d", d)
        object.__setattr__(self, "input_names", _names(self.input_names, n_u, "input_names",
                                                       "u"))
        object.__setattr__(self, "output_names", _names(self.output_names, n_y, "output_names",
                                                        "y"))
        if self.kind not in ("lti", "ltv"):
            raise ParameterError(f"kind must be 'lti' or 'ltv'; got {self.kind!r}")
        if self.u_nominal is not None:
            un = as_finite_array(self.u_nominal, "u_nominal", shape=(N, n_u))
            un.setflags(write=False)
            object.__setattr__(self, "u_nominal", un)

    # shape facts -----------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        """``(N*n_y, N*n_u)``."""
        return self.G.shape

    @property
    def input_times(self) -> np.ndarray:
        """Times of the input samples u(0..N-1) [s]."""
        return self.t0 + self.ts * np.arange(self.N)

    @property
    def output_times(self) -> np.ndarray:
        """Times of the output window y(s..N-1+s) [s]."""
        return self.t0 + self.ts * (self.shift + np.arange(self.N))

    def block(self, i: int, j: int) -> np.ndarray:
        r"""The block :math:`G_{ij} = \partial y(i+s)/\partial u(j)`, shape ``(n_y, n_u)``.

        Parameters
        ----------
        i, j : int
            Output and input sample indices in [0, N).
        """
        for name, k in (("i", i), ("j", j)):
            if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k < self.N:
                raise ParameterError(f"{name} must be an integer in [0, {self.N}); got {k!r}")
        return self.G[i * self.n_y:(i + 1) * self.n_y, j * self.n_u:(j + 1) * self.n_u]

    def markov_blocks(self, count: int | None = None) -> np.ndarray:
        r"""The first column of blocks :math:`G_{i0}`, ``(count, n_y, n_u)``; for an LTI
        lifting these are the Markov parameters :math:`h_{s}, h_{s+1}, \dots`.

        Parameters
        ----------
        count : int, optional
            How many blocks (default: N; at most N).
        """
        count = self.N if count is None else min(positive_int(count, "count"), self.N)
        col = self.G[:count * self.n_y, :self.n_u]
        return col.reshape(count, self.n_y, self.n_u).copy()

    # conversions -----------------------------------------------------------------------------
    def dense(self) -> np.ndarray:
        """G as a writable dense ``ndarray`` (a copy)."""
        return np.array(self.G)

    def sparse(self) -> scipy.sparse.csr_array:
        """G as a ``scipy.sparse`` CSR array (exact zeros dropped)."""
        return scipy.sparse.csr_array(self.G)

    def lifted(self, signal, name: str, per: str) -> np.ndarray:
        """A signal as a lifted vector: accepts ``(N, n)`` (time-major) or ``(N*n,)``.

        Parameters
        ----------
        signal : array_like, shape (N, n) or (N*n,)
            The signal, time-major or lifted.
        name : str
            The signal's name in error messages.
        per : {'input', 'output'}
            Whether n is the number of inputs or of outputs.
        """
        n = self.n_u if per == "input" else self.n_y
        arr = np.asarray(signal, dtype=float)
        if arr.ndim == 2:
            return as_finite_array(arr, name, shape=(self.N, n)).reshape(-1)
        return as_finite_array(arr, name, shape=(self.N * n,))

    def predict(self, u) -> np.ndarray:
        r""":math:`y = G u + d` as a lifted vector ``(N*n_y,)``.

        ``u`` is ``(N, n_u)`` (time-major) or the lifted ``(N*n_u,)``; reshape the result with
        :meth:`to_samples`.

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        """
        return self.G @ self.lifted(u, "u", "input") + self.d

    def to_samples(self, y, which: str = "output") -> np.ndarray:
        """A lifted vector as a time-major ``(N, n)`` array (``which`` = 'output' or 'input').

        Parameters
        ----------
        y : array_like, shape (N*n,)
            A lifted vector.
        which : {'output', 'input'}, optional
            Whether it is an output (n = n_y) or an input (n = n_u).
        """
        if which not in ("output", "input"):
            raise ParameterError(f"which must be 'output' or 'input'; got {which!r}")
        n = self.n_y if which == "output" else self.n_u
        return as_finite_array(y, which, shape=(self.N * n,)).reshape(self.N, n)

    def as_dict(self) -> dict:
        """Plain arrays and metadata (the content of :meth:`save`; ``u_nominal`` only for an
        LTV lifting)."""
        out = {"G": self.dense(), "d": np.array(self.d), "shift": self.shift, "ts": self.ts,
               "N": self.N, "n_u": self.n_u, "n_y": self.n_y, "t0": self.t0,
               "kind": self.kind, "input_names": list(self.input_names),
               "output_names": list(self.output_names)}
        if self.u_nominal is not None:
            out["u_nominal"] = np.array(self.u_nominal)
        return out

    def save(self, path: str | Path) -> Path:
        """Write G, d, shift, ts, N (and names) to ``.npz`` (numpy) or ``.mat`` (MATLAB).

        Parameters
        ----------
        path : str or pathlib.Path
            Target file; its suffix (``.npz`` or ``.mat``) picks the format.
        """
        path = Path(path)
        data = self.as_dict()
        if path.suffix == ".npz":
            arrays: dict[str, Any] = {k: (np.array(v) if isinstance(v, list) else v)
                                      for k, v in data.items()}
            np.savez(path, **arrays)
        elif path.suffix == ".mat":
            data["input_names"] = np.array(self.input_names, dtype=object)
            data["output_names"] = np.array(self.output_names, dtype=object)
            scipy.io.savemat(path, data, do_compression=True, oned_as="column")
        else:
            raise ParameterError(f"path must end in .npz or .mat; got {str(path)!r}")
        return path

    @classmethod
    def load(cls, path: str | Path) -> LiftedSystem:
        """Read a file written by :meth:`save` (``.npz`` or ``.mat``).

        Parameters
        ----------
        path : str or pathlib.Path
            A ``.npz`` or ``.mat`` file written by :meth:`save`.
        """
        from .._array_files import read_arrays

        path = Path(path)
        if path.suffix not in (".npz", ".mat"):
            raise ParameterError(f"path must end in .npz or .mat; got {str(path)!r}")
        # bounded, never unpickled (ilc_analysis._array_files): numbers and names only
        raw = read_arrays(path, "lifted-system file", error=ParameterError, text=True)
        missing = [k for k in ("G", "d", "shift", "ts", "N", "n_u", "n_y", "t0", "kind",
                               "input_names", "output_names") if k not in raw]
        if missing:
            raise ParameterError(f"lifted-system file {str(path)!r} lacks {missing} (not a "
                                 f"file written by LiftedSystem.save)")

        def names(key):
            return tuple(str(s).strip() for s in np.ravel(raw[key]))

        def number(key):
            value = np.ravel(raw[key])
            if value.size != 1 or value.dtype.kind not in "iuf":
                raise ParameterError(f"lifted-system file {str(path)!r}: {key} must be one "
                                     f"number; found shape {value.shape}, dtype {value.dtype}")
            return value[0]

        N, n_u = int(number("N")), int(number("n_u"))
        return cls(G=raw["G"], d=np.ravel(raw["d"]), shift=int(number("shift")),
                   ts=float(number("ts")), N=N, n_u=n_u, n_y=int(number("n_y")),
                   t0=float(number("t0")), kind=str(np.ravel(raw["kind"])[0]).strip(),
                   input_names=names("input_names"), output_names=names("output_names"),
                   u_nominal=(np.reshape(raw["u_nominal"], (N, n_u))
                              if "u_nominal" in raw else None))

    # display ---------------------------------------------------------------------------------
    def __repr__(self) -> str:
        return (f"<LiftedSystem {self.kind}: N={self.N}, ts={self.ts:g} s, shift={self.shift}, "
                f"inputs {list(self.input_names)}, outputs {list(self.output_names)}, "
                f"G {self.G.shape[0]}x{self.G.shape[1]}>")

    def _repr_html_(self) -> str:
        rows = [
            ("kind", "LTI (block Toeplitz of Markov parameters)" if self.kind == "lti"
             else "LTV (Jacobian along a nominal trial)"),
            ("trial", f"N = {self.N} samples, T<sub>s</sub> = {self.ts:g} s, "
                      f"t<sub>0</sub> = {self.t0:g} s"),
            ("shift s", f"{self.shift} (y window: y({self.shift}) … y({self.N - 1 + self.shift}))"),
            ("inputs", ", ".join(map(html.escape, self.input_names))),
            ("outputs", ", ".join(map(html.escape, self.output_names))),
            ("G", f"{self.G.shape[0]} × {self.G.shape[1]}, "
                  f"{np.count_nonzero(self.G)} non-zeros"),
            ("‖d‖<sub>∞</sub>", f"{np.max(np.abs(self.d), initial=0.0):.4g}"),
        ]
        if self.G.size <= _HTML_NORM_MAX_ENTRIES:
            rows.append(("‖G‖<sub>2</sub>", f"{np.linalg.norm(self.G, 2):.4g}"))
        blocks = self.markov_blocks(_HTML_BLOCKS_SHOWN)
        shown = "".join(f"<li>G<sub>{i},0</sub> = {html.escape(np.array2string(b, precision=4))}"
                        f"</li>" for i, b in enumerate(blocks))
        rows.append(("first blocks", f"<ul style='margin:0'>{shown}</ul>"))
        body = "".join(f"<tr><th style='text-align:left'>{k}</th><td style='text-align:left'>"
                       f"{v}</td></tr>" for k, v in rows)
        return f"<b>LiftedSystem</b> <i>y = G u + d</i><table>{body}</table>"


def _names(names, n: int, what: str, prefix: str) -> tuple[str, ...]:
    if names is None or len(names) == 0:
        return tuple(f"{prefix}{k}" for k in range(n))
    names = tuple(names)
    if len(names) != n:
        raise ShapeError(f"{what} must have {n} entries; found {len(names)}")
    if any(not isinstance(s, str) or not s for s in names):
        raise ParameterError(f"{what} must be non-empty strings; got {names!r}")
    return names
