r"""Arrays in the toolkit's TOML files, written compactly and read back exactly.

A nested list of numbers is written in the shortest of three forms (docs/design-file.md,
"Arrays"), every float with Python's ``repr`` (the shortest text that reads back to the same
double: a round trip is bit-identical, -0.0 and subnormals included; ``inf`` / ``-inf`` /
``nan`` as TOML spells them):

* **inline rows**: the list itself, one line if it fits in :data:`LINE_WIDTH` characters,
  else one line per entry of its first axis (up to :data:`ROW_WIDTH`; a vector wrapped at
  the line width)::

      x0 = [1.0, 0.0, 1.5707963267948966, 3.141592653589793]
      Phi1 = [
          [[0.5, 0.5, 0.12099934569184612], [0.5, 0.5, 0.11056122708198564]],
          [[0.5, 0.16004182590229296, 0.06555775739385714], [0.5, 0.3135447521023097, 0.0575166]],
      ]

* **a constant** array: its shape and the one value, ``{ shape = [600], fill = 0.0 }``;
* **leading rows, then a constant**: the first rows along the first axis and the value of the
  rest, ``{ shape = [200, 2, 3], fill = 0.0, rows = [...] }`` (the rows after
  ``len(rows)`` hold ``fill``; e.g. the gains of a law with a lead, zero on its last samples);
  ``rows`` is itself written in its shortest form, so a vector that is one constant and then
  another is ``{ shape = [200], fill = 0.0, rows = { shape = [40], fill = 0.15 } }``.

:func:`dumps` writes a document with every such array in its shortest form;
:func:`expand_arrays` turns the two table forms back into nested lists, so that every reader
sees the lists it has always read (the long form stays valid). A table is an array form only
with exactly the keys ``shape`` and ``fill`` (and ``rows``); its size is checked before it is
built (:data:`MAX_EXPANDED`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import TypeGuard

import numpy as np
import tomli_w

from .exceptions import ParameterError

__all__ = ["dumps", "expand_arrays", "format_array", "LINE_WIDTH", "ROW_WIDTH", "MAX_EXPANDED"]

#: Characters an array may take on one line; a longer one is written one row (entry of its
#: first axis) per line.
LINE_WIDTH = 100
#: Characters one row may take on its line (e.g. one sample's gain matrix of a time-varying
#: law); a longer row is broken in turn.
ROW_WIDTH = 160
#: Most entries a table form may expand to (64 MiB of float64, the inflation cap of the
#: toolkit's other compressed inputs, :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES`).
MAX_EXPANDED = 8 * 2**20
#: Fewest repeated trailing entries written as ``fill`` rather than spelled out.
_MIN_FILL = 2


# ---------------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------------
def _number(x) -> str:
    """One number as TOML: an int as itself, a float by ``repr`` (exact), inf and nan as TOML
    spells them."""
    if isinstance(x, bool):
        raise TypeError("a bool is not a number of an array")
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(x)


def _is_number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _shape(value) -> tuple[int, ...] | None:
    """The shape of a rectangular nested list of numbers (at least one number), else None."""
    if _is_number(value):
        return ()
    if not isinstance(value, list) or not value:
        return None
    inner = [_shape(v) for v in value]
    if inner[0] is None or any(s != inner[0] for s in inner):
        return None
    return (len(value), *inner[0])


def _flat(value) -> list:
    if _is_number(value):
        return [value]
    return [x for v in value for x in _flat(v)]


def _inline(value) -> str:
    if _is_number(value):
        return _number(value)
    return "[" + ", ".join(_inline(v) for v in value) + "]"


def _lines(value, indent: str, width: int = LINE_WIDTH) -> str:
    """The nested list, one line if it fits in ``width``, else one line per entry of its first
    axis (each up to :data:`ROW_WIDTH`; a vector in lines of numbers)."""
    one = _inline(value)
    if len(indent) + len(one) <= width or _is_number(value):
        return one
    inner = indent + "    "
    if all(_is_number(v) for v in value):          # a long vector: wrapped
        rows, line = [], ""
        for text in (_number(v) + "," for v in value):
            if line and len(inner) + len(line) + 1 + len(text) > LINE_WIDTH:
                rows.append(inner + line)
                line = text
            else:
                line = f"{line} {text}" if line else text
        rows.append(inner + line)
        return "[\n" + "\n".join(rows) + f"\n{indent}]"
    return "[\n" + "".join(f"{inner}{_lines(v, inner, ROW_WIDTH)},\n" for v in value) \
        + f"{indent}]"


def _same(a, b) -> bool:
    """Equal as stored: the same type and bits (-0.0 is not 0.0; nan is nan)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return np.float64(a).tobytes() == np.float64(b).tobytes()
    return a == b


def _uniform(value) -> bool:
    flat = _flat(value)
    return all(_same(x, flat[0]) for x in flat)


def format_array(value, indent: str = "") -> str:
    """The shortest exact TOML text of a rectangular nested list of numbers (module
    docstring): inline rows, ``{ shape, fill }`` or ``{ shape, fill, rows }``.

    Parameters
    ----------
    value : list
        A rectangular nested list of ints and floats (at least one number).
    indent : str
        The indentation of the line the value starts on (for breaking long arrays).

    Raises
    ------
    ValueError
        ``value`` is not a rectangular nested list of numbers.

    Examples
    --------
    >>> format_array([0.0] * 30)
    '{ shape = [30], fill = 0.0 }'
    >>> format_array([[1.5, -0.0], [2.0, 3.0]])
    '[[1.5, -0.0], [2.0, 3.0]]'
    """
    shape = _shape(value)
    if not shape:
        raise ValueError("not a rectangular nested list of numbers")
    dims = "[" + ", ".join(map(str, shape)) + "]"
    candidates = [_lines(value, indent)]
    if len(_flat(value)) >= _MIN_FILL and _uniform(value):
        candidates.append(f"{{ shape = {dims}, fill = {_number(_flat(value)[0])} }}")
    else:
        last = _flat(value[-1])[0] if _uniform(value[-1]) else None
        k = len(value)
        while last is not None and k > 0 and _uniform(value[k - 1]) \
                and _same(_flat(value[k - 1])[0], last):
            k -= 1
        if last is not None and len(value) - k >= _MIN_FILL and k > 0:
            rows = format_array(value[:k], indent)     # itself a constant, perhaps
            candidates.append(f"{{ shape = {dims}, fill = {_number(last)}, rows = {rows} }}")
    return min(candidates, key=len)


def _placeholders(obj, found: list):
    """``obj`` with every array of numbers replaced by a placeholder string (its index in
    ``found``)."""
    if isinstance(obj, Mapping):
        return {k: _placeholders(v, found) for k, v in obj.items()}
    if isinstance(obj, list):
        if _shape(obj):
            found.append(obj)
            return f"\x00array {len(found) - 1}\x00"
        return [_placeholders(v, found) for v in obj]
    return obj


def dumps(doc: Mapping) -> str:
    """``tomli_w.dumps(doc)`` with every array of numbers in its shortest exact form
    (:func:`format_array`).

    Parameters
    ----------
    doc : mapping
        A TOML document of plain values (dicts, lists, str, int, float, bool).

    Returns
    -------
    str
        The TOML text; :func:`tomllib.loads` of it, then :func:`expand_arrays`, gives
        ``doc`` back with every float bit-identical.
    """
    found: list = []
    start_of_line = re.compile(r"[ ]*")     # the indent of the line a placeholder is on
    text = tomli_w.dumps(_placeholders(doc, found))

    def put(match: re.Match) -> str:
        start = text.rfind("\n", 0, match.start()) + 1
        indent = start_of_line.match(text, start)
        return format_array(found[int(match.group(1))], indent.group(0) if indent else "")

    return re.sub(r'"\\u0000array (\d+)\\u0000"', put, text)


# ---------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------
def _is_form(table: object) -> TypeGuard[Mapping]:
    return isinstance(table, Mapping) and "shape" in table and "fill" in table \
        and set(table) <= {"shape", "fill", "rows"}


def _expand(table: Mapping, where: str) -> list:
    shape = table["shape"]
    if not isinstance(shape, list) or not shape or not all(
            isinstance(d, int) and not isinstance(d, bool) and d >= 1 for d in shape):
        raise ParameterError(f"{where}.shape must be a list of integers >= 1 (the array's "
                             f"dimensions, e.g. shape = [200, 2, 3]); got {shape!r:.80}")
    fill = table["fill"]
    if not _is_number(fill):
        raise ParameterError(f"{where}.fill must be a number (the value of every entry, or of "
                             f"those after rows); got {fill!r:.80}")
    size = math.prod(shape)
    if size > MAX_EXPANDED:
        raise ParameterError(f"{where}: shape {shape} has {size} entries; an array written as "
                             f"a table may hold at most {MAX_EXPANDED}")
    out = np.full(shape, fill, dtype=object)        # the numbers as read: ints stay ints
    rows = table.get("rows")
    if _is_form(rows):                              # leading rows that are a constant in turn
        rows = _expand(rows, f"{where}.rows")
    if rows is not None:
        got = _shape(rows)
        if got is None or got[1:] != tuple(shape[1:]) or got[0] > shape[0]:
            raise ParameterError(f"{where}.rows must be at most {shape[0]} rows of shape "
                                 f"{shape[1:]} (the first rows along the first axis; those "
                                 f"after them hold fill); got shape {got}")
        out[:got[0]] = np.array(rows, dtype=object)
    return out.tolist()


def expand_arrays(doc, where: str = ""):
    """``doc`` with every array table (``{ shape, fill }``, ``{ shape, fill, rows }``) turned
    into the nested list it stands for; everything else unchanged.

    Parameters
    ----------
    doc : dict or list or value
        A parsed TOML document (or part of one).
    where : str
        The key path of ``doc`` (for messages, e.g. ``"[law]"``).

    Raises
    ------
    ParameterError
        A table form with a bad shape, fill or rows, or more than :data:`MAX_EXPANDED`
        entries; the message names its key path.

    Examples
    --------
    >>> expand_arrays({"x0": {"shape": [3], "fill": 0.0}})
    {'x0': [0.0, 0.0, 0.0]}
    >>> expand_arrays({"g": {"shape": [3, 1], "fill": 0.0, "rows": [[2.5]]}})
    {'g': [[2.5], [0.0], [0.0]]}
    >>> expand_arrays({"w": {"shape": [4], "fill": 0.0, "rows": {"shape": [2], "fill": 0.5}}})
    {'w': [0.5, 0.5, 0.0, 0.0]}
    """
    if isinstance(doc, Mapping):
        if _is_form(doc):
            return _expand(doc, where or "array")
        return {k: expand_arrays(v, f"{where}.{k}" if where else f"[{k}]")
                for k, v in doc.items()}
    if isinstance(doc, list):
        return [expand_arrays(v, f"{where}[{i}]") for i, v in enumerate(doc)]
    return doc
