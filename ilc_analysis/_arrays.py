"""Array helpers shared by the stages (numeric, no package imports)."""

from __future__ import annotations

import math
import mmap
import threading
import weakref

import numpy as np

__all__ = ["long_matmul", "narrow_reduce", "lazy_zeros", "recycled_empty"]

#: inner dimensions up to this are multiplied by broadcasting (:func:`long_matmul`)
_BROADCAST_INNER = 8
#: arrays of at least this many bytes are mapped zero pages (:func:`lazy_zeros`)
_LAZY_ZEROS_BYTES = 1 << 20
#: arrays of at least this many bytes come from the pool of maps (:func:`recycled_empty`)
_RECYCLE_BYTES = 1 << 20
#: maps kept for reuse once no array uses them (the most recently freed), and their total size
_RECYCLE_KEEP = 2
_RECYCLE_KEEP_BYTES = 256 << 20
_free_maps: list[mmap.mmap] = []
_free_lock = threading.Lock()


def long_matmul(X: np.ndarray, M: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    r"""``X @ M`` for a long ``X`` ``(L, p)`` and a small ``M`` ``(p, q)``.

    :math:`\sum_j X_{:,j} M_{j,:}` by ``p`` broadcast products when p is small: numpy's
    ``matmul`` takes a generic loop for such shapes (ten times slower at L = 20 000, p = q = 1
    on the development machine); a larger inner dimension goes to ``matmul``. Unlike
    ``matmul`` it follows numpy's floating-point error state (an overflow warns unless the
    caller has set ``np.errstate``).

    Parameters
    ----------
    X : ndarray, shape (L, p)
    M : ndarray, shape (p, q)
    out : ndarray, shape (L, q), optional
        Where to write the product (not overlapping ``X``); default a new array.

    Returns
    -------
    ndarray, shape (L, q)
        ``out`` when given.
    """
    p = M.shape[0]
    if p > _BROADCAST_INNER or p == 0:
        return np.matmul(X, M, out=out)
    if M.shape[1] == 1:     # one column: products with scalars (numpy's fast loop; a (1,)
        if p == 1:          # array takes a slower one)
            return np.multiply(X, M[0, 0].item(), out=out)
        out = np.multiply(X[:, :1], M[0, 0].item(), out=out)
        for j in range(1, p):
            out += X[:, j:j + 1] * M[j, 0].item()
        return out
    out = np.multiply(X[:, 0, None], M[0], out=out)
    for j in range(1, p):
        out += X[:, j, None] * M[j]
    return out


def narrow_reduce(ufunc: np.ufunc, a: np.ndarray, axis: int) -> np.ndarray:
    r"""``ufunc.reduce(a, axis=axis)`` for an array whose axes after ``axis`` are few.

    numpy reduces a long axis followed by a short one (a trial's samples by its few states or
    channels) with one short inner loop per sample, tens of nanoseconds per value (on the
    development machine, the maximum over 20 001 samples of 7 states: 0.78 ms, against 0.15 ms
    state by state); so up to ``_BROADCAST_INNER`` trailing values are reduced one at a time,
    each along one long loop. The values reduced are the same (a sum may round differently:
    numpy sums a long loop pairwise).

    Parameters
    ----------
    ufunc : numpy.ufunc
        A reducing ufunc (``np.maximum``, ``np.add``, ...).
    a : ndarray
        A float array.
    axis : int
        The axis to reduce (non-negative).

    Returns
    -------
    ndarray
        ``a``'s shape without ``axis``.
    """
    tail = a.shape[axis + 1:]
    width = math.prod(tail)
    if width > _BROADCAST_INNER or width == 0 or a.shape[axis] == 0:
        return ufunc.reduce(a, axis=axis)
    flat = a.reshape(a.shape[:axis + 1] + (width,))
    out = np.empty(a.shape[:axis] + (width,), dtype=a.dtype)
    for j in range(width):
        out[..., j] = ufunc.reduce(flat[..., j], axis=axis)
    return out.reshape(a.shape[:axis] + tail)


def lazy_zeros(shape: tuple[int, ...]) -> np.ndarray:
    r"""A writable float array of zeros whose memory is cleared only where it is touched.

    ``np.zeros`` asks ``calloc``, which clears the whole block when the allocator reuses
    memory (glibc: any block below its mmap threshold; a learning run's data set raises that
    threshold to its record's size): 0.6 ms for 6.4 MB on the development machine, over 10 ms
    when the heap grows first. From :data:`_LAZY_ZEROS_BYTES` on the array is an anonymous
    memory map instead: zero pages the operating system supplies on first access, so an
    array that is mostly never read or written (a run's forgetting factors without
    forgetting) costs one map. Smaller arrays: ``np.zeros``.

    Parameters
    ----------
    shape : tuple of int
        The array's shape.

    Returns
    -------
    ndarray of float64
        Zeros, C-ordered and writable.
    """
    nbytes = math.prod(shape) * np.dtype(float).itemsize
    if nbytes < _LAZY_ZEROS_BYTES:
        return np.zeros(shape)
    return np.frombuffer(_anonymous_map(nbytes), dtype=float).reshape(shape)


def _anonymous_map(nbytes: int, huge: bool = False) -> mmap.mmap:
    """A private anonymous memory map of ``nbytes``; ``huge``: huge pages asked for where the
    system offers them on request (as numpy does for its large arrays), for memory that is
    written whole."""
    if hasattr(mmap, "MAP_PRIVATE"):    # POSIX: the process's own pages, not shared on fork
        memory = mmap.mmap(-1, nbytes, flags=mmap.MAP_PRIVATE)
    else:                               # Windows: an anonymous map is the process's own
        memory = mmap.mmap(-1, nbytes)
    if huge and hasattr(mmap, "MADV_HUGEPAGE"):
        memory.madvise(mmap.MADV_HUGEPAGE)
    return memory


def _release(memory: mmap.mmap) -> None:
    """Put ``memory`` back in the pool (no array uses it any more): the pool keeps the
    :data:`_RECYCLE_KEEP` most recently freed maps while they total at most
    :data:`_RECYCLE_KEEP_BYTES`; a map it drops is returned to the system."""
    with _free_lock:
        _free_maps.append(memory)
        del _free_maps[:-_RECYCLE_KEEP]
        while sum(len(m) for m in _free_maps) > _RECYCLE_KEEP_BYTES:
            del _free_maps[0]


def recycled_empty(n: int) -> np.ndarray:
    r"""A new uninitialised float64 array of ``n`` values whose memory is reused from an
    earlier array that is gone.

    A learning run's record is written once, trial by trial, into one block (32 MB for 40
    trials of 20 000 samples). Memory the process has not touched yet costs a page fault per
    page on first write (on a virtual machine, more than the run's whole arithmetic), and
    glibc hands a block of this size back to the system when it is freed unless its mmap
    threshold happens to lie above it. So from :data:`_RECYCLE_BYTES` on the array is an
    anonymous memory map from a small pool: when the array and every view of it are gone the
    map goes back to the pool (at most :data:`_RECYCLE_KEEP` maps of at most
    :data:`_RECYCLE_KEEP_BYTES` in all are kept), and the next array of at least half and at
    most its size reuses its pages. A run whose result is kept gets a new map. Smaller
    arrays: ``np.empty``.

    Parameters
    ----------
    n : int
        Number of values.

    Returns
    -------
    ndarray of float64, shape (n,)
        Writable and uninitialised (a reused map holds the earlier array's values).
    """
    nbytes = n * np.dtype(float).itemsize
    if nbytes < _RECYCLE_BYTES:
        return np.empty(n)
    with _free_lock:       # the smallest free map that fits and is at most twice the size
        fits = [m for m in _free_maps if nbytes <= len(m) <= 2 * nbytes]
        memory = min(fits, key=len) if fits else None
        if memory is not None:
            _free_maps.remove(memory)
    if memory is None:
        memory = _anonymous_map(nbytes, huge=True)
    array = np.frombuffer(memory, dtype=float, count=n)
    weakref.finalize(array, _release, memory)     # views of it keep it (their base)
    return array
