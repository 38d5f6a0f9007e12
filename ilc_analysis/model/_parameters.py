"""Physical parameters of the two-wheeled self-balancing robot (TWSBR).

Table 1 of Dong et al. (2019) exactly as printed (``g = 9.87``), plus the parameters the
mobile model needs and the paper does not give, each a named default with its reason.
"""

from __future__ import annotations

import dataclasses
import textwrap
from dataclasses import dataclass, field

from .._validation import nonnegative, positive
from ..exceptions import ParameterError

__all__ = ["RobotParameters"]


def _doc(text: str) -> dict:
    return {"doc": text}


def _with_attributes(cls):
    """``cls`` with an ``Attributes`` section in its docstring, written from each field's
    ``doc`` metadata (the one place the meanings are written; :meth:`describe` reads it)."""
    lines = ["Attributes", "----------"]
    for f in dataclasses.fields(cls):
        lines.append(f"{f.name} : float")
        lines += textwrap.wrap(f.metadata["doc"], 88, initial_indent="    ",
                               subsequent_indent="    ")
    section = textwrap.indent("\n".join(lines), "    ")
    cls.__doc__ = cls.__doc__.replace("\n    Examples\n", "\n" + section + "\n\n    Examples\n", 1)
    return cls


@_with_attributes
@dataclass(frozen=True)
class RobotParameters:
    """Robot parameters (SI units). Frozen; validated on construction.

    The first seven are Table 1 of the paper. The last four are not in the paper; the mobile
    model (pitch/forward dynamics, yaw axis, unicycle kinematics; docs/theory.md §3, §10) needs
    them.

    Examples
    --------
    >>> p = RobotParameters()
    >>> round(p.p, 10)
    0.0092463872
    >>> p.replace(m=0.6).m
    0.6
    """

    M: float = field(default=1.12, metadata=_doc("mass of the wheels/base [kg] (Table 1)"))
    m: float = field(default=0.51, metadata=_doc("mass of the body [kg] (Table 1)"))
    l: float = field(default=0.084, metadata=_doc(  # noqa: E741 - the paper's symbol
        "distance from the wheel axle to the body's centre of mass [m] (Table 1)"))
    I: float = field(default=0.0032, metadata=_doc(  # noqa: E741 - the paper's symbol
        "body moment of inertia about its centre of mass [kg m^2] (Table 1)"))
    g: float = field(default=9.87, metadata=_doc(
        "gravitational acceleration [m/s^2] (Table 1 prints 9.87; kept as printed)"))
    b: float = field(default=0.1, metadata=_doc(
        "viscous friction between wheels and ground [N s/m] (Table 1)"))
    r: float = field(default=0.042, metadata=_doc(
        "wheel radius [m]. Table 1 prints 0.042 m as the 'wheel diameter'; for a robot whose "
        "centre of mass sits 0.084 m above the axle a 0.042 m radius is the plausible reading. "
        "Used only by the mobile model (wheel torque -> force)"))
    track: float = field(default=0.17, metadata=_doc(
        "wheel track: distance between the two wheel contact points [m]. Not in the paper; "
        "0.17 m is an assumed value for a robot of this size (body mass 0.51 kg, COM height "
        "0.084 m), where tracks of 0.15-0.20 m are usual"))
    J: float = field(default=0.0093, metadata=_doc(
        "yaw moment of inertia about the vertical axis [kg m^2]. Not in the paper; estimated "
        "as wheels at half-track plus a slab body: M (track/2)^2 + m track^2/12 = 0.0093 "
        "with the defaults"))
    b_yaw: float = field(default=0.00072, metadata=_doc(
        "yaw viscous friction [N m s/rad]. Not in the paper; the wheel friction b acting at "
        "half-track: b (track/2)^2 = 0.00072 with the defaults"))

    def __post_init__(self) -> None:
        for name in ("M", "m", "l", "I", "g", "r", "track", "J"):
            positive(getattr(self, name), f"RobotParameters.{name}")
        for name in ("b", "b_yaw"):
            nonnegative(getattr(self, name), f"RobotParameters.{name}")
        # store plain floats (ints from TOML or the CLI are accepted, not kept as ints)
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, float(getattr(self, f.name)))

    # derived quantities -------------------------------------------------------------------
    @property
    def p(self) -> float:
        r"""Determinant of the mass matrix at the upright, :math:`p = I(M+m) + M m l^2`.

        Equals the paper's :math:`q = (M+m)(I+ml^2) - m^2 l^2` of eq (6).
        """
        return self.I * (self.M + self.m) + self.M * self.m * self.l**2

    # conveniences ---------------------------------------------------------------------------
    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of all parameters, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def describe(cls, name: str) -> str:
        """The documented meaning and source of parameter ``name``.

        Parameters
        ----------
        name : str
            A field name (``'M'``, ``'m'``, ``'l'``, ...).
        """
        for f in dataclasses.fields(cls):
            if f.name == name:
                return f.metadata["doc"]
        raise ParameterError(f"unknown robot parameter {name!r}; known: {', '.join(cls.names())}")

    def replace(self, **changes: float) -> RobotParameters:
        """A copy with some parameters changed; unknown names raise :class:`ParameterError`."""
        unknown = sorted(set(changes) - set(self.names()))
        if unknown:
            raise ParameterError(
                f"unknown robot parameter(s) {', '.join(map(repr, unknown))}; "
                f"known: {', '.join(self.names())}")
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        """Parameters as a plain ``name -> value`` dict."""
        return dataclasses.asdict(self)
