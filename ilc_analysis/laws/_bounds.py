r"""The machine's limits on a trial, for the optimisation-based laws (constrained and nonlinear
norm-optimal ILC): one parser, one violation measure, one plain form for design files.

.. math::

    \underline u(k) \le u(k) \le \overline u(k),\quad |u(k) - u(k-1)| \le \delta(k),\quad
    \underline y(j) \le y(j) \le \overline y(j),\quad
    \underline x_c(k) \le x_c(k) \le \overline x_c(k)\ (k \ge 1)

on the inputs u(0..N-1), the output window y(s..N-1+s) and named states x(0..N+s-1) (the
initial state is not the input's to change). Each bound is a number, one per channel or one
per sample; ±inf (or a missing side) for none; lower > upper is refused.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from ..exceptions import ParameterError, ShapeError

__all__ = ["TrialBounds", "VIOLATION_TOL", "bound_array", "bound_pair", "plain_bound",
           "violation"]

#: absolute tolerance (relative to the signal's scale) before a bound counts as violated by
#: a certificate or an elastic diagnosis
VIOLATION_TOL = 1e-7


def bound_array(value, name: str, n: int, rows: int, *, fill: float) -> np.ndarray:
    """A bound as ``(rows, n)``: None (= fill), scalar, per channel ``(n,)`` or per sample
    ``(rows, n)`` (``(rows,)`` for a single channel); ±inf allowed, NaN not."""
    if value is None:
        return np.full((rows, n), fill)
    if isinstance(value, bool) or (not isinstance(value, numbers.Real | list | tuple | np.ndarray)):
        raise ParameterError(f"{name} must be a number, shape ({n},) per channel or ({rows}, "
                             f"{n}) per sample; got {type(value).__name__}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be real numbers; got {value!r:.80}") from exc
    if np.any(np.isnan(arr)):
        raise ParameterError(f"{name} must not contain NaN (use ±inf for no bound)")
    if arr.ndim == 0:
        return np.full((rows, n), float(arr))
    if arr.shape == (n,):
        return np.tile(arr, (rows, 1))
    if arr.shape == (rows, n):
        return arr.copy()
    if n == 1 and arr.shape == (rows,):
        return arr.reshape(rows, 1).copy()
    raise ShapeError(f"{name} must be a scalar, shape ({n},) per channel or ({rows}, {n}) per "
                     f"sample; found shape {arr.shape}")


def bound_pair(value, name: str, n: int, rows: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(lower, upper)`` bounds, each as :func:`bound_array`; lower <= upper everywhere; None
    when nothing is bounded."""
    if value is None:
        return None
    if isinstance(value, dict):
        unknown = sorted(str(k) for k in set(value) - {"lower", "upper"})
        if unknown:
            raise ParameterError(f"{name} as a table takes the keys 'lower' and 'upper' (either "
                                 f"may be left out); got unknown key(s) {unknown}")
        value = (value.get("lower"), value.get("upper"))
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ParameterError(f"{name} must be a pair (lower, upper) or a table {{lower, upper}} "
                             f"(each a number, ({n},) per channel or ({rows}, {n}) per sample, "
                             f"None for no bound); got {value!r:.80}")
    lo = bound_array(value[0], f"{name} lower", n, rows, fill=-np.inf)
    hi = bound_array(value[1], f"{name} upper", n, rows, fill=np.inf)
    bad = np.argwhere(lo > hi)
    if bad.size:
        k, c = bad[0]
        raise ParameterError(f"{name} are inconsistent: lower > upper at sample {k}, channel {c} "
                             f"({lo[k, c]:g} > {hi[k, c]:g}); lower <= upper is required")
    if np.all(np.isinf(lo) & (lo < 0)) and np.all(np.isinf(hi) & (hi > 0)):
        return None
    return lo, hi


def violation(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How far ``x`` lies outside ``[lo, hi]`` (0 inside), elementwise."""
    return np.maximum(np.maximum(lo - x, x - hi), 0.0)


def plain_bound(b: np.ndarray):
    """A bound array as the smallest plain form: a number, per channel, or per sample."""
    if np.all(b == b[0]):
        row = b[0]
        return float(row[0]) if np.all(row == row[0]) else row.tolist()
    return b.tolist()


@dataclass(frozen=True)
class TrialBounds:
    """The parsed bounds of a trial (module docstring): ``input`` and ``output`` are
    ``(lower, upper)`` arrays ``(N, n)``, ``rate`` ``(N-1, n_u)``, ``state``
    ``(indices (n_c,), lower (N+s, n_c), upper (N+s, n_c))``; None where unbounded."""

    input: tuple | None
    rate: np.ndarray | None
    output: tuple | None
    state: tuple | None
    input_names: tuple
    state_names: tuple

    @classmethod
    def parse(cls, *, N: int, shift: int, n_u: int, n_y: int, input_names, state_names=None,
              input_bounds=None, rate_bounds=None, output_bounds=None,
              state_bounds=None) -> TrialBounds:
        """Validate and normalise the user's bounds (names the offending parameter)."""
        rate = None
        if rate_bounds is not None:
            rb = bound_array(rate_bounds, "rate_bounds", n_u, max(N - 1, 1), fill=np.inf)
            if np.any(rb <= 0):
                raise ParameterError(f"rate_bounds must be > 0 (|u(k) - u(k-1)| <= delta); "
                                     f"found min {rb.min():g}")
            rate = None if np.all(np.isinf(rb)) or N < 2 else rb[: N - 1]
        names = tuple(state_names) if state_names is not None else ()
        return cls(bound_pair(input_bounds, "input_bounds", n_u, N), rate,
                   bound_pair(output_bounds, "output_bounds", n_y, N),
                   _state(state_bounds, names, N + shift), tuple(input_names), names)

    @property
    def any(self) -> bool:
        """Whether anything is bounded."""
        return any(b is not None for b in (self.input, self.rate, self.output, self.state))

    def violations(self, u: np.ndarray, y: np.ndarray | None = None,
                   x: np.ndarray | None = None) -> dict:
        """Largest violation of each bound group by input ``u`` (N, n_u), output ``y``
        (N, n_y) and states ``x`` (N+s, n_x; k >= 1); NaN for a group whose signal is not
        given."""
        out = {}
        if self.input is not None:
            out["input"] = float(np.max(violation(u, *self.input)))
        if self.rate is not None:
            out["rate"] = float(np.max(violation(np.diff(u, axis=0), -self.rate, self.rate)))
        if self.output is not None:
            out["output"] = (float("nan") if y is None
                             else float(np.max(violation(y, *self.output))))
        if self.state is not None:
            idx, lo, hi = self.state
            out["state"] = (float("nan") if x is None
                            else float(np.max(violation(x[1:, idx], lo[1:], hi[1:]),
                                              initial=0.0)))
        return out

    def first_violation(self, u: np.ndarray) -> str | None:
        """The largest violation of the input or rate bounds by ``u``, as a sentence, or None."""
        names = self.input_names
        if self.input is not None:
            v = violation(u, *self.input)
            if np.any(v > VIOLATION_TOL * (1.0 + np.abs(u))):
                k, c = np.unravel_index(np.argmax(v), v.shape)
                lo, hi = self.input[0][k, c], self.input[1][k, c]
                return (f"input_bounds [{lo:g}, {hi:g}] on channel {c} ({names[c]}) at sample "
                        f"{k}: u = {u[k, c]:g}")
        if self.rate is not None:
            du = np.diff(u, axis=0)
            v = violation(du, -self.rate, self.rate)
            if np.any(v > VIOLATION_TOL * (1.0 + np.abs(du))):
                k, c = np.unravel_index(np.argmax(v), v.shape)
                return (f"rate_bounds |u(k) - u(k-1)| <= {self.rate[k, c]:g} on channel "
                        f"{c} ({names[c]}) between samples {k} and {k + 1}: change "
                        f"{du[k, c]:g}")
        return None

    def describe(self) -> dict:
        """The bounds as a design file writes them (no ±inf: a missing side)."""

        def pair(b):
            out = {}
            for key, side, inf in (("lower", b[0], -np.inf), ("upper", b[1], np.inf)):
                if not np.all(side == inf):
                    out[key] = plain_bound(side)
            return out

        out = {}
        if self.input is not None:
            out["input_bounds"] = pair(self.input)
        if self.rate is not None:
            out["rate_bounds"] = plain_bound(self.rate)
        if self.output is not None:
            out["output_bounds"] = pair(self.output)
        if self.state is not None:
            idx, lo, hi = self.state
            out["state_bounds"] = {self.state_names[i]: pair((lo[:, [c]], hi[:, [c]]))
                                   for c, i in enumerate(idx)}
        return out


def _state(value, names: tuple, rows: int):
    """``(indices, lower (rows, n_c), upper (rows, n_c))`` from ``{state name: (lower, upper)
    or {lower, upper}}`` (each side a number or ``(rows,)`` per sample)."""
    if value is None:
        return None
    if not isinstance(value, dict) or not value:
        raise ParameterError(f"state_bounds must be a table {{state name: (lower, upper)}} "
                             f"(states: {', '.join(names)}); got {value!r:.80}")
    idx, los, his = [], [], []
    for key, pair in value.items():
        if key not in names:
            raise ParameterError(f"state_bounds: unknown state {key!r}; the states are "
                                 f"{list(names)}")
        bounds = bound_pair(pair, f"state_bounds[{key!r}]", 1, rows)
        if bounds is None:
            continue
        idx.append(names.index(key))
        los.append(bounds[0][:, 0])
        his.append(bounds[1][:, 0])
    if not idx:
        return None
    return np.array(idx, dtype=int), np.column_stack(los), np.column_stack(his)
