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
import importlib.abc
import importlib.util
import warnings
from collections.abc import Callable, Mapping

from .exceptions import ILCDeprecationWarning, ParameterError

__all__ = ["warn_deprecated", "deprecated_names", "MovedModules", "REMOVED_IN"]

#: the release that removes what this one deprecates (one minor release later)
REMOVED_IN = "0.3.0"


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


def deprecated_names(module: str, renamed: Mapping[str, tuple[str, ...]]
                     ) -> Callable[[str], object]:
    """A module ``__getattr__`` that still resolves renamed names, with a warning.

    Parameters
    ----------
    module : str
        The module's ``__name__``; a new name without a dot is looked up in it.
    renamed : mapping of str to (str, str) or (str, str, str)
        ``old name -> (new name, release that removes the old one)``; a new name with dots is
        an absolute ``module.attribute`` path. A name that is no longer public (its path has a
        private component) is deprecated without a replacement, unless a third entry says
        what to use instead.

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
        if not (isinstance(entry, tuple) and len(entry) in (2, 3)
                and all(isinstance(x, str) for x in entry)):
            raise ParameterError(f"renamed[{old!r}] must be a pair (new name, removed in) or a "
                                 f"triple (where it is, removed in, what to use instead); "
                                 f"got {entry!r}")

    def __getattr__(name: str) -> object:
        if name not in table:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new, removed_in, *instead = table[name]  # instead: list[str]
        where, _, attribute = (new if "." in new else f"{module}.{new}").rpartition(".")
        target = f"{where}.{attribute}"
        private = any(part.startswith("_") for part in target.split("."))
        warn_deprecated(f"{module}.{name}", instead[0] if instead else None if private
                        else target, removed_in)
        return getattr(importlib.import_module(where), attribute)

    return __getattr__


class MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Import hook that keeps moved or renamed modules importable under their old paths.

    ``import old.path`` (or ``from old.path import name``) finds the module at its new path,
    warns :class:`~ilc_analysis.exceptions.ILCDeprecationWarning` naming the new path and the
    release that removes the old one, and binds the old name to the *same* module object (no
    second copy: ``isinstance`` checks and module state are shared).

    Parameters
    ----------
    moved : mapping of str to str
        ``old dotted module path -> new dotted module path``.
    removed_in : str
        The release that removes the old paths.

    Examples
    --------
    >>> import sys, warnings
    >>> hook = MovedModules({"ilc_analysis.old_errors": "ilc_analysis.exceptions"}, "0.3.0")
    >>> sys.meta_path.append(hook)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     import ilc_analysis.old_errors as errors
    >>> errors is sys.modules["ilc_analysis.exceptions"]
    True
    >>> print(caught[0].message)  # doctest: +NORMALIZE_WHITESPACE
    ilc_analysis.old_errors is deprecated and will be removed in 0.3.0;
    use ilc_analysis.exceptions instead
    >>> sys.meta_path.remove(hook); del sys.modules["ilc_analysis.old_errors"]
    """

    def __init__(self, moved: Mapping[str, str], removed_in: str) -> None:
        self.moved = dict(moved)
        self.removed_in = removed_in
        self._specs: dict[str, object] = {}

    def find_spec(self, fullname, path=None, target=None):
        """The spec of an old path (importlib's finder protocol); None for any other name."""
        if fullname not in self.moved:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        """Warn, and return the module at its new path (importlib's loader protocol)."""
        new = self.moved[spec.name]
        warnings.warn(f"{spec.name} is deprecated and will be removed in {self.removed_in}; "
                      f"use {new} instead", ILCDeprecationWarning,
                      stacklevel=2)  # warnings skips importlib's own frames
        module = importlib.import_module(new)
        self._specs[new] = module.__spec__
        return module

    def exec_module(self, module) -> None:
        """Nothing to execute (the module ran at its new path); the import machinery stamped
        the old path's spec on the module: give it back its own."""
        module.__spec__ = self._specs[module.__name__]

