r"""One step of a generated between-trial update: its C, its cost and its rounding bound.

A generated update (:mod:`ilc_analysis.export._plan`) is a sequence of :class:`Stage`\ s, each a
``static`` C function of the law's file, called in order by ``ilc_update``. A stage reads named
signals (``ff`` the last trial's input, ``e`` the error on the window, ``u`` the input the
trial applied, ``x`` the next input being built) and writes one; besides its C it states

* its constant arrays (flash) and its members of the work struct (RAM), sized at export;
* its operations per trial (:class:`Operations`);
* for single precision, a proven bound of its rounding (:meth:`Stage.bound`): with the
  standard model of floating-point arithmetic, :math:`\mathrm{fl}(a \circ b) = (a \circ b)
  (1 + \theta)`, :math:`|\theta| \le u` (u the unit roundoff), a value computed along a path
  of n roundings is exact up to a factor :math:`1 + \theta_n`, :math:`|\theta_n| \le
  \gamma_n = nu/(1 - nu)` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed.,
  Lemma 3.1). Bounds are on the 2-norm over the trial of each signal: :class:`Sig` holds a
  bound of the exact signal's norm (``mag``) and of the computed signal's distance to it
  (``err``).

A stage whose exact map is linear in an input of norm bound ``n`` and which adds a local
rounding of at most :math:`\eta\,\|\hat x\|` propagates

.. math::

    \mathrm{err}_{out} \le n\,\mathrm{err}_{in} + \eta\,(\mathrm{mag}_{in} + \mathrm{err}_{in}),
    \qquad \mathrm{mag}_{out} \le n\,\mathrm{mag}_{in}

(:func:`linear`), summed over its inputs.
"""

from __future__ import annotations

import abc
from collections import Counter
from dataclasses import dataclass

from ..exceptions import ParameterError
from ._c import CArray

__all__ = ["Sig", "Stage", "Operations", "WorkArray", "gamma", "linear", "UNDERFLOW"]

#: Absolute error a single-precision operation may add by underflow (gradual or flushed to
#: zero, as some microcontrollers' FPUs do): the smallest normal float, 2^-126.
UNDERFLOW = 2.0 ** -126


def gamma(n: int, u: float) -> float:
    r""":math:`\gamma_n = nu/(1 - nu)`: the relative error of a value computed along a path of
    n roundings of unit roundoff u (valid for nu < 1)."""
    if n * u >= 0.5:
        raise ParameterError(f"a path of {n} roundings at unit roundoff {u:g} has no useful "
                             f"bound (n u >= 1/2): the trial is too long for this precision")
    return n * u / (1.0 - n * u)


@dataclass(frozen=True)
class Sig:
    """Bounds of one signal of the update: 2-norms over the trial."""

    mag: float
    """bound of the exact signal's norm"""
    err: float
    """bound of the norm of (computed - exact)"""


def linear(*terms: tuple[Sig, float, float], extra: float = 0.0, mag_extra: float = 0.0) -> Sig:
    r"""The output of a stage linear in its inputs (module docstring): each term ``(sig, n,
    eta)`` an input with the norm bound n of the exact map from it and the local rounding
    coefficient η; ``extra`` a local rounding of constants, ``mag_extra`` the exact output's
    part from constants."""
    err = extra + sum(n * s.err + eta * (s.mag + s.err) for s, n, eta in terms)
    mag = mag_extra + sum(n * s.mag for s, n, _ in terms)
    return Sig(mag, err)


@dataclass(frozen=True)
class WorkArray:
    """A member ``ilc_real name[length]`` of the work struct ``ilc_work_t``."""

    name: str
    length: int
    comment: str


class Operations(Counter):
    """Floating-point operations per trial by kind: ``add`` (additions and subtractions),
    ``mul``, ``div``, ``exp`` (calls of libm's exp) and ``minmax`` (fabs, fmin, fmax)."""

    KINDS = ("add", "mul", "div", "exp", "minmax")

    def as_dict(self) -> dict:
        return {k: int(self.get(k, 0)) for k in self.KINDS} | {"total": int(self.total())}


class Stage(abc.ABC):
    """One step of the generated update (module docstring)."""

    #: C function name (``static``, unique in the file)
    function_name: str
    #: the signals the stage reads, and the one it writes
    inputs: tuple[str, ...]
    output: str

    def constants(self) -> list[CArray]:
        """The stage's constant arrays (in flash)."""
        return []

    def work(self) -> list[WorkArray]:
        """The stage's members of the work struct (in RAM)."""
        return []

    def macros(self, precision: str) -> dict[str, str]:
        """The stage's private macros of the law's C file (name -> C text)."""
        return {}

    @abc.abstractmethod
    def function(self) -> str:
        """The stage's ``static`` C function."""

    @abc.abstractmethod
    def call(self) -> str:
        """The statement of ``ilc_update`` that runs the stage (one line)."""

    @abc.abstractmethod
    def operations(self) -> Operations:
        """Its operations per trial."""

    @abc.abstractmethod
    def bound(self, sigs: dict[str, Sig], u: float) -> Sig:
        """Bounds of the output signal from those of the inputs, at unit roundoff u."""

    def description(self) -> str:
        """One line for the generated file's comment."""
        return (self.__doc__ or self.function_name).strip().splitlines()[0]
