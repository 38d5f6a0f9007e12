r""":func:`export`: a certified design as self-contained C for the machine's processor.

The certificate is re-verified first (:meth:`~ilc_analysis.design.Design.check`, on exactly
the operator it was computed on): a design without one, or whose certificate does not hold,
is refused unless ``uncertified=True``, which writes the fact into the header. The law's
update is then planned (:func:`~ilc_analysis.export._plan.update_plan`; a law without
self-contained C is refused with the reason), its single-precision rounding bounded
(:func:`~ilc_analysis.export._rounding.single_precision_bound`; refused where the
certificate's margin cannot absorb it), its RAM checked against ``ram``, the files written
(:func:`~ilc_analysis.export._sources.generate_sources`) into ``out`` (replaced as a whole
when everything is written) and the firmware objects compiled to measure the flash
(:mod:`~ilc_analysis.export._footprint`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from .._output import output_directory
from .._version import __version__
from ..exceptions import ExportRefusedError, ParameterError
from ._c import check_precision
from ._footprint import (
    Footprint,
    analytic_footprint,
    check_constants,
    check_ram,
    object_sizes,
)
from ._plan import update_plan
from ._rounding import RoundingBound, single_precision_bound
from ._sources import FIRMWARE_SOURCES, generate_sources

__all__ = ["export", "ExportResult", "MANIFEST"]

#: The machine-readable summary written beside the sources.
MANIFEST = "ilc_export.json"


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export` wrote and measured."""

    directory: Path
    """the output directory"""
    files: tuple[str, ...]
    """the files written (sources, header, manifest)"""
    precision: str
    """``'double'`` or ``'single'``"""
    kind: str
    """the law kind"""
    fingerprint: str
    """the design's fingerprint (learn's state file carries the same)"""
    certified: bool
    """the certificate was re-verified and holds"""
    certificate: str
    """the certificate's claim (or why there is none)"""
    footprint: Footprint
    """RAM, flash and operations per trial"""
    rounding: RoundingBound | None = None
    """the proven floor single precision adds (None in double)"""
    notes: tuple[str, ...] = field(default_factory=tuple)
    """what the generated update computes"""

    def as_dict(self) -> dict:
        return {"directory": str(self.directory), "files": list(self.files),
                "precision": self.precision, "law_kind": self.kind,
                "fingerprint": self.fingerprint, "certified": self.certified,
                "certificate": self.certificate, "footprint": self.footprint.as_dict(),
                "rounding": None if self.rounding is None else self.rounding.as_dict(),
                "notes": list(self.notes)}

    def summary(self) -> str:
        lines = [f"wrote {self.directory}: {', '.join(self.files)} ({self.kind} law, "
                 f"{self.precision} precision)",
                 f"certificate: {self.certificate}",
                 f"fingerprint: {self.fingerprint}",
                 f"footprint: {self.footprint.summary()}"]
        if self.rounding is not None:
            lines.append(self.rounding.summary())
        lines.append(f"build the host driver: cd {self.directory} && cc -std=c99 -O2 *.c -lm "
                     f"-o ilc_host")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def _gate(design, uncertified: bool, allow_code: bool):
    """``(check, certificate text, certified)``: the certificate re-verified, or refused."""
    from ..design._design import certificate_text

    cert = design.certificate
    if not cert:
        if not uncertified:
            raise ExportRefusedError(
                "this design", "it holds no certificate: certify it first (Design.certify, or "
                "'ilc-analysis synthesize' writes one) so the code on the machine names what "
                "was proven, or pass uncertified=True (--uncertified), which writes the fact "
                "into the generated header")
        return None, "UNCERTIFIED: the design holds no certificate", False
    try:
        check = design.check(analysis=False, allow_code=allow_code)
    except ParameterError as exc:
        if not uncertified:
            raise ExportRefusedError("this design", f"its certificate cannot be re-verified: "
                                                    f"{exc}") from exc
        return None, f"UNCERTIFIED: the certificate cannot be re-verified ({exc})", False
    if not check.holds:
        why = check.summary().splitlines()[0]
        if not uncertified:
            raise ExportRefusedError(
                "this design", f"its certificate does not hold on its own operator ({why}); "
                f"pass uncertified=True (--uncertified) to export it anyway with that fact in "
                f"the header")
        return check, f"UNCERTIFIED: the certificate does not hold ({why})", False
    return check, (certificate_text(cert) + " -- re-verified at export (Design.check): holds"), \
        True


def _info(design, kind: str, fingerprint: str, certificate: str, check, precision: str,
          rounding: RoundingBound | None, notes: list[str]) -> dict:
    p, law = design.problem, design.law
    source = design.sources.get("path") if isinstance(design.sources, dict) else None
    lines = [f"Design:      {source or '(built in Python)'}: problem {p.name!r}, law "
             f"{law.name!r} (kind {kind})",
             f"Trial:       N = {p.N} samples of ts = {p.ts:g} s, shift s = {p.shift}; input "
             f"{p.n_u} ({', '.join(p.input_names)}) at t0 + k ts, k = 0..N-1;",
             f"             record {p.n_y} ({', '.join(p.output_names)}) at t0 + k ts, "
             f"k = 0..N+s-1; the reference is y_d(k) for y(k + s)",
             f"Certificate: {certificate}"]
    if check is not None:
        op = check.operator
        lines.append("Operator:    " + ", ".join(f"{k} = {op[k]}" for k in
                                                  ("N", "shift", "ts", "lifting", "filter",
                                                   "forgetting") if k in op))
        lines.append(f"             {op.get('law', '')}")
    lines.append(f"Fingerprint: {fingerprint} (the design's; `ilc-analysis learn`'s state file "
                 f"carries the same)")
    if precision == "double":
        lines.append("Precision:   double, the toolkit's own arithmetic: agrees with "
                     "`ilc-analysis learn` to rounding (the order of sums)")
    elif rounding is not None:
        lines += ["Precision:   single (IEEE 754 binary32, round to nearest; libm's double exp "
                  "within a few ulps), with a proof:",
                  *[f"             {t}" for t in _wrap(rounding.summary(), 80)]]
    lines += [f"Update:      {n}" for n in notes]
    return {"title": f"the law of {Path(source).name if source else 'a design'} as C99 "
                     f"(ilc-analysis {__version__} export)",
            "lines": lines, "fingerprint": fingerprint}


def _wrap(text: str, width: int) -> list[str]:
    out, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            out.append(line)
            line = word
        else:
            line = f"{line} {word}".strip()
    return out + ([line] if line else [])


def export(design, out, *, precision: str = "double", ram: int | None = None,
           uncertified: bool = False, allow_code: bool = False,
           measure: bool = True) -> ExportResult:
    r"""Write the design's certified law as self-contained C99 into the directory ``out``.

    The files (:mod:`ilc_analysis.export._sources`): ``ilc_law.h`` (the one header: sizes,
    the work, state and step structs, the functions; its comment names the design, its
    fingerprint and the certificate's claim), ``ilc_law.c`` (the between-trial update
    ``ilc_update``, the in-trial step ``ilc_step`` of a law with a current-trial part, the
    first input), the CasADi code of a variable forgetting factor, the host driver
    ``ilc_host.c`` and ``ilc_export.json`` (this result). ``cc -std=c99 -O2 *.c -lm -o
    ilc_host`` in ``out`` builds the driver.

    Parameters
    ----------
    design : Design
        A design with a problem (:func:`~ilc_analysis.design.load_design`).
    out : str or path-like
        The output directory (created, or replaced as a whole when everything is written).
    precision : {'double', 'single'}
        The arithmetic of the generated code. Single precision comes with a proven bound of
        the error floor its rounding adds (:func:`~ilc_analysis.export._rounding.
        single_precision_bound`), and is refused where the certificate's margin cannot
        absorb it.
    ram : int, optional
        A RAM budget in bytes: the export is refused when the update needs more
        (:attr:`Footprint.ram_bytes`).
    uncertified : bool
        Export a design without a certificate, or whose certificate does not hold, stating
        it in the header (never in single precision: its bound rests on the certificate).
    allow_code : bool
        Let the certificate's re-check import a module plant a robust certificate names
        (as :meth:`~ilc_analysis.design.Design.check`).
    measure : bool
        Compile the firmware sources with the system C compiler to measure the flash
        (default); False: constants counted, code not measured.

    Returns
    -------
    ExportResult

    Raises
    ------
    ExportRefusedError
        No certificate that holds (without ``uncertified``), a law without self-contained C,
        single precision the certificate's margin cannot absorb, or a RAM budget exceeded;
        the message says why and what to do.
    ParameterError
        Not a design with a problem, an unknown precision, a bad ``ram`` or ``out``.
    """
    from ..design import Design
    from ..simulation import Learner

    if not isinstance(design, Design):
        raise ParameterError(f"design must be a Design (ilc_analysis.design.load_design); got "
                             f"{type(design).__name__}")
    if design.problem is None:
        raise ParameterError("this design names no problem (an old gains file): attach one "
                             "with Design.with_problem(problem) before exporting it")
    precision = check_precision(precision)
    if ram is not None and (isinstance(ram, bool) or not isinstance(ram, int) or ram <= 0):
        raise ParameterError(f"ram must be a positive number of bytes; got {ram!r}")
    problem, law = design.problem, design.law
    if precision == "single" and uncertified and not design.certificate:
        raise ExportRefusedError("in single precision", "the rounding bound rests on the "
                                 "certificate's contraction and this design has none")
    check, certificate, certified = _gate(design, uncertified, allow_code)
    plan = update_plan(problem, law, precision)
    footprint = analytic_footprint(plan, problem, precision)
    check_constants(footprint, plan)
    check_ram(footprint, ram)
    rounding = None
    if precision == "single":
        if not certified or design.certificate is None:
            raise ExportRefusedError("in single precision", "the rounding bound rests on the "
                                     "certificate's contraction and this design's certificate "
                                     "does not hold")
        rounding = single_precision_bound(problem, law, plan, check, design.certificate)
    fingerprint = Learner(problem, law).fingerprint
    info = _info(design, plan.kind, fingerprint, certificate, check, precision, rounding,
                 plan.notes)
    files = generate_sources(plan, problem, precision, info)
    with output_directory(out, "--out", command="ilc-analysis export") as tmp:
        for name, text in files.items():
            (tmp / name).write_text(text, encoding="utf-8")
        if measure:
            firmware = [f for f in FIRMWARE_SOURCES if f in files]
            objects, compiler, note = object_sizes(tmp, firmware)
        else:
            objects, compiler, note = {}, None, "not measured (measure=False)"
        footprint = Footprint(**{**footprint.__dict__, "objects": objects,
                                 "compiler": compiler, "note": note})
        result = ExportResult(Path(out).resolve(), (*sorted(files), MANIFEST), precision,
                              plan.kind, fingerprint, certified, certificate, footprint,
                              rounding, tuple(plan.notes))
        (tmp / MANIFEST).write_text(json.dumps(result.as_dict(), indent=2, allow_nan=False)
                                    + "\n", encoding="utf-8")
    return result
