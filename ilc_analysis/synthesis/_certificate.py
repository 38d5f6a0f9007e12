r"""The certificate of a synthesis, as a typed, frozen record.

Every number a synthesis certificate states (:mod:`.certify`: recomputed from the returned
gains by the analysis stage) is a field of :class:`Certificate`. A certificate states only
some of them (a paper-level one has ``gamma1``, a lifted one ``norm_2_per_plant``, a
frequency-domain one ``peak_omega``); the others are None. :meth:`Certificate.as_dict` gives
the plain data a gains or design file stores — exactly the keys the certificate states, in
the order it states them (the file format is fixed: old files keep loading) — and
:meth:`Certificate.from_dict` reads it back; an unknown key is refused, naming it. A design's
own certificate (:meth:`ilc_analysis.design.Design.certify`) reads the same way.

The verdict rule (:attr:`Certificate.holds`): the re-checked ``verdict`` is ``holds``, i.e.
:func:`~ilc_analysis.analysis._verdicts.threshold_verdict` of the value against
:math:`\min(\text{target}, 1)` with a margin larger than rounding.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..exceptions import ParameterError

__all__ = ["Certificate"]


@dataclass(frozen=True)
class Certificate:
    """What a synthesis certificate states (module docstring); None: not stated."""

    quantity: str | None = None
    """the certified quantity: ``'norm_2'``, ``'frequency_peak'``, ``'tight_contraction'`` or
    ``'gamma1_gamma2'``"""
    value: float | None = None
    """its value, recomputed from the gains (None when no gains were found)"""
    target: float | None = None
    """the bound the value must be strictly below"""
    verdict: str | None = None
    """``holds`` / ``marginal`` / ``fails`` / ``unknown`` / ``not applicable``"""
    holds: bool | None = None
    """``verdict == 'holds'``"""
    # -- paper level (certify_paper)
    gamma1: float | None = None
    gamma2: float | None = None
    gamma1_gamma2: float | None = None
    tight_contraction: float | None = None
    vertices: int | None = None
    """number of coupling matrices H (robust paper-level synthesis)"""
    relative_degree: list | None = None
    """per output, the relative degree the coupling H uses"""
    # -- per-sample forgetting box (a variable forgetting factor)
    forgetting_box_upper: float | None = None
    forgetting_box_lower: float | None = None
    forgetting_box_norm_inf: float | None = None
    forgetting_box_witness: list | None = None
    forgetting_covers: str | None = None
    """what of the forgetting factor the numbers cover"""
    # -- lifted (certify_lifted)
    spectral_radius: float | None = None
    norm_inf: float | None = None
    transient_peak: float | None = None
    peak_settled: bool | None = None
    iterations_to_reduce: int | None = None
    claimed: float | None = None
    """the solver's own value, which the recomputation reproduced"""
    norm_2_per_plant: list | None = None
    plants: int | None = None
    forgetting_values: list | None = None
    """the constant forgetting factors the numbers are computed at"""
    monotone_in: str | None = None
    notes: list | None = None
    lower_bound: float | None = None
    """no gain of the structure beats it (dual bound; 0 when none is available)"""
    best_value: float | None = None
    # -- frequency domain (certify_frequency, certify_frequency_on_trial)
    frequency_verdict: str | None = None
    frequency_reason: str | None = None
    every_trial_length: bool | None = None
    peak_omega: float | None = None
    closed_loop_stable: bool | None = None
    grid_points: int | None = None
    on_synthesis_grid: float | None = None
    grid_excess: float | None = None
    trial_length: int | None = None
    lifted_check_length: int | None = None
    lifted_norm_2: float | None = None
    lifted_spectral_radius: float | None = None
    lifted_verdict: str | None = None
    # -- a design's own certificate (ilc_analysis.design.Design.certify)
    norm_2: float | None = None
    """||T||_2 (when the certified quantity is another number)"""
    error_norm_2: float | None = None
    """the tracking error's ||T_e||_2"""
    operator: dict | None = None
    """what the certificate was computed on (N, shift, ts, lifting, filter, ...)"""
    stated: tuple[str, ...] = field(default=(), repr=False, compare=False)
    """the keys the certificate states, in order (set by :meth:`from_dict`; empty: the
    fields that are not None)"""

    @classmethod
    def keys_known(cls) -> tuple[str, ...]:
        """Every key a certificate may state."""
        return tuple(f.name for f in dataclasses.fields(cls) if f.name != "stated")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | Certificate) -> Certificate:
        """The certificate of plain data (:meth:`as_dict`'s, or a file's ``[certificate]``).

        Raises
        ------
        ParameterError
            For a key that is not a certificate field (named), or data that is not a mapping.
        """
        if isinstance(data, Certificate):
            return data
        if not isinstance(data, Mapping):
            raise ParameterError(f"certificate must be a mapping of its keys "
                                 f"{cls.keys_known()}; got {type(data).__name__}")
        known = set(cls.keys_known())
        unknown = [k for k in data if k not in known]
        if unknown:
            raise ParameterError(f"certificate: unknown key {unknown[0]!r}; a certificate "
                                 f"states some of {cls.keys_known()}")
        return cls(**dict(data), stated=tuple(data))

    def as_dict(self) -> dict:
        """The plain data a file stores: the stated keys, in order, values as stated."""
        keys = self.stated or tuple(k for k in self.keys_known() if getattr(self, k) is not None)
        return {k: getattr(self, k) for k in keys}

    def replace(self, **changes) -> Certificate:
        """A copy with ``changes`` (new keys are appended to the stated ones)."""
        data = self.as_dict()
        data.update(changes)
        return Certificate.from_dict(data)

    # -- transitional read-only mapping view (MIGRATION: certificate['key'] -> .key)
    def __getitem__(self, key: str):
        data = self.as_dict()
        if key not in data:
            raise KeyError(key)
        return data[key]

    def get(self, key: str, default=None):
        """``as_dict().get(key, default)`` (the dict-era read; use the fields)."""
        return self.as_dict().get(key, default)

    def __contains__(self, key: object) -> bool:
        return key in self.as_dict()

    def keys(self):
        """The stated keys (the dict-era view; ``dict(certificate)`` works through it)."""
        return self.as_dict().keys()

    def items(self):
        """The stated ``(key, value)`` pairs."""
        return self.as_dict().items()

    def __iter__(self) -> Iterator[str]:
        return iter(self.as_dict())

    def __len__(self) -> int:
        return len(self.as_dict())
