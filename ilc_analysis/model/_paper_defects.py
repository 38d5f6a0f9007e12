"""The printed errors of Dong et al. (2019), each verified by computation (docs/theory.md §2)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

__all__ = ["PaperDefect", "PAPER_DEFECTS"]


@dataclass(frozen=True)
class PaperDefect:
    """One printed error: where, what is printed, what is correct, and why it matters."""

    equation: str
    """Where in the paper (equation or table)."""
    printed: str
    """What the paper prints."""
    correct: str
    """The corrected form the toolkit uses."""
    note: str
    """What follows from it."""

    def as_dict(self) -> dict[str, str]:
        return asdict(self)


PAPER_DEFECTS: tuple[PaperDefect, ...] = (
    PaperDefect(
        "eqs (1)-(3)",
        "theta from the upright, then cos(theta) ~ 1 and sin(theta) ~ -theta",
        "one convention: theta from the upright with (M+m)x'' + bx' - ml theta'' cos(theta) "
        "+ ml theta'^2 sin(theta) = u and (I+ml^2) theta'' - mgl sin(theta) = ml x'' cos(theta)",
        "as printed (theta from the upright, eqs 1-2) the origin is the stable hanging "
        "pendulum; the toolkit's equations linearise exactly to eqs (4)-(5)"),
    PaperDefect(
        "eq (8), A[1,2]", "m g l^2 / p", "m^2 g l^2 / p",
        "p = I(M+m) + M m l^2 (= q of eq 6); the printed entry is missing a factor m"),
    PaperDefect(
        "eq (6), s coefficient of the denominator", "b m g / l / q", "b m g l / q",
        "dimensionally inconsistent as printed"),
    PaperDefect(
        "Table 1, r", "wheel diameter 0.042 m", "probably the wheel radius",
        "unused by the planar model; the mobile model uses r = 0.042 m as the radius"),
    PaperDefect(
        "Section 4, eq (29)-(31)",
        "Lipschitz constant silently taken as 1 (e^t, (1-e^{-lambda T})/lambda)",
        "rho(lambda) = b_B (1 - e^{-(lambda-k_f)T}) / (lambda - k_f) with lambda > k_f",
        "for a linear plant k_f = ||A||, not 1"),
    PaperDefect(
        "Theorem 5 with eq (9)", "gamma1 = sup||(1-a)I - Phi1 CB||, gamma2 = sup||(I+Phi2 CB)^-1||",
        "relative-degree-aware: H = C A^{r-1} B with the r-th error derivative",
        "CB = 0 for the robot, so gamma1 = 1-a and gamma2 = 1 whatever the gains: the condition "
        "is met by the forgetting factor alone and the learning gains do nothing in it"),
    PaperDefect(
        "Section 5", "planar model with one input, two outputs (x, theta)",
        "P_d = [cos pi t, sin pi t, pi t + pi/2] and u0 = [0.1, 0.1] need a mobile model with "
        "yaw and unicycle kinematics (two inputs, outputs X, Y, psi)",
        "the toolkit adds the decoupled mobile model of the paper's ref [4]"),
)
