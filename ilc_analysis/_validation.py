"""Input validation shared by every module: one shape validator, one finiteness check."""

from __future__ import annotations

import math
import numbers
import os
import re
import stat
import tomllib
from collections.abc import Sequence

import numpy as np

from ._toml_arrays import expand_arrays
from .exceptions import ParameterError, ShapeError

__all__ = ["as_matrix", "as_vector", "as_finite_array", "real", "positive", "nonnegative",
           "in_interval", "positive_int", "MAX_ARRAY_BYTES", "MAX_LIFTED_ENTRIES",
           "MAX_TRIAL_SAMPLES", "MAX_SUBSTEPS", "MAX_ITERATIONS", "largest_lifted_trial",
           "check_lifted_size", "check_allocation", "read_toml_file", "table",
           "MAX_TOML_NESTING", "MAX_STATES", "MAX_SHIFT", "MAX_FILTER_ORDER",
           "MAX_STUDY_POINTS", "MAX_DECOMPRESSED_BYTES", "check_limit", "printable", "shown",
           "shown_list", "MAX_SHOWN_CHARS", "MAX_SHOWN_NAMES", "MAX_ZIP_MEMBERS",
           "MAX_NPY_HEADER_BYTES"]


def _describe(shape: Sequence[int | None]) -> str:
    parts = ["any" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def _found(kind: type) -> str:
    """How a value of type ``kind`` is named in an error message ("found a bool", ...)."""
    if issubclass(kind, bool | np.bool_):
        return "a bool (true/false is not a number)"
    if issubclass(kind, numbers.Real):
        return f"a real number ({kind.__name__})"
    if issubclass(kind, numbers.Complex):
        return f"a complex number ({kind.__name__}; only real numbers are accepted)"
    if issubclass(kind, str | bytes | np.str_ | np.bytes_):
        return f"a string ({kind.__name__})"
    if kind is type(None):
        return "None"
    if issubclass(kind, list | tuple | np.ndarray):
        return ("a ragged nested sequence (rows of different lengths, or nested deeper than "
                "an array can be)")
    return f"a {kind.__name__}"


#: deepest nesting of sequences read as an array (numpy iterates at most 32 dimensions)
_MAX_NESTING = 32
#: numpy dtype kinds that are refused, and how the message names them
_BAD_KINDS = {"b": bool, "c": complex, "U": str, "S": bytes}


def _real_array(value, name: str, form: str) -> np.ndarray:
    """``value`` as a float array if every entry is a real number (int or float).

    Refused, with a message naming ``name``, the expected ``form`` and what was found: bools
    (numpy would read them as 0/1), complex numbers (numpy would drop the imaginary part),
    strings, None, other objects, and ragged or too deeply nested sequences.
    """
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
        return np.asarray(value, dtype=float)
    if isinstance(value, np.ndarray) and value.dtype.kind != "O":
        kind = _BAD_KINDS.get(value.dtype.kind)
        what = _found(kind) if kind is not None else f"an array of dtype {value.dtype}"
        raise ParameterError(f"{name} must be {form}; found {what}")
    # sequences (and object arrays): look at every entry, since numpy turns [1.0, True] into
    # [1.0, 1.0] and a ragged list into an object array without complaint
    try:
        obj = np.asarray(value, dtype=object)
    except (ValueError, TypeError) as exc:
        raise ShapeError(f"{name} must be {form}; found {_found(list)}") from exc
    if obj.ndim > _MAX_NESTING:
        raise ShapeError(f"{name} must be {form}; found a sequence nested {obj.ndim} levels "
                         f"deep (at most {_MAX_NESTING})")
    kinds = {type(v) for v in obj.flat}
    bad = sorted((k for k in kinds if issubclass(k, bool | np.bool_)
                  or not issubclass(k, numbers.Real)), key=lambda k: k.__name__)
    if bad:
        ragged = [k for k in bad if issubclass(k, list | tuple | np.ndarray)]
        error = ShapeError if ragged else ParameterError
        raise error(f"{name} must be {form}; found {_found((ragged or bad)[0])}")
    try:
        return obj.astype(float)
    except OverflowError as exc:   # an int too large for a float (e.g. 10**400)
        raise ParameterError(f"{name} must be finite; an entry is too large for a float") \
            from exc


def as_finite_array(value, name: str, *, ndim: int | None = None,
                    shape: Sequence[int | None] | None = None) -> np.ndarray:
    """Return ``value`` as a finite float array, checking its entries, rank and shape.

    This is the one validator of array input in the package. Entries must be real numbers
    (Python or numpy ints and floats); nothing is coerced.

    Parameters
    ----------
    value : array_like
        The user's input. It is never reshaped or broadcast silently. A float ndarray is
        returned as is (not copied).
    name : str
        The parameter name used in error messages.
    ndim : int, optional
        Required number of dimensions.
    shape : sequence of int or None, optional
        Required shape; ``None`` entries match any size.

    Raises
    ------
    ShapeError
        If the rank or shape differs (the message gives expected and found shapes), or the
        input is a ragged nested sequence.
    ParameterError
        If an entry is not a real number -- a bool, a complex number (even with zero imaginary
        part), a string, None or another object -- or is NaN/inf. The message names the
        parameter, the expected form and what was found.
    """
    if shape is not None:
        ndim = len(shape)
    if shape is not None:
        form = f"an array of real numbers of shape {_describe(shape)}"
    elif ndim is not None:
        form = f"a {ndim}-D array of real numbers"
    else:
        form = "an array of real numbers"
    arr = _real_array(value, name, form)
    if ndim is not None and arr.ndim != ndim:
        expected = _describe(shape) if shape is not None else f"{ndim}-D"
        raise ShapeError(f"{name} must have shape {expected}; found shape {arr.shape}")
    if shape is not None:
        for want, got in zip(shape, arr.shape, strict=True):
            if want is not None and want != got:
                raise ShapeError(
                    f"{name} must have shape {_describe(shape)}; found shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite; it contains NaN or inf")
    return arr


def as_matrix(value, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """A finite 2-D float array of shape ``(rows, cols)`` (``None`` = any)."""
    return as_finite_array(value, name, shape=(rows, cols))


def as_vector(value, name: str, size: int | None = None) -> np.ndarray:
    """A finite 1-D float array of length ``size`` (``None`` = any)."""
    return as_finite_array(value, name, shape=(size,))


def _number(value, name: str) -> float:
    """``value`` as a float if it is a real number (finite or not), else ParameterError."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a real number (int or float); found "
                             f"{_found(type(value))}: {value!r}")
    try:
        return float(value)
    except OverflowError:            # an int too large for a float
        return math.inf


def real(value, name: str) -> float:
    """A finite real number (Python or numpy int or float; bools and complex are refused).

    Raises
    ------
    ParameterError
        Naming ``name``: not a real number (with what was found), or NaN/inf.
    """
    v = _number(value, name)
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be a finite real number; got {value!r}")
    return v


def _scalar(value, name: str) -> float:
    v = _number(value, name)
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite; got {value!r}")
    return v


def positive(value, name: str) -> float:
    """A finite real number > 0."""
    v = _scalar(value, name)
    if v <= 0:
        raise ParameterError(f"{name} must be positive; got {value!r}")
    return v


def nonnegative(value, name: str) -> float:
    """A finite real number >= 0."""
    v = _scalar(value, name)
    if v < 0:
        raise ParameterError(f"{name} must be non-negative; got {value!r}")
    return v


def in_interval(value, name: str, low: float, high: float, *, closed_high: bool = False) -> float:
    """A finite real number in ``[low, high)`` (or ``[low, high]`` with ``closed_high``)."""
    v = _scalar(value, name)
    ok = low <= v <= high if closed_high else low <= v < high
    if not ok:
        bracket = "]" if closed_high else ")"
        raise ParameterError(f"{name} must lie in [{low}, {high}{bracket}; got {value!r}")
    return v


def positive_int(value, name: str, minimum: int = 1, maximum: int | None = None) -> int:
    """An integer in ``[minimum, maximum]`` (bools and floats are rejected, not truncated).

    ``maximum`` (default: none) is one of the size caps below when ``value`` sets the size of
    the work (trial length, sub-steps, iterations).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be an integer >= {minimum}; found "
                             f"{_found(type(value))}: {value!r}")
    if int(value) < minimum:
        raise ParameterError(f"{name} must be an integer >= {minimum}; got {value!r}")
    if maximum is not None and int(value) > maximum:
        raise ParameterError(f"{name} must be at most {maximum}; got {value!r}")
    return int(value)


# ---------------------------------------------------------------------------------------------
# TOML input files (gains, scenario)
# ---------------------------------------------------------------------------------------------
#: Deepest nesting of arrays / inline tables, and most parts of a dotted key, read from a TOML
#: input file. The toolkit's files need 3 (time-varying gains); Python's TOML parser recurses
#: per level (RecursionError near 500) and its memory grows with the square of a dotted key's
#: length (measured: 151 MB for a key of 6000 parts, so a 200 kB key of 100 000 parts would
#: ask for about 40 GB).
MAX_TOML_NESTING = 32

# strings and comments: they hold no structure (their brackets and dots do not count)
_TOML_STRINGS = re.compile("|".join((
    r'"""(?:[^"\\]|\\.|"(?!""))*"""',   # multi-line basic string
    r"'{3}.*?'{3}",                     # multi-line literal string
    r'"(?:[^"\\\n]|\\.)*"',             # basic string
    r"'[^'\n]*'",                       # literal string
    r"#[^\n]*",                         # comment
)), re.DOTALL)
_TOML_DOTTED = re.compile(r"(?<![\w.\-])[\w\-]+(?:[ \t]*\.[ \t]*[\w\-]+)"
                          + f"{{{MAX_TOML_NESTING},}}")

# +1 for an opening bracket or brace, -1 for a closing one, by byte value
_TOML_DEPTH_STEP = np.zeros(256, dtype=np.int8)
_TOML_DEPTH_STEP[[ord("["), ord("{")]] = 1
_TOML_DEPTH_STEP[[ord("]"), ord("}")]] = -1


def _toml_nesting(text: str, source: str) -> None:
    """Refuse TOML text nested deeper than :data:`MAX_TOML_NESTING` before parsing it."""
    bare = _TOML_STRINGS.sub("s", text)
    if _TOML_DOTTED.search(bare):
        raise ParameterError(f"{source} is nested too deeply: a dotted key has more than "
                             f"{MAX_TOML_NESTING} parts")
    codes = np.frombuffer(bare.encode(), dtype=np.uint8)
    if codes.size and int(np.cumsum(_TOML_DEPTH_STEP[codes], dtype=np.int64).max()) \
            > MAX_TOML_NESTING:
        raise ParameterError(f"{source} is nested too deeply: arrays or inline tables more "
                             f"than {MAX_TOML_NESTING} levels deep")


def read_toml_file(path, what: str) -> dict:
    """Read a TOML input file within bounds: the one reader of the toolkit's input files.

    ``path`` must name a readable regular file of at most
    :data:`~ilc_analysis._output.MAX_INPUT_BYTES` bytes (a directory, FIFO or device is refused
    before it is opened, so a FIFO cannot block), hold UTF-8 text (a leading byte-order mark,
    which some Windows editors write, is dropped), be valid TOML and be nested at most
    :data:`MAX_TOML_NESTING` levels deep. Arrays written compactly (``{ shape, fill }``
    tables, :mod:`ilc_analysis._toml_arrays`) are returned as the nested lists they stand for.

    Parameters
    ----------
    path : str or os.PathLike
    what : str
        How messages name the file, e.g. ``"gains file"``.

    Raises
    ------
    ParameterError
        Naming ``what`` and the path, for every way the file can be unreadable.
    """
    from ._output import MAX_INPUT_BYTES, check_input_file

    p = check_input_file(path, what)
    source = f"{what} {str(p)!r}"
    try:
        # non-blocking: should a FIFO replace the file after the check, opening cannot hang
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ParameterError(f"{source} cannot be opened: {exc.strerror or exc}") from exc
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise ParameterError(f"{source} is not a regular file")
        try:
            data = f.read(MAX_INPUT_BYTES + 1)
        except OSError as exc:
            raise ParameterError(f"{source} cannot be read: {exc.strerror or exc}") from exc
    if len(data) > MAX_INPUT_BYTES:
        raise ParameterError(f"{source} has more than {MAX_INPUT_BYTES} bytes; at most "
                             f"{MAX_INPUT_BYTES} are read")
    try:
        text = data.decode("utf-8-sig")     # a byte-order mark (Windows editors) is dropped
    except UnicodeDecodeError as exc:
        raise ParameterError(f"{source} is not UTF-8 text (byte {exc.start}: "
                             f"{exc.reason})") from exc
    _toml_nesting(text, source)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{source} is not valid TOML: {exc}") from exc
    except RecursionError as exc:   # pragma: no cover - _toml_nesting refuses such files first
        raise ParameterError(f"{source} is nested too deeply to be read") from exc
    try:
        return expand_arrays(doc)       # arrays written compactly: the nested lists again
    except ParameterError as exc:
        raise ParameterError(f"{source}: {exc}") from exc


# ---------------------------------------------------------------------------------------------
# Text from files, echoed in messages
# ---------------------------------------------------------------------------------------------
#: Most characters of one name or value quoted from a file in a message (:func:`shown`).
MAX_SHOWN_CHARS = 80
#: Most names listed in one message (:func:`shown_list`); the rest are counted.
MAX_SHOWN_NAMES = 8


def printable(text: str) -> str:
    """``text`` with every character that is not printable (a terminal's escape sequences,
    other control characters, line breaks) written as its Python escape (``\\x1b``), so that
    a message quoting a file cannot move the cursor, recolour or clear the user's terminal."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def shown(value, limit: int = MAX_SHOWN_CHARS) -> str:
    """A name or value from a file, as a message quotes it: its ``repr`` (quoted, control
    characters escaped), cut to ``limit`` characters with the number of those left out."""
    try:
        text = repr(value) if isinstance(value, str) else printable(repr(value))
    except ValueError:          # an int beyond Python's digit limit for str()
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def shown_list(items, limit: int = MAX_SHOWN_NAMES) -> str:
    """Names from a file as a message lists them: at most ``limit``, each :func:`shown`, then
    how many more there are (``['a', 'b', ... and 49 998 more]``); a file of 50 000 arrays
    gives a one-line message, not half a megabyte."""
    items = list(items)
    head = ", ".join(shown(v) for v in items[:limit])
    more = f", ... and {len(items) - limit} more" if len(items) > limit else ""
    return f"[{head}{more}]"


def table(value, name: str, where: str = "") -> dict:
    """``value`` must be a TOML table (a dict): ``[name]`` of the file ``where``."""
    if not isinstance(value, dict):
        prefix = f"{where}: " if where else ""
        raise ParameterError(f"{prefix}[{name}] must be a table (key = value pairs); found "
                             f"{_found(type(value))}")
    return value


# ---------------------------------------------------------------------------------------------
# Size caps of user-chosen problem sizes
# ---------------------------------------------------------------------------------------------
# Without them -N 100000 asks for 149 GiB and substeps = 1e8 never ends. They are chosen from
# what the reference machine can do (24 GiB of memory, 2 cores, shared by a few processes),
# never from a target, and applied where the sizes enter the library: the trial length N in
# lifting (check_horizon, lift), simulation (simulate) and the scenario (horizon / ts); the
# sub-steps in discretize and the scenario; the iterations in simulate and the scenario. The
# command line refuses the same values with exit status 2 before any work.

#: Largest array, in bytes, the library allocates for a size the user chose (a dense lifted
#: matrix, the record of a simulation): 1 GiB. A dense decomposition of a lifted matrix holds
#: the matrix, LAPACK's working copy and the factors (SVD: U and V^T), 4-5 copies, and an
#: Largest magnitude of a measured value the toolkit accepts (an FRF, a trial's sample, an
#: input written for the machine): the square root of the largest float64, so that its square,
#: which spreads, norms and the design's regularisation form, stays finite (a response of
#: 1e308 made the SVD fail, unexplained).
LARGEST_SAMPLE = float(np.sqrt(np.finfo(float).max))


#: analysis forms T = I - L G beside G: about 5-8 GiB at the cap, so two such runs still fit
#: in 24 GiB. (Time grows faster than memory: a full dense SVD took 10 s at 2048 x 2048 on the
#: reference machine and grows as n^3, so at the cap's 11 585 x 11 585 it takes of order 20
#: minutes; the analysis chooses cheaper methods well before that.)
MAX_ARRAY_BYTES = 2**30
#: Largest number of entries of a dense lifted matrix, (N n_y) x (N n_u): MAX_ARRAY_BYTES of
#: float64, 2**27 entries (N <= 11 585 for one input and one output, N <= 4 729 for the mobile
#: robot's two inputs and three outputs).
MAX_LIFTED_ENTRIES = MAX_ARRAY_BYTES // 8
#: Largest trial length N in samples (any plant). Building the compiled trial of the
#: simulation costs about 60 microseconds per sample (measured: 6.1 s for N = 100 000, mobile
#: robot, 4 RK4 sub-steps), and every lifted quantity is limited further by
#: MAX_LIFTED_ENTRIES.
MAX_TRIAL_SAMPLES = 100_000
#: Largest number of RK4 sub-steps per sample. The sampled step is unrolled symbolically:
#: measured on the mobile robot, 1000 sub-steps take 1.7 s to build and 0.29 s per trial of
#: 200 samples (time linear in the sub-steps), 250 times the scenario's 4.
MAX_SUBSTEPS = 1_000
#: Largest number of learning iterations (trials) of one simulation. The record of every
#: trial is kept (see MAX_ARRAY_BYTES); 10 000 trials of the paper's scenario take a few
#: minutes, 250 times its 40.
MAX_ITERATIONS = 10_000


# ---------------------------------------------------------------------------------------------
# Limits on what a design / study file may make the toolkit allocate or loop over
# ---------------------------------------------------------------------------------------------
# A design file is data from anyone (docs/design-file.md, "Trust model"): every size it sets is
# checked against these limits before anything of that size is allocated or looped over, and a
# refusal names the key path and the limit.

#: Largest number of states of a plant given by matrices (``[plant].statespace``, a ``.npz`` /
#: ``.mat`` plant file): the lifting forms powers of the n x n matrix A for each of the N + s
#: Markov parameters, n^2 N work, and a CasADi model of n states is built from it. The toolkit's
#: plants have 2 to 12 states; 1000 states (an 8 MB A) is far above any ILC model in practice.
MAX_STATES = 1_000
#: Largest output-window shift s (``[problem].shift``, the relative degree in samples): the
#: simulation runs N + s samples and the lifting computes N + s Markov parameters. The shift of
#: a sampled LTI plant is at most its number of states (or it has no output at all), so the
#: cap is MAX_STATES.
MAX_SHIFT = MAX_STATES
#: Largest order of a filter a design file names: a Q-filter's ``order`` (Butterworth order,
#: FIR taps - 1, DCT roll-off), the number of states of an LTI filter (``Q``, ``L``) and of a
#: loop controller (``[problem.learning_at.controller]``: states of ``ss``, denominator degree
#: of ``tf``). Filter loops and realisations grow with the order; 1000 leaves room for long FIR
#: filters (the default has 31 taps).
MAX_FILTER_ORDER = 1_000
#: Largest number of points of a study (the product of its axes' lengths), checked from the
#: axis specifications (``count``, ``num``, the number of values or vertices) before any axis
#: values are built: every point stores its numbers (``iterations`` floats per output).
MAX_STUDY_POINTS = 10_000_000
#: Largest array, in bytes, an ``.npz`` member or a ``.mat`` variable may declare (and largest
#: total a ``.mat`` file's compressed variables may inflate to): checked from the member's
#: header and the archive's declared sizes before it is read, so a file of a few kB that
#: inflates to gigabytes (a zip bomb) is refused. Input files are at most 16 MiB
#: (:data:`~ilc_analysis._output.MAX_INPUT_BYTES`); 64 MiB holds a reference of 100 000 samples
#: of 80 channels.
MAX_DECOMPRESSED_BYTES = 64 * 2**20
#: Most members (arrays) of an ``.npz`` archive read: a plant file holds five, a reference one.
#: The archive's directory is read before any member, and a 16 MiB file can list some 300 000
#: empty members; past this many the archive is refused before one is inflated.
MAX_ZIP_MEMBERS = 1_000
#: Largest ``.npy`` header (the dictionary of ``descr``, ``fortran_order`` and ``shape``) read,
#: in bytes: numpy's own limit for a header it parses without being told it is safe.
MAX_NPY_HEADER_BYTES = 10_000


def check_limit(value: int, limit: int, name: str, what: str) -> int:
    """``value`` if it is at most ``limit``, else a ParameterError naming ``name`` (a key path)
    and the limit (``what`` says what the number counts, e.g. ``"states"``).

    Raises
    ------
    ParameterError
        ``"{name} has {value} {what}; at most {limit} are allowed"``.
    """
    if value > limit:
        raise ParameterError(f"{name} has {value} {what}; at most {limit} are allowed")
    return value


def largest_lifted_trial(n_y: int, n_u: int) -> int:
    r"""The largest N whose dense lifted matrix :math:`(N n_y) \times (N n_u)` has at most
    :data:`MAX_LIFTED_ENTRIES` entries: :math:`\lfloor\sqrt{E_{max} / (n_y n_u)}\rfloor`."""
    return math.isqrt(MAX_LIFTED_ENTRIES // (n_y * n_u))


def _gib(n_bytes: int) -> str:
    return f"{n_bytes / 2**30:.3g} GiB"


def check_lifted_size(N: int, n_y: int, n_u: int, name: str = "N") -> None:
    r"""Refuse a trial length whose dense lifted matrix would exceed :data:`MAX_LIFTED_ENTRIES`.

    The matrix is :math:`(N n_y) \times (N n_u)` float64, :math:`8 N^2 n_y n_u` bytes.

    Raises
    ------
    ParameterError
        Naming ``name`` and N, the estimated size in GiB, the limit and the largest N allowed.
    """
    entries = (N * n_y) * (N * n_u)        # Python ints: no overflow
    if entries > MAX_LIFTED_ENTRIES:
        raise ParameterError(
            f"{name} = {N}: a dense lifted matrix of {N * n_y} x {N * n_u} float64 entries "
            f"would take {_gib(8 * entries)}, more than the {_gib(MAX_ARRAY_BYTES)} allowed "
            f"(MAX_LIFTED_ENTRIES); {name} must be at most {largest_lifted_trial(n_y, n_u)} "
            f"for {n_u} input(s) and {n_y} output(s)")


def check_allocation(entries: int, what: str) -> None:
    """Refuse to allocate ``entries`` float64 values for ``what`` beyond
    :data:`MAX_ARRAY_BYTES`; ``what`` names the sizes the user chose (e.g.
    ``"iterations = 100 and N = 5000: the simulation record"``).

    Raises
    ------
    ParameterError
        With the estimated size in GiB and the limit.
    """
    if 8 * entries > MAX_ARRAY_BYTES:
        raise ParameterError(f"{what} would take {_gib(8 * entries)} of float64, more than "
                             f"the {_gib(MAX_ARRAY_BYTES)} allowed (MAX_ARRAY_BYTES)")
