r"""The first-order recursion of a Schur mode, compiled.

A mode of a linear trial (:mod:`~ilc_analysis.simulation._linear_trial`) obeys, over a stretch
of L samples,

.. math::

    \zeta(k+1) = t\,\zeta(k) + d(k),\qquad k = 0, \dots, L-2,

with :math:`t` the mode's eigenvalue (real, or complex in a complex Schur basis) and the drive
:math:`d` known before the stretch starts. This module solves it in place in a strided column
of the array that keeps the states, by three loops of C: the drive already in the column
(:meth:`FirstOrderKernel.solve`, real or complex), or the drive :math:`d(k) = w\,v(k)` read from
an input column and written with the solution in one pass (:meth:`FirstOrderKernel.driven`).
In the same pass each loop keeps the largest magnitude of what it wrote and read and a sum
that only a NaN or an infinity makes non-finite: the trial's screen
(:mod:`~ilc_analysis.simulation._engine`) takes its bounds from them instead of reading the
states and the input again.

Each sample is one multiplication and one addition in the order the recursion is written (the
library is built with ``-ffp-contract=off``: no fused multiply-add), the roundings of the
recursion stepped sample by sample in IEEE double arithmetic. The BLAS banded triangular solve the
linear trial uses without a compiler (``?tbsv``) computes the same recursion but calls a
vector kernel per sample: about 56 µs for 20 000 samples on the development machine, against
about 31 µs here, and the fused drive saves the separate pass that writes it.

The library is built once by the C compiler of the compiled trials
(:func:`~ilc_analysis.simulation._trial.c_compiler`) and kept on disk with them
(:func:`~ilc_analysis.simulation._trial.build_shared_library`); it is loaded with
:mod:`ctypes`. Every call checks that the column it writes lies inside the array.
"""

from __future__ import annotations

import ctypes
import functools

import numpy as np

from ..exceptions import ParameterError, ShapeError
from ._trial import _state_once, build_shared_library, c_compiler

__all__ = ["FirstOrderKernel", "first_order_kernel"]

#: the kernel's C source (its hash names the library on disk)
SOURCE = r"""
/* ilc-analysis: first-order recursions in place (simulation/_first_order.py) */
#include <stddef.h>
#include <math.h>

/* Each function also writes peaks[0] = the largest |z_k| (|re| + |im| for a complex z), k < n,
   peaks[1] = the largest |v_k| it read (0 if it read none), and peaks[2] = the sum of every
   value it read and of the last z: a NaN or an infinity anywhere makes peaks[0] or peaks[2]
   non-finite (a NaN drive makes the sum NaN; an infinite z is its own peak; a NaN z follows
   an infinite one or a NaN drive). */

/* z[k inc] <- t z[(k-1) inc] + z[k inc], k = 1 .. n-1 */
void ilc_first_order_real(double *z, ptrdiff_t n, ptrdiff_t inc, double t, double *peaks)
{
    double prev = z[0], peak = fabs(prev), sum = 0.0;
    for (ptrdiff_t k = 1; k < n; ++k) {
        double *p = z + k * inc;
        double d = *p;
        sum += d;
        prev = t * prev + d;
        *p = prev;
        double a = fabs(prev);
        peak = a > peak ? a : peak;
    }
    peaks[0] = peak;
    peaks[1] = 0.0;
    peaks[2] = sum + prev;
}

/* the same on complex numbers stored as (re, im) pairs; inc counts complex numbers */
void ilc_first_order_complex(double *z, ptrdiff_t n, ptrdiff_t inc, double tr, double ti,
                             double *peaks)
{
    double pr = z[0], pi = z[1], peak = fabs(pr) + fabs(pi), sum = 0.0;
    for (ptrdiff_t k = 1; k < n; ++k) {
        double *p = z + 2 * k * inc;
        sum += p[0] + p[1];
        double re = (tr * pr - ti * pi) + p[0];
        double im = (tr * pi + ti * pr) + p[1];
        p[0] = re;
        p[1] = im;
        pr = re;
        pi = im;
        double a = fabs(re) + fabs(im);
        peak = a > peak ? a : peak;
    }
    peaks[0] = peak;
    peaks[1] = 0.0;
    peaks[2] = sum + (pr + pi);
}

/* z[k inc] <- t z[(k-1) inc] + w v[(k-1) vinc], k = 1 .. n-1 */
void ilc_first_order_driven(double *z, ptrdiff_t n, ptrdiff_t inc, double t,
                            const double *v, ptrdiff_t vinc, double w, double *peaks)
{
    double prev = z[0], peak = fabs(prev), vpeak = 0.0, sum = 0.0;
    for (ptrdiff_t k = 1; k < n; ++k) {
        double d = v[(k - 1) * vinc];
        double ad = fabs(d);
        vpeak = ad > vpeak ? ad : vpeak;
        sum += d;
        prev = t * prev + w * d;
        z[k * inc] = prev;
        double a = fabs(prev);
        peak = a > peak ? a : peak;
    }
    peaks[0] = peak;
    peaks[1] = vpeak;
    peaks[2] = sum + prev;
}
"""

#: build flags of the kernel: no contraction into fused multiply-adds (module docstring)
FLAGS = ("-O2", "-shared", "-fPIC", "-ffp-contract=off")

_SIZE = ctypes.c_ssize_t
_POINTER = ctypes.c_void_p
_DOUBLE = ctypes.c_double


def _pointer(a: np.ndarray, byte_offset: int):
    """A pointer argument to the byte ``byte_offset`` of the array ``a``: for a writeable
    C-contiguous array a ctypes view of its buffer, about a quarter of the cost of
    ``a.ctypes.data`` (a trial passes three per mode); for any other array (read-only,
    strided, empty) its address."""
    if a.size and a.flags.c_contiguous and a.flags.writeable:
        # an ndarray exports the buffer protocol (numpy's type stubs do not declare it)
        return ctypes.byref(_DOUBLE.from_buffer(a), byte_offset)  # type: ignore[arg-type]
    return a.ctypes.data + byte_offset


class FirstOrderKernel:
    """The compiled recursions of the module docstring, on numpy arrays.

    Parameters
    ----------
    library : ctypes.CDLL
        The loaded library built from :data:`SOURCE`.
    """

    def __init__(self, library: ctypes.CDLL) -> None:
        self._real = library.ilc_first_order_real
        self._real.argtypes = [_POINTER, _SIZE, _SIZE, _DOUBLE, _POINTER]
        self._complex = library.ilc_first_order_complex
        self._complex.argtypes = [_POINTER, _SIZE, _SIZE, _DOUBLE, _DOUBLE, _POINTER]
        self._driven = library.ilc_first_order_driven
        self._driven.argtypes = [_POINTER, _SIZE, _SIZE, _DOUBLE, _POINTER, _SIZE, _DOUBLE,
                                 _POINTER]
        for fn in (self._real, self._complex, self._driven):
            fn.restype = None

    @staticmethod
    def _column(flat: np.ndarray, offset: int, inc: int, length: int):
        """A pointer to element ``offset`` of the C-contiguous vector ``flat``, after checking
        that elements ``offset + k inc``, k < ``length``, lie inside it."""
        if flat.ndim != 1 or not flat.flags.c_contiguous or not flat.flags.writeable:
            raise ShapeError("the recursion's states must be a writeable contiguous vector")
        if offset < 0 or inc < 1 or length < 1 or offset + (length - 1) * inc >= flat.size:
            raise ShapeError(f"a column of {length} elements from {offset} in steps of {inc} "
                             f"does not fit a vector of {flat.size}")
        return _pointer(flat, offset * flat.itemsize)

    @staticmethod
    def _peaks(peaks: np.ndarray):
        """A pointer to ``peaks``, after checking that it holds three writeable float64."""
        if peaks.dtype != np.float64 or peaks.shape != (3,) or not peaks.flags.c_contiguous \
                or not peaks.flags.writeable:
            raise ShapeError("peaks must be a writeable contiguous float64 vector of 3")
        return _pointer(peaks, 0)

    def solve(self, flat: np.ndarray, offset: int, inc: int, length: int, t: complex,
              peaks: np.ndarray) -> None:
        r""":math:`z_k \leftarrow t z_{k-1} + z_k`, k = 1 .. ``length`` - 1, in place on
        ``z_k = flat[offset + k inc]``.

        Parameters
        ----------
        flat : ndarray of float64 or complex128, shape (size,)
            C-contiguous and writeable: the states of all modes, mode j at offset j.
        offset, inc, length : int
            The column: its first element, the step between samples, the samples.
        t : float or complex
            The mode's eigenvalue (real for a real ``flat``).
        peaks : ndarray of float64, shape (3,)
            Written: the largest :math:`|z_k|` (:math:`|\mathrm{Re}|+|\mathrm{Im}|` for a
            complex column), 0, and a sum that is finite only if every drive and the last
            :math:`z` are (the C source's comment).
        """
        address = self._column(flat, offset, inc, length)
        out = self._peaks(peaks)
        if flat.dtype == np.float64:
            if isinstance(t, complex) or np.iscomplexobj(t):
                raise ParameterError("a real column needs a real eigenvalue t")
            self._real(address, length, inc, float(t), out)
        elif flat.dtype == np.complex128:
            self._complex(address, length, inc, float(np.real(t)), float(np.imag(t)), out)
        else:
            raise ParameterError(f"the states must be float64 or complex128; got {flat.dtype}")

    def driven(self, flat: np.ndarray, offset: int, inc: int, length: int, t: float,
               v: np.ndarray, w: float, peaks: np.ndarray) -> None:
        r""":math:`z_k \leftarrow t z_{k-1} + w v_{k-1}`, k = 1 .. ``length`` - 1, in place
        on ``z_k = flat[offset + k inc]`` (``z_0`` as it is).

        Parameters
        ----------
        flat : ndarray of float64, shape (size,)
            As :meth:`solve` (real).
        offset, inc, length : int
            As :meth:`solve`.
        t, w : float
            The mode's eigenvalue and its input weight.
        v : ndarray of float64, shape (at least length - 1,)
            The input samples (any stride, not overlapping the column).
        peaks : ndarray of float64, shape (3,)
            Written: the largest :math:`|z_k|`, the largest :math:`|v_k|` read, and a sum that
            is finite only if every input read and the last :math:`z` are.
        """
        if flat.dtype != np.float64 or v.dtype != np.float64:
            raise ParameterError("the driven recursion takes float64 states and input")
        if v.ndim != 1 or v.shape[0] < length - 1 or v.strides[0] % 8:
            raise ShapeError(f"the input must be a vector of at least {length - 1} samples")
        self._driven(self._column(flat, offset, inc, length), length, inc, t, _pointer(v, 0),
                     v.strides[0] // 8, w, self._peaks(peaks))


@functools.lru_cache(maxsize=1)
def _loaded() -> FirstOrderKernel | str:
    """The kernel, built (or found on disk) and loaded once per process, or why not."""
    compiler = c_compiler()
    if compiler is None:
        return "no C compiler found ($CC, cc or gcc)"
    try:
        library = build_shared_library("ilc_first_order", SOURCE, compiler, FLAGS)
        return FirstOrderKernel(ctypes.CDLL(str(library)))
    except (ParameterError, OSError, AttributeError) as exc:
        return f"the first-order kernel could not be built or loaded: {exc}"


def first_order_kernel(use: bool | None = None) -> FirstOrderKernel | None:
    """The compiled first-order kernel (module docstring), or None.

    Parameters
    ----------
    use : bool or None, optional
        None (default): the kernel where a C compiler is found (a build that fails warns once,
        :class:`~ilc_analysis.exceptions.ILCWarning`, and the caller solves by BLAS); True:
        the kernel or an error; False: None (the caller never uses the compiler).

    Raises
    ------
    ParameterError
        ``use=True`` and no kernel can be built.
    """
    if use is False:
        return None
    loaded = _loaded()
    if isinstance(loaded, FirstOrderKernel):
        return loaded
    if use:
        raise ParameterError(f"jit=True needs the compiled first-order kernel: {loaded}")
    if not loaded.startswith("no C compiler"):
        _state_once(f"{loaded}; linear trials are solved by BLAS")
    return None
