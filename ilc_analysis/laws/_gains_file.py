"""The gains file (TOML): PD gains, forgetting, sample time and certificate, one file format.

Read by ``check``, written by synthesis and the paper pipeline; old gains files also load as a
:class:`~ilc_analysis.design.Design` without a problem (:mod:`ilc_analysis.design._file`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._toml_arrays import dumps
from .._validation import positive, read_toml_file, table
from ..exceptions import ParameterError, ShapeError
from ._forgetting import NO_FORGETTING, FixedForgetting, Forgetting, VariableForgetting
from ._gains import GAIN_NAMES as _GAIN_NAMES
from ._gains import PDGains

__all__ = ["GainsFile", "load_gains", "save_gains"]


@dataclass(frozen=True)
class GainsFile:
    """Contents of a gains file: gains, forgetting, sample time and optional certificate."""

    gains: PDGains
    """the learning gains of eq (11)"""
    forgetting: Forgetting = NO_FORGETTING
    """the forgetting factor of eq (12) (fixed or variable)"""
    ts: float | None = None
    """sample time [s] the gains were designed for (None: not recorded)"""
    certificate: dict = field(default_factory=dict)
    """the numbers that certified the gains (``[certificate]`` table)"""
    meta: dict = field(default_factory=dict)
    """free-form provenance (``[meta]`` table)"""


_TOP_KEYS = {*_GAIN_NAMES, "lead", "ts", "forgetting", "certificate", "meta"}


def _forgetting_from(value, source: str) -> Forgetting:
    forgetting = table(value, "forgetting", source)
    keys = set(forgetting)
    if keys <= {"a"} and keys:
        return FixedForgetting(forgetting["a"])
    if keys and keys <= {"delta", "Lambda", "base"} and {"delta", "Lambda"} <= keys:
        return VariableForgetting(**forgetting)
    raise ParameterError(f"{source}: [forgetting] must hold either 'a' (fixed) or 'delta' and "
                         f"'Lambda' (variable, optional 'base'); found keys {sorted(keys)}")


def load_gains(path: str | Path) -> GainsFile:
    """Read a gains TOML file.

    Format: matrices ``Phi1``, ``Phi2``, ``Psi1``, ``Psi2`` as nested arrays of numbers
    (inputs x outputs, or samples x inputs x outputs), optional ``lead`` (samples, an integer)
    and ``ts`` (s), a ``[forgetting]`` table with ``a`` or ``delta`` and ``Lambda``, optional
    ``[certificate]`` and ``[meta]`` tables. Unknown keys are errors; booleans, strings and
    non-finite numbers where numbers are expected are errors.

    Parameters
    ----------
    path : str or pathlib.Path
        The gains file.

    Returns
    -------
    GainsFile
        Its gains, forgetting factor, sample time, certificate and metadata.

    Raises
    ------
    ParameterError
        The file is missing, not a regular file (a directory, a FIFO: refused before it is
        opened), too large, not UTF-8, not TOML, nested too deeply
        (:func:`~ilc_analysis._validation.read_toml_file`), or a key is unknown, missing or of
        the wrong form; the message names the file and the key.
    ShapeError
        Gain matrices of different or wrong shapes (ragged nested arrays included).
    """
    source = f"gains file {str(path)!r}"
    data = read_toml_file(path, "gains file")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise ParameterError(f"{source}: unknown key(s) {unknown}; "
                             f"allowed: {sorted(_TOP_KEYS)}")
    missing = [n for n in _GAIN_NAMES if n not in data]
    if missing:
        raise ParameterError(f"{source}: missing gain matrix/matrices {missing}")
    try:
        gains = PDGains(data["Phi1"], data["Phi2"], data["Psi1"], data["Psi2"],
                        lead=data.get("lead", 0))
        forgetting = _forgetting_from(data["forgetting"], source) if "forgetting" in data \
            else NO_FORGETTING
        ts = positive(data["ts"], "ts") if "ts" in data else None
    except (ParameterError, ShapeError) as exc:
        message = str(exc)
        raise type(exc)(message if message.startswith(source) else f"{source}: {message}") \
            from exc
    certificate = dict(table(data.get("certificate", {}), "certificate", source))
    meta = dict(table(data.get("meta", {}), "meta", source))
    return GainsFile(gains=gains, forgetting=forgetting, ts=ts, certificate=certificate,
                     meta=meta)


def save_gains(path: str | Path, gains: PDGains, forgetting: Forgetting = NO_FORGETTING, *,
               ts: float | None = None, certificate: dict | None = None,
               meta: dict | None = None) -> Path:
    """Write a gains TOML file readable by :func:`load_gains`.

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write.
    gains : PDGains
        The learning gains.
    forgetting : FixedForgetting or VariableForgetting, optional
        The forgetting factor (default: none, a = 1).
    ts : float, optional
        Sample time [s] the gains were designed for.
    certificate : dict, optional
        The numbers that certified the gains (written as ``[certificate]``).
    meta : dict, optional
        Free-form provenance (written as ``[meta]``).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    doc: dict = gains.as_dict()
    if ts is not None:
        doc["ts"] = positive(ts, "ts")
    doc["forgetting"] = forgetting.as_dict()
    if certificate:
        doc["certificate"] = _plain(certificate)
    if meta:
        doc["meta"] = _plain(meta)
    path = Path(path)
    path.write_text(dumps(doc))
    return path


def _plain(obj):
    """Convert numpy scalars/arrays in nested dicts to TOML-serialisable Python values."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
