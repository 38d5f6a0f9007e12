r"""The footprint of a generated update: RAM, flash and operations per trial.

* **RAM** (:attr:`Footprint.ram_bytes`): the work struct ``ilc_work_t``, the state between
  runs ``ilc_state_t`` and the in-trial step's ``ilc_step_t`` where the law has them, and the
  trial's buffers the update reads and writes (the last input, the record, the next input);
  every size fixed at export, ``sizeof`` exactly (the host driver's ``--sizes`` prints them);
* **flash**: the constants (``static const`` arrays: gains, filters, lifted matrices,
  reference, first input) and the code, measured on the objects the system C compiler makes
  of the firmware sources (``cc -std=c99 -O2 -c``): the sizes of their allocated sections read
  from the ELF file itself (text = code and read-only data, data, bss, as binutils' ``size``
  counts them), or not measured when no compiler is found;
* **operations per trial**: additions, multiplications, divisions, exp calls and
  comparisons, counted per stage (:meth:`~ilc_analysis.export._stage.Stage.operations`);
  the update's loops have fixed lengths, so every call does exactly these.
"""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from ..exceptions import ExportRefusedError
from ._c import REAL_BYTES
from ._plan import UpdatePlan

__all__ = ["Footprint", "ObjectSize", "find_compiler", "object_sizes", "analytic_footprint",
           "check_ram", "check_constants", "COMPILE_FLAGS", "MAX_CONSTANT_BYTES"]

#: Flags the footprint's objects are compiled with (the build line of the generated files).
COMPILE_FLAGS = ("-std=c99", "-O2")
#: ``sizeof`` of the fixed-width integers of ``ilc_state_t`` (``uint32_t``).
_COUNTER_BYTES = 4
#: Largest constant data the export writes (bytes): beyond it the C text (about three times
#: larger) and its compilation take longer than any machine's flash is worth; a law whose
#: lifted gains are stored dense reaches it at a few thousand samples.
MAX_CONSTANT_BYTES = 32 * 2 ** 20
#: Seconds a compilation may take before it counts as failed.
_COMPILE_TIMEOUT = 300


@dataclass(frozen=True)
class ObjectSize:
    """The allocated sections of one compiled object (binutils ``size``'s Berkeley columns)."""

    text: int
    """code and read-only data (the constants)"""
    data: int
    """initialised writable data"""
    bss: int
    """zero-initialised writable data"""

    @property
    def flash(self) -> int:
        return self.text + self.data


@dataclass(frozen=True)
class Footprint:
    """RAM, flash and operations of a generated update (module docstring)."""

    precision: str
    """``'double'`` or ``'single'``"""
    real_bytes: int
    """``sizeof(ilc_real)``"""
    work_bytes: int
    """``sizeof(ilc_work_t)``"""
    state_bytes: int
    """``sizeof(ilc_state_t)`` (0: no state between runs)"""
    step_bytes: int
    """``sizeof(ilc_step_t)`` (0: no current-trial part)"""
    buffer_bytes: int
    """the trial's buffers: last input, record, next input"""
    constant_bytes: int
    """the constant arrays (flash)"""
    operations: dict
    """floating-point operations per trial by kind, and their total"""
    objects: dict = field(default_factory=dict)
    """measured :class:`ObjectSize` of each firmware source (empty: not measured)"""
    compiler: str | None = None
    """the compiler that measured them, or None"""
    note: str = ""
    """why the code size was not measured, when it was not"""

    @property
    def ram_bytes(self) -> int:
        """Work, state, step memory and the trial's buffers."""
        return self.work_bytes + self.state_bytes + self.step_bytes + self.buffer_bytes

    @property
    def flash_bytes(self) -> int | None:
        """Code and constants of the firmware objects (None: not measured)."""
        if not self.objects:
            return None
        return sum(o.flash for o in self.objects.values())

    def as_dict(self) -> dict:
        return {"precision": self.precision, "real_bytes": self.real_bytes,
                "ram_bytes": self.ram_bytes, "work_bytes": self.work_bytes,
                "state_bytes": self.state_bytes, "step_bytes": self.step_bytes,
                "buffer_bytes": self.buffer_bytes, "constant_bytes": self.constant_bytes,
                "flash_bytes": self.flash_bytes,
                "objects": {k: {"text": v.text, "data": v.data, "bss": v.bss}
                            for k, v in self.objects.items()},
                "compiler": self.compiler, "note": self.note,
                "operations_per_trial": dict(self.operations)}

    def summary(self) -> str:
        flash = ("not measured (" + self.note + ")" if self.flash_bytes is None
                 else f"{self.flash_bytes} bytes (code and constants, {self.compiler} "
                      f"{' '.join(COMPILE_FLAGS)})")
        parts = [f"work {self.work_bytes}"]
        if self.state_bytes:
            parts.append(f"state {self.state_bytes}")
        if self.step_bytes:
            parts.append(f"in-trial step {self.step_bytes}")
        parts.append(f"trial buffers {self.buffer_bytes}")
        ops = self.operations
        return (f"RAM {self.ram_bytes} bytes ({', '.join(parts)}); flash {flash}; constant "
                f"tables {self.constant_bytes} bytes (as written: the compiler may merge equal "
                f"ones); {ops['total']} floating-point operations "
                f"per trial ({ops['mul']} mul, {ops['add']} add, {ops['div']} div, "
                f"{ops['exp']} exp)")


def analytic_footprint(plan: UpdatePlan, problem, precision: str) -> Footprint:
    """The footprint's sizes and operations from the plan (no compiler)."""
    real = REAL_BYTES[precision]
    work = sum(w.length for w in plan.work()) or 1
    state = 0
    if plan.stateful is not None:
        state = 2 * _COUNTER_BYTES + real * sum(
            int(m.split("[")[1].rstrip("]")) for _, m, _ in plan.stateful.state_members()
            if "[" in m)
    step = real * problem.n_y if plan.feedback is not None else 0
    buffers = real * (2 * problem.N * problem.n_u + (problem.N + problem.shift) * problem.n_y)
    constants = problem.N * problem.n_u + sum(c.size for c in plan.constants())
    if plan.stateful is not None:
        constants += sum(c.size for c in plan.stateful.constants())
    ops = plan.operations()
    if plan.stateful is not None:
        ops.update(plan.stateful.operations())
    return Footprint(precision, real, real * work, state, step, buffers, real * constants,
                     ops.as_dict())


def check_ram(footprint: Footprint, ram: int | None) -> None:
    """Refuse (:class:`ExportRefusedError`) an update that needs more RAM than ``ram`` bytes."""
    if ram is not None and footprint.ram_bytes > ram:
        raise ExportRefusedError(
            "the update", f"it needs {footprint.ram_bytes} bytes of RAM (work "
            f"{footprint.work_bytes}, state {footprint.state_bytes}, in-trial step "
            f"{footprint.step_bytes}, trial buffers {footprint.buffer_bytes}) and the limit "
            f"--ram is {ram} bytes; shorten the trial, use single precision or a law with "
            f"fewer work arrays")


def check_constants(footprint: Footprint, plan: UpdatePlan) -> None:
    """Refuse (:class:`ExportRefusedError`) constants beyond :data:`MAX_CONSTANT_BYTES`."""
    if footprint.constant_bytes <= MAX_CONSTANT_BYTES:
        return
    biggest = sorted(plan.constants(), key=lambda c: -c.size)[:2]
    names = ", ".join(f"{c.name} ({c.size} values)" for c in biggest)
    raise ExportRefusedError(
        "the update", f"its constants take {footprint.constant_bytes / 2 ** 20:.1f} MiB "
        f"({names}), above the export's limit of {MAX_CONSTANT_BYTES // 2 ** 20} MiB: the "
        f"law stores its lifted gains dense, N x N; shorten the trial, or use a law with a "
        f"structured update (a PD or Q/L law: filters, not matrices)")


def find_compiler() -> str | None:
    """The system C compiler: ``$CC``, else ``cc``, ``gcc`` or ``clang`` on the path."""
    env = os.environ.get("CC")
    if env and shutil.which(env):
        return shutil.which(env)
    for name in ("cc", "gcc", "clang"):
        found = shutil.which(name)
        if found:
            return found
    return None


def object_sizes(directory: Path, sources, compiler: str | None = None,
                 flags=COMPILE_FLAGS) -> tuple[dict, str | None, str]:
    """Compile each of ``sources`` in ``directory`` to an object and measure it.

    Returns
    -------
    (sizes, compiler, note)
        ``{source: ObjectSize}``, the compiler used and, when nothing was measured, why.
    """
    compiler = compiler or find_compiler()
    if compiler is None:
        return {}, None, "no C compiler found ($CC, cc, gcc, clang)"
    out = {}
    with tempfile.TemporaryDirectory(prefix="ilc-export-objects-") as tmp:
        for name in sources:
            obj = Path(tmp) / (Path(name).stem + ".o")
            try:
                done = subprocess.run([compiler, *flags, "-c", str(Path(directory) / name), "-o",
                                       str(obj)], capture_output=True, text=True,
                                      timeout=_COMPILE_TIMEOUT, check=False)
            except (OSError, subprocess.TimeoutExpired) as exc:
                return {}, compiler, f"{compiler} failed to run: {exc}"
            if done.returncode != 0:
                return {}, compiler, (f"{compiler} could not compile {name}: "
                                      f"{done.stderr.strip()[:400]}")
            sizes = elf_sizes(obj.read_bytes())
            if sizes is None:
                return {}, compiler, f"{name}'s object is not an ELF file: sizes not read"
            out[name] = sizes
    return out, compiler, ""


def elf_sizes(blob: bytes) -> ObjectSize | None:
    """The Berkeley sizes of an ELF object (32 or 64 bits, either byte order): the allocated
    sections, read-only (text), writable with contents (data) and without (bss); None for
    anything else."""
    if len(blob) < 52 or blob[:4] != b"\x7fELF" or blob[4] not in (1, 2) \
            or blob[5] not in (1, 2):
        return None
    wide = blob[4] == 2
    end = "<" if blob[5] == 1 else ">"
    if wide:
        shoff, = struct.unpack_from(end + "Q", blob, 0x28)
        shentsize, shnum = struct.unpack_from(end + "HH", blob, 0x3A)
    else:
        shoff, = struct.unpack_from(end + "I", blob, 0x20)
        shentsize, shnum = struct.unpack_from(end + "HH", blob, 0x2E)
    text = data = bss = 0
    SHF_WRITE, SHF_ALLOC, SHT_NOBITS = 0x1, 0x2, 8
    for i in range(shnum):
        base = shoff + i * shentsize
        if base + shentsize > len(blob):
            return None
        if wide:
            _, sh_type, flags = struct.unpack_from(end + "IIQ", blob, base)
            size, = struct.unpack_from(end + "Q", blob, base + 0x20)
        else:
            _, sh_type, flags = struct.unpack_from(end + "III", blob, base)
            size, = struct.unpack_from(end + "I", blob, base + 0x14)
        if not flags & SHF_ALLOC:
            continue
        if sh_type == SHT_NOBITS:
            bss += size
        elif flags & SHF_WRITE:
            data += size
        else:
            text += size
    return ObjectSize(int(text), int(data), int(bss))
