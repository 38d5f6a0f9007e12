r"""The deploy stage: a certified design as self-contained C for the machine's processor.

::

    Design (certified) --check--> update plan (stages of the law) --> ilc_law.h / ilc_law.c
                                        |                              (+ CasADi's code of a
                                        +--> rounding bound (single)    variable forgetting
                                        +--> footprint (RAM, flash,     factor, ilc_host.c)
                                             operations per trial)

:func:`export` writes a design's law as C99 (no dynamic allocation, no library beyond libm,
fixed sizes, no recursion, ``const`` inputs, one header, deterministic time per call): the
between-trial update ``ilc_update`` (the next trial's input from the last one and its
measured record, in the index convention of ``ilc-analysis learn``), the in-trial step
``ilc_step`` of a law with a current-trial part, the state between runs of a law that has one,
and a host driver ``ilc_host`` that reads and writes ``learn``'s CSV files, so that the code
is run beside ``learn`` on a PC before it is flashed. The header names the design's
fingerprint and the claim of the certificate it carries (re-verified at export).

In double precision the code is the toolkit's own arithmetic; in single precision it comes
with a proven bound of the error floor its rounding adds (:class:`RoundingBound`), and is
refused where the certificate's margin cannot absorb it. Refusals are
:class:`~ilc_analysis.exceptions.ExportRefusedError` (exit 2 on the command line), with the
reason.

Stage: after :mod:`ilc_analysis.design`, beside :mod:`ilc_analysis.studies`; only the command
line imports it.
"""

from ._export import ExportResult, export
from ._footprint import Footprint, ObjectSize
from ._plan import EXPORTED_KINDS, REFUSED_KINDS
from ._rounding import RoundingBound

__all__ = ["export", "ExportResult", "Footprint", "ObjectSize", "RoundingBound",
           "EXPORTED_KINDS", "REFUSED_KINDS"]
