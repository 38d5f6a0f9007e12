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
    """γ1 of the paper's theorem (eq 25)"""
    gamma2: float | None = None
    """γ2 of the paper's theorem (eq 25)"""
    gamma1_gamma2: float | None = None
    """the product γ1 γ2 the paper's condition bounds"""
    tight_contraction: float | None = None
    """the tight contraction bound of the theorem (the certified quantity of
    ``objective='tight'``)"""
    vertices: int | None = None
    """number of coupling matrices H (robust paper-level synthesis)"""
    relative_degree: list | None = None
    """per output, the relative degree the coupling H uses"""
    # -- per-sample forgetting box (a variable forgetting factor)
    forgetting_box_upper: float | None = None
    """a proven upper bound of ‖T‖₂ over every per-sample forgetting factor in the range"""
    forgetting_box_lower: float | None = None
    """‖T‖₂ attained at a vertex of the per-sample forgetting box (a lower bound)"""
    forgetting_box_norm_inf: float | None = None
    """the exact ‖T‖∞ over the per-sample forgetting box"""
    forgetting_box_witness: list | None = None
    """the per-sample factors (a vertex of the box) that attain ``forgetting_box_lower``"""
    forgetting_covers: str | None = None
    """what of the forgetting factor the numbers cover"""
    # -- lifted (certify_lifted)
    spectral_radius: float | None = None
    """ρ(T), the largest over the plants and forgetting values"""
    norm_inf: float | None = None
    """‖T‖∞ at the worst plant and forgetting value"""
    transient_peak: float | None = None
    """the largest ‖T^k‖₂ found"""
    peak_settled: bool | None = None
    """the transient peak is the supremum over every k (some ‖T^K‖₂ < 1 was computed)"""
    iterations_to_reduce: int | None = None
    """iterations until the input error is reduced by the default factor (None: not within
    the horizon)"""
    claimed: float | None = None
    """the solver's own value, which the recomputation reproduced"""
    norm_2_per_plant: list | None = None
    """‖T‖₂ for each plant of the robust set, in order"""
    plants: int | None = None
    """the number of plants the certificate covers"""
    uncertainty: dict | None = None
    """the plant set of a robust synthesis, as :meth:`~ilc_analysis.synthesis._robust.
    ParameterBox.as_dict` or :meth:`~ilc_analysis.synthesis._robust.
    MultiplicativeUncertainty.as_dict` give it (the re-check rebuilds the set from it)"""
    uncertainty_covers: str | None = None
    """what the certificate proves about that set (and what it does not)"""
    multiplicative_bound: float | None = None
    """a proven bound of ||T||_2 over every G(I + Delta), ||Delta|| <= w
    (:func:`~ilc_analysis.synthesis._robust.multiplicative_bound`)"""
    multiplicative_coupling: float | None = None
    """||Q L1 G||_2 of the nominal plant (the bound's slope in w)"""
    forgetting_values: list | None = None
    """the constant forgetting factors the numbers are computed at"""
    monotone_in: str | None = None
    """the quantity the certificate proves monotone (e.g. the input error to the fixed
    point)"""
    notes: list | None = None
    """plain-text remarks of the re-check"""
    engine: str | None = None
    """what judged the design at its full trial length: ``'dense'`` (the dense lifted
    operator) or ``'operator'`` (the matrix-free analysis; :mod:`.full_trial`)"""
    norm_2_lower: float | None = None
    """the operator engine: the proven lower bound of ||T||_2 (a norm it attains)"""
    norm_2_upper: float | None = None
    """the operator engine: the proven upper bound of ||T||_2 (None: none is known)"""
    lower_bound: float | None = None
    """no gain of the structure beats it (dual bound; 0 when none is available)"""
    best_value: float | None = None
    """the best value the solver found (``value`` is its recomputation)"""
    # -- frequency domain (certify_frequency, certify_frequency_on_trial)
    frequency_verdict: str | None = None
    """the verdict of the frequency-domain condition"""
    frequency_reason: str | None = None
    """why the frequency-domain verdict is what it is"""
    every_trial_length: bool | None = None
    """the frequency-domain certificate holds for every trial length (not only
    ``trial_length``)"""
    peak_omega: float | None = None
    """the frequency where the frequency-domain peak is attained"""
    closed_loop_stable: bool | None = None
    """the current-trial feedback loop is stable (required by the frequency condition)"""
    grid_points: int | None = None
    """the number of frequency grid points checked"""
    on_synthesis_grid: float | None = None
    """the peak on the synthesis grid (``value`` is on the finer check grid)"""
    grid_excess: float | None = None
    """``value`` minus ``on_synthesis_grid``: what the finer grid found above the synthesis
    grid"""
    trial_length: int | None = None
    """the trial length N the frequency certificate was re-checked on (None: none)"""
    lifted_check_length: int | None = None
    """N of the lifted re-check of a frequency certificate"""
    lifted_norm_2: float | None = None
    """‖T‖₂ of the lifted re-check on ``lifted_check_length`` samples"""
    lifted_spectral_radius: float | None = None
    """ρ(T) of the lifted re-check"""
    lifted_verdict: str | None = None
    """the verdict of the lifted re-check"""
    # -- a design's own certificate (ilc_analysis.design.Design.certify)
    norm_2: float | None = None
    """||T||_2 (when the certified quantity is another number)"""
    error_norm_2: float | None = None
    """the tracking error's ||T_e||_2"""
    operator: dict | None = None
    """what the certificate was computed on (N, shift, ts, lifting, filter, ...)"""
    lower: float | None = None
    """the proven lower bound of the certified quantity (None: none; a ``fails`` verdict rests
    on it)"""
    upper: float | None = None
    """the proven upper bound of the certified quantity (None: none; a ``holds`` verdict rests
    on it)"""
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

        Parameters
        ----------
        data : mapping or Certificate
            The stated keys and their values (a Certificate is returned as it is).

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
        """``as_dict().get(key, default)`` (the dict-era read; use the fields).

        Parameters
        ----------
        key : str
            A certificate key.
        default : object, optional
            Returned when the certificate does not state ``key``.
        """
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
