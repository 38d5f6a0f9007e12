"""C text for the export: literals of the chosen precision, constant arrays, string literals.

Every number written into the generated sources goes through :func:`literal`: in double
precision the shortest text that reads back as the same double (``repr``), in single precision
the float nearest the value (rounded once, to nearest, by numpy) written with an ``f`` suffix,
so the compiler does no rounding of its own. The rounding analysis of single precision
(:mod:`ilc_analysis.export._rounding`) counts that one rounding per constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import InternalError, ParameterError

__all__ = ["PRECISIONS", "REAL_BYTES", "UNIT_ROUNDOFF", "literal", "CArray", "c_string",
           "comment_text", "indent"]

#: The arithmetic of the generated code: ``ilc_real`` is ``double`` or ``float``.
PRECISIONS = {"double": "double", "single": "float"}
#: ``sizeof(ilc_real)`` of each precision (IEEE 754 binary64 / binary32).
REAL_BYTES = {"double": 8, "single": 4}
#: The unit roundoff u of each precision (round to nearest): 2^-53 and 2^-24.
UNIT_ROUNDOFF = {"double": 2.0 ** -53, "single": 2.0 ** -24}
#: Values per line of a constant array.
_PER_LINE = 4


def check_precision(precision) -> str:
    """``precision`` must be one of :data:`PRECISIONS`."""
    if precision not in PRECISIONS:
        raise ParameterError(f"precision must be one of {sorted(PRECISIONS)}; got "
                             f"{precision!r}")
    return precision


def literal(value: float, precision: str) -> str:
    """``value`` as a C literal of ``ilc_real`` (module docstring)."""
    v = float(value)
    if not math.isfinite(v):
        raise InternalError(f"a constant of the generated code is not finite: {v!r}")
    if precision == "single":
        f = np.float32(v)
        if not np.isfinite(f):
            raise ParameterError(f"the constant {v!r} overflows single precision (its largest "
                                 f"value is {np.finfo(np.float32).max:.4g}): export in double")
        text = np.format_float_scientific(f, unique=True)      # e.g. 1.5e-01
        return text + "f"
    text = repr(v)
    return text if any(c in text for c in ".e") else text + ".0"


@dataclass(frozen=True)
class CArray:
    """A constant array of the generated code (it lives in flash: ``static const``)."""

    name: str
    """its C name"""
    values: np.ndarray
    """its values, flattened in the order the code indexes them"""
    comment: str
    """what it holds and its layout"""

    def __post_init__(self) -> None:
        arr = np.ascontiguousarray(np.asarray(self.values, dtype=float).reshape(-1))
        if arr.size == 0:
            raise InternalError(f"constant array {self.name} is empty")
        object.__setattr__(self, "values", arr)

    @property
    def size(self) -> int:
        return int(self.values.size)

    def definition(self, precision: str) -> str:
        """``/* comment */ static const ilc_real name[size] = {...};``."""
        items = [literal(v, precision) for v in self.values]
        rows = [", ".join(items[i:i + _PER_LINE]) for i in range(0, len(items), _PER_LINE)]
        body = ",\n    ".join(rows)
        return (f"/* {comment_text(self.comment)} */\n"
                f"static const ilc_real {self.name}[{self.size}] = {{\n    {body}\n}};\n")


def comment_text(text: str) -> str:
    """``text`` safe inside a C block comment (no ``*/``, no ``/*``)."""
    return str(text).replace("*/", "* /").replace("/*", "/ *")


def c_string(text: str) -> str:
    """``text`` as a C string literal (ASCII; other characters as octal escapes)."""
    out = []
    for ch in str(text):
        code = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 32 <= code < 127:
            out.append(ch)
        else:
            out.extend(f"\\{b:03o}" for b in ch.encode("utf-8"))
    return '"' + "".join(out) + '"'


def indent(text: str, spaces: int = 4) -> str:
    """Every non-empty line of ``text`` indented by ``spaces``."""
    pad = " " * spaces
    return "\n".join(pad + line if line.strip() else line for line in text.splitlines())
