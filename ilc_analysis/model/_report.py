"""A structured report on a plant at an operating point (what ``ilc-analysis model`` prints)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._deprecation import REMOVED_IN, warn_deprecated
from ._linear_analysis import markov_parameters, relative_degree
from ._paper_defects import PAPER_DEFECTS
from ._plant import Plant

__all__ = ["ModelReport", "model_report"]


@dataclass(frozen=True)
class ModelReport:
    """Linearisation, eigenvalues, relative degree and Markov parameters of a plant."""

    plant_name: str
    """the plant's ``name``"""
    state_names: tuple[str, ...]
    """names of the states, in order"""
    input_names: tuple[str, ...]
    """names of the inputs, in order"""
    output_names: tuple[str, ...]
    """names of the outputs, in order"""
    x0: np.ndarray
    """operating-point state, shape (n_x,)"""
    u0: np.ndarray
    """operating-point input, shape (n_u,)"""
    A: np.ndarray
    r""":math:`\partial f/\partial x` at (x0, u0), shape (n_x, n_x)"""
    B: np.ndarray
    r""":math:`\partial f/\partial u` at (x0, u0), shape (n_x, n_u)"""
    C: np.ndarray
    r""":math:`\partial h/\partial x` at (x0, u0), shape (n_y, n_x)"""
    D: np.ndarray
    r""":math:`\partial h/\partial u` at (x0, u0), shape (n_y, n_u)"""
    eigenvalues: np.ndarray
    """eigenvalues of A (complex), sorted by real part, then imaginary part"""
    relative_degree: list
    """relative degree of each output (:func:`~ilc_analysis.model.relative_degree`: 0 with
    feedthrough, None when the input does not reach the output)"""
    markov: list
    r"""Markov parameters :math:`CB, CAB, \dots, CA^{n-1}B` (n_y x n_u arrays;
    :func:`~ilc_analysis.model.markov_parameters`)"""
    params: dict
    """the parameter values the plant was built with"""
    is_equilibrium: bool
    r"""(x0, u0) is an equilibrium: :math:`\|f(x_0, u_0, 0)\|_\infty \le 10^{-9}`
    (:meth:`~ilc_analysis.model.Plant.is_equilibrium`)"""
    notes: list[str] = field(default_factory=list)
    """remarks: an output the input does not reach, a relative degree of 2 or more (the paper's
    D-type condition cannot see the gains there), an unstable linearisation"""
    paper_defects: bool = True
    """list the paper's printed errors (:data:`PAPER_DEFECTS`; about the paper's robot, not a
    user's plant)"""

    @property
    def stable(self) -> bool:
        """All eigenvalues strictly in the open left half-plane."""
        return bool(np.all(self.eigenvalues.real < 0))

    def to_dict(self) -> dict:
        """Deprecated name of :meth:`as_dict` (removed in 0.3.0)."""
        warn_deprecated("ModelReport.to_dict", "ModelReport.as_dict", REMOVED_IN)
        return self.as_dict()

    def as_dict(self) -> dict:
        """JSON-ready dict (keys of the CLI's ``--json``)."""
        return {
            "model": self.plant_name,
            "states": list(self.state_names),
            "inputs": list(self.input_names),
            "outputs": list(self.output_names),
            "x0": self.x0.tolist(),
            "u0": self.u0.tolist(),
            "is_equilibrium": self.is_equilibrium,
            "A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
            "D": self.D.tolist(),
            "eigenvalues": [[float(e.real), float(e.imag)] for e in self.eigenvalues],
            "relative_degree": list(self.relative_degree),
            "markov": [h.tolist() for h in self.markov],
            "params": dict(self.params),
            "paper_defects": [d.as_dict() for d in PAPER_DEFECTS] if self.paper_defects
            else [],
            "notes": list(self.notes),
        }

    def to_text(self) -> str:
        """A readable plain-text report."""
        def mat(M):
            return "\n".join("    [" + ", ".join(f"{v: .6g}" for v in row) + "]" for row in M)

        shown = [f"{k}={v:g}" for k, v in self.params.items() if isinstance(v, float)]
        eig = ", ".join(f"{e.real:.6g}" + (f"{e.imag:+.6g}j" if abs(e.imag) > 0 else "")
                        for e in self.eigenvalues)
        lines = [
            f"Model {self.plant_name}: {len(self.state_names)} states "
            f"({', '.join(self.state_names)}), inputs ({', '.join(self.input_names)}), "
            f"outputs ({', '.join(self.output_names)})",
            f"Operating point x0 = {self.x0.tolist()}, u0 = {self.u0.tolist()}"
            + ("" if self.is_equilibrium else "  (not an equilibrium)"),
            *(["Parameters: " + ", ".join(shown)] if shown else []),
            "A =", mat(self.A), "B =", mat(self.B), "C =", mat(self.C),
            f"Eigenvalues: {eig}  ({'stable' if self.stable else 'NOT stable'})",
            "Relative degree per output: " + ", ".join(
                f"{n}: {r}" for n, r in zip(self.output_names, self.relative_degree,
                                            strict=True)),
        ]
        for k, h in enumerate(self.markov[:3]):
            lines.append(f"Markov parameter C A^{k} B = {np.round(h, 6).tolist()}")
        lines += ["", *self.notes]
        if self.paper_defects:
            lines += ["", "Printed errors of the paper (see PAPER_DEFECTS):"]
            lines += [f"  - {d.equation}: printed {d.printed!r}; correct {d.correct!r}"
                      for d in PAPER_DEFECTS]
        return "\n".join(lines)


def _relative_degree_notes(degrees, output_names) -> list[str]:
    notes = []
    for name, r in zip(output_names, degrees, strict=True):
        if r is None:
            notes.append(f"Output {name} is not influenced by the input.")
        elif r >= 2:
            notes.append(
                f"Relative degree is {r} for output {name} (CB = 0 in that row): the paper's "
                "D-type condition gamma1 = sup||(1-a)I - Phi1 CB||, gamma2 = sup||(I + Phi2 "
                "CB)^-1|| does not involve the learning gains there, so it is met by the "
                "forgetting factor alone; use the relative-degree-aware condition "
                f"(H = C A^{r - 1} B, relative_degree_aware=True) or the lifted checks.")
    return notes


def model_report(plant: Plant, x0=None, u0=None, *, paper_defects: bool = True) -> ModelReport:
    """Linearise ``plant`` at ``(x0, u0)`` and collect the facts of :class:`ModelReport`.

    Parameters
    ----------
    plant : Plant
        The plant.
    x0 : array_like, shape (n_x,), optional
        Operating-point state (default: zero).
    u0 : array_like, shape (n_u,), optional
        Operating-point input (default: zero).
    paper_defects : bool, optional
        List the paper's printed errors in the report (default; pass False for a plant that
        is not the paper's robot).
    """
    sys = plant.linearize(x0, u0)
    x0v = np.zeros(plant.n_x) if x0 is None else np.asarray(x0, dtype=float)
    u0v = np.zeros(plant.n_u) if u0 is None else np.asarray(u0, dtype=float)
    degrees = relative_degree(sys)
    eig = np.linalg.eigvals(np.asarray(sys.A))
    eig = eig[np.lexsort((eig.imag, eig.real))]
    notes = _relative_degree_notes(degrees, plant.output_names)
    if np.any(eig.real > 0):
        notes.append("The linearisation is unstable: learning needs a stabilising current-trial "
                     "(closed-loop) feedback, Phi2/Psi2 or an inner balance loop.")
    return ModelReport(
        plant_name=plant.name, state_names=plant.state_names, input_names=plant.input_names,
        output_names=plant.output_names, x0=x0v, u0=u0v,
        A=np.asarray(sys.A), B=np.asarray(sys.B), C=np.asarray(sys.C), D=np.asarray(sys.D),
        eigenvalues=eig, relative_degree=degrees, markov=markov_parameters(sys),
        params={k: v for k, v in plant.params.items()},
        is_equilibrium=plant.is_equilibrium(x0v, u0v), notes=notes,
        paper_defects=paper_defects)
