"""Deprecation helpers of the version policy (CHANGELOG.md): a renamed or removed public name
keeps working for one more minor release, with an
:class:`~ilc_analysis.exceptions.ILCDeprecationWarning` naming the replacement and the release
that removes it.

A module that renames ``old_name`` to ``new_name`` keeps the old one importable with::

    __getattr__ = deprecated_names(__name__, {"old_name": ("new_name", "0.3.0")})

and a function whose parameter is renamed calls :func:`warn_deprecated` when the old keyword is
given. The examples below run in ``make test`` (``tests/test_doctests.py``).
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Mapping

from .exceptions import ILCDeprecationWarning, ParameterError

__all__ = ["warn_deprecated", "deprecated_names"]


def warn_deprecated(old: str, new: str | None, removed_in: str, *, stacklevel: int = 3) -> None:
    """Warn that ``old`` is deprecated.

    Parameters
    ----------
    old : str
        The deprecated name, parameter or option as the user wrote it.
    new : str or None
        What to use instead (None: nothing replaces it).
    removed_in : str
        The release that removes ``old`` (one minor release after the deprecation).
    stacklevel : int, optional
        Passed to :func:`warnings.warn`; the default points at the caller of the function that
        calls this one.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warn_deprecated("gain", "gains", "0.3.0")
    >>> print(caught[0].category.__name__, caught[0].message)
    ILCDeprecationWarning gain is deprecated and will be removed in 0.3.0; use gains instead
    """
    instead = f"; use {new} instead" if new else ""
    warnings.warn(f"{old} is deprecated and will be removed in {removed_in}{instead}",
                  ILCDeprecationWarning, stacklevel=stacklevel)


def deprecated_names(module: str, renamed: Mapping[str, tuple[str, str]]
                     ) -> Callable[[str], object]:
    """A module ``__getattr__`` that still resolves renamed names, with a warning.

    Parameters
    ----------
    module : str
        The module's ``__name__``; a new name without a dot is looked up in it.
    renamed : mapping of str to (str, str)
        ``old name -> (new name, release that removes the old one)``; a new name with dots is
        an absolute ``module.attribute`` path.

    Returns
    -------
    callable
        ``__getattr__(name)`` for the module (PEP 562): the new object for an old name, after
        an :class:`~ilc_analysis.exceptions.ILCDeprecationWarning`; AttributeError otherwise.

    Raises
    ------
    ParameterError
        An entry of ``renamed`` that is not a pair of strings.

    Examples
    --------
    >>> import warnings
    >>> getattr_ = deprecated_names("ilc_analysis.exceptions",
    ...                             {"BadParameter": ("ParameterError", "0.3.0")})
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     cls = getattr_("BadParameter")
    >>> cls.__name__
    'ParameterError'
    >>> print(caught[0].message)  # doctest: +NORMALIZE_WHITESPACE
    ilc_analysis.exceptions.BadParameter is deprecated and will be removed in 0.3.0;
    use ilc_analysis.exceptions.ParameterError instead
    >>> getattr_("Missing")
    Traceback (most recent call last):
    ...
    AttributeError: module 'ilc_analysis.exceptions' has no attribute 'Missing'
    """
    table = dict(renamed)
    for old, entry in table.items():
        if not (isinstance(entry, tuple) and len(entry) == 2
                and all(isinstance(x, str) for x in entry)):
            raise ParameterError(f"renamed[{old!r}] must be a pair (new name, removed in); "
                                 f"got {entry!r}")

    def __getattr__(name: str) -> object:
        if name not in table:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new, removed_in = table[name]
        where, _, attribute = (new if "." in new else f"{module}.{new}").rpartition(".")
        warn_deprecated(f"{module}.{name}", f"{where}.{attribute}", removed_in)
        return getattr(importlib.import_module(where), attribute)

    return __getattr__
