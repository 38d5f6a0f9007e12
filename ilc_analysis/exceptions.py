"""Exceptions of ilc-analysis.

Every exception subclasses a built-in, so users may catch ``ValueError`` (bad input)
or the package's own class. Messages name the parameter, the expected form and what was found.
"""

from __future__ import annotations

__all__ = [
    "ILCError",
    "ParameterError",
    "ShapeError",
    "DesignFileError",
    "DivergenceError",
    "UnstableLoopError",
    "SolverError",
    "CertificateError",
    "ExportRefusedError",
    "InternalError",
    "MissingExtraError",
    "ILCWarning",
    "DegenerateConditionWarning",
    "TransientGrowthWarning",
    "SolverInaccurateWarning",
    "ILCDeprecationWarning",
]


class ILCError(Exception):
    """Base class of all ilc-analysis errors."""


class ParameterError(ILCError, ValueError):
    """A parameter has an invalid value (non-finite, out of range, unknown name)."""


class ShapeError(ILCError, ValueError):
    """An array has the wrong shape; the message gives the expected and the found shape."""


class DesignFileError(ParameterError):
    """A design file (or a law/plant description in one) is invalid: the message names the key
    path (e.g. ``[law].beta``), the expected form and what was found."""


class DivergenceError(ILCError, RuntimeError):
    """A simulation left its admissible region (raised only when the caller asks for it)."""


class UnstableLoopError(ILCError, RuntimeError):
    """The feedback loop a problem learns on is unstable (a closed-loop eigenvalue outside the
    unit circle): a negative result about the user's controller, not a numerical failure. The
    message gives the eigenvalue; the command line exits 1."""


class SolverError(ILCError, RuntimeError):
    """A numerical solver crashed; carries the solver's status and message.

    Parameters
    ----------
    message : str
        What failed, naming the solver and the problem.
    status : str, optional
        The solver's own status string (kept as the attribute ``status``).
    """

    def __init__(self, message: str, status: str | None = None):
        super().__init__(message)
        self.status = status


class CertificateError(ILCError, RuntimeError):
    """A synthesised certificate failed its independent re-check."""


class ExportRefusedError(ParameterError):
    """A design cannot be exported as C for a machine (:func:`ilc_analysis.export.export`):
    its law has no self-contained C, it holds no certificate that holds, the single-precision
    rounding is not absorbed by its certificate's margin, or the update does not fit a RAM
    budget. The command line exits 2.

    Parameters
    ----------
    subject : str
        What cannot be exported (e.g. ``"the constrained-norm-optimal law"``).
    reason : str
        Why, and what to do instead (kept as the attribute ``reason``).
    """

    def __init__(self, subject: str, reason: str):
        super().__init__(f"cannot export {subject}: {reason}")
        self.subject = subject
        self.reason = reason


class InternalError(ILCError, RuntimeError):
    """An invariant of the toolkit itself does not hold (a bug, not bad input: please report
    it with the call that raised it)."""


class MissingExtraError(ILCError, ImportError):
    """A feature needs an optional part of the toolkit that is not installed (an extra, e.g.
    ``ilc-analysis[studies]`` for Dask and zarr); the message names the extra to install. The
    command line exits 2."""


class ILCWarning(UserWarning):
    """Base class of all ilc-analysis warnings."""


class DegenerateConditionWarning(ILCWarning):
    """A convergence condition is degenerate (e.g. CB = 0 makes the D-type terms vanish)."""


class TransientGrowthWarning(ILCWarning):
    """Asymptotic convergence holds but the error can grow by a large factor first."""


class SolverInaccurateWarning(ILCWarning):
    """The solver returned an inaccurate solution."""


class ILCDeprecationWarning(ILCWarning, FutureWarning):
    """A deprecated name, parameter or option was used: it still works for one more minor
    release (the message names the replacement and the release that removes it; see the
    version policy in CHANGELOG.md). A ``FutureWarning``, so that it is shown to users."""
