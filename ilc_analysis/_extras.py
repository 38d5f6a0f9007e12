"""The optional extras: libraries that serve one feature are not in the core install (issue 27).

``pyproject.toml`` declares them; a feature that needs one calls :func:`require_extra` first, so a
user without it reads which extra to install instead of a ``ModuleNotFoundError`` from deep
inside the feature:

``studies``
    Dask (``dask[distributed]``) and zarr for :mod:`ilc_analysis.studies` (``ilc-analysis
    study``).
``notebooks``
    JupyterLab and the kernel for the notebooks (``make notebooks``); nothing in the package
    imports them.
"""

from __future__ import annotations

import importlib

from .exceptions import MissingExtraError

__all__ = ["EXTRAS", "require_extra"]

#: extra -> the modules it provides that the package imports
EXTRAS: dict[str, tuple[str, ...]] = {
    "studies": ("dask", "distributed", "zarr"),
}


def require_extra(extra: str, feature: str) -> None:
    """Check that the modules of the optional ``extra`` import.

    Parameters
    ----------
    extra : str
        A key of :data:`EXTRAS`.
    feature : str
        What needs it, as the message's subject (e.g. ``'a study'``).

    Raises
    ------
    MissingExtraError
        A module of the extra does not import; the message names the missing modules and the
        install command.
    """
    missing = []
    for module in EXTRAS[extra]:
        try:
            importlib.import_module(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise MissingExtraError(
            f"{feature} needs {_listed(missing)}, which the core install leaves out: install "
            f"ilc-analysis[{extra}] (from a clone of the repository: "
            f"pip install \".[{extra}]\"; make installs every extra)")


def _listed(names: list[str]) -> str:
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
