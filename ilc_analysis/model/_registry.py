r"""A registry of built-in plant models, addressable by name (design files, command line).

Each entry is a constructor with named scalar parameters, their defaults and valid ranges, and
a one-line description::

    >>> from ilc_analysis.model import builtin_model, BUILTIN_MODELS
    >>> sorted(BUILTIN_MODELS)
    ['mass-spring-damper', 'mobile', 'mobile_balanced', 'planar', 'two-mass']
    >>> builtin_model("two-mass", k=200.0).name
    'two_mass'

Built-in entries:

``planar``, ``mobile``, ``mobile_balanced``
    The two-wheeled self-balancing robot of the paper (:mod:`ilc_analysis.model._robots`); the
    parameters are the fields of :class:`~ilc_analysis.model.RobotParameters` the model uses
    (``mobile_balanced`` adds the steady ``speed`` and ``yaw_rate`` its balance loop holds).
``mass-spring-damper``
    One mass on a spring and a damper to ground, force input, position output:

    .. math::

        m\ddot x + c\dot x + k x = F, \qquad \frac{X(s)}{F(s)} = \frac{1}{m s^2 + c s + k}.
``two-mass``
    A two-mass drive (motor and load coupled by a compliant shaft or belt): force F on mass 1,
    output the position of mass 2, spring k and damper c between the masses, optional mounting
    spring :math:`k_1` and damper :math:`c_1` from mass 1 to ground (zero by default: a free
    drive with a rigid-body double integrator):

    .. math::

        m_1\ddot x_1 &= F - k(x_1 - x_2) - c(\dot x_1 - \dot x_2) - k_1 x_1 - c_1\dot x_1 \\
        m_2\ddot x_2 &= k(x_1 - x_2) + c(\dot x_1 - \dot x_2)

    .. math::

        \frac{X_2(s)}{F(s)} = \frac{c s + k}{(m_1 s^2 + (c + c_1) s + k + k_1)
                              (m_2 s^2 + c s + k) - (c s + k)^2},

    whose static gain is :math:`1/k_1` (infinite for the free drive).

Users add their own with :func:`register_model`.
"""

from __future__ import annotations

import dataclasses
import keyword
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import control
import numpy as np

from .._validation import nonnegative, positive, real
from ..exceptions import ParameterError
from ._parameters import RobotParameters
from ._plant import Plant
from ._robots import balanced_mobile_robot, mobile_robot, planar_robot

__all__ = ["ModelEntry", "BUILTIN_MODELS", "builtin_model", "register_model",
           "unregister_model", "two_mass_plant", "mass_spring_damper_plant"]

#: Admissible parameter domains and their validators.
DOMAINS: Mapping[str, Callable[[object, str], float]] = MappingProxyType(
    {"positive": positive, "nonnegative": nonnegative, "real": real})


@dataclass(frozen=True)
class ModelEntry:
    """One registered model.

    Attributes
    ----------
    name : str
        The registry name (``[plant] builtin = name`` in a design file).
    constructor : callable
        Called with every parameter as a keyword argument (defaults merged with the caller's
        values); returns a :class:`Plant` (or a continuous python-control LTI, converted with
        :meth:`Plant.from_statespace`).
    defaults : mapping of str to float
        Parameter names, in declaration order, and their default values.
    description : str
        One line.
    domains : mapping of str to str
        ``'positive'``, ``'nonnegative'`` or ``'real'`` per parameter.
    parameter_docs : mapping of str to str
        One line per parameter (meaning and unit), possibly empty.
    builtin : bool
        Shipped with the package (cannot be replaced or removed).
    """

    name: str
    constructor: Callable[..., object]
    defaults: Mapping[str, float]
    description: str
    domains: Mapping[str, str]
    parameter_docs: Mapping[str, str] = field(default_factory=dict)
    builtin: bool = False

    @property
    def parameters(self) -> tuple[str, ...]:
        """Parameter names in declaration order."""
        return tuple(self.defaults)

    def resolve(self, parameters: Mapping[str, object]) -> dict[str, float]:
        """Defaults overridden by ``parameters``, each checked against its domain.

        Parameters
        ----------
        parameters : mapping of str to float
            Overrides of the model's default parameters, by name.

        Raises
        ------
        ParameterError
            An unknown parameter name (the accepted ones are listed), a value that is not a
            finite real number, or a value outside its domain (named ``model.parameter``).
        """
        if not isinstance(parameters, Mapping):
            raise ParameterError(f"parameters of model {self.name!r} must be a mapping of "
                                 f"name to number; got {type(parameters).__name__}")
        unknown = [k for k in parameters if k not in self.defaults]
        if unknown:
            accepted = ", ".join(self.defaults) or "(none)"
            raise ParameterError(
                f"unknown parameter(s) {', '.join(map(repr, unknown))} for model "
                f"{self.name!r}; accepted: {accepted}")
        values = {}
        for key, default in self.defaults.items():
            value = parameters.get(key, default)
            values[key] = DOMAINS[self.domains[key]](value, f"{self.name}.{key}")
        return values

    def build(self, **parameters) -> Plant:
        """The plant with ``parameters`` (others at their defaults); see :func:`builtin_model`."""
        values = self.resolve(parameters)
        plant = self.constructor(**values)
        if isinstance(plant, control.TransferFunction):
            plant = control.ss(plant)
        if isinstance(plant, control.StateSpace):
            plant = Plant.from_statespace(plant, name=self.name)
        if not isinstance(plant, Plant):
            raise ParameterError(f"the constructor of model {self.name!r} must return a Plant "
                                 f"or a continuous control.StateSpace; it returned "
                                 f"{type(plant).__name__}")
        return plant


_REGISTRY: dict[str, ModelEntry] = {}
#: The registered models, name → :class:`ModelEntry` (read-only view; see
#: :func:`register_model`).
BUILTIN_MODELS: Mapping[str, ModelEntry] = MappingProxyType(_REGISTRY)


def builtin_model(name: str, **parameters) -> Plant:
    """The registered model ``name`` with ``parameters`` overriding its defaults.

    Parameters
    ----------
    name : str
        A key of :data:`BUILTIN_MODELS` (``'planar'``, ``'mobile'``, ``'mobile_balanced'``,
        ``'two-mass'``, ``'mass-spring-damper'``, or a user-registered name).
    **parameters : float
        Values of the entry's parameters (``BUILTIN_MODELS[name].defaults`` lists them).

    Returns
    -------
    Plant

    Raises
    ------
    ParameterError
        ``name`` is not registered (the known names are listed); a parameter is unknown (the
        accepted ones are listed), not a finite real number, or outside its domain (e.g.
        ``two-mass.m1 must be positive``).

    Examples
    --------
    >>> builtin_model("planar", m=0.6).params["m"]
    0.6
    """
    return _entry(name).build(**parameters)


def _entry(name) -> ModelEntry:
    """The registered entry ``name``; an unknown name lists the known ones."""
    if not isinstance(name, str) or name not in _REGISTRY:
        raise ParameterError(f"unknown model {name!r}; known models: "
                             f"{', '.join(sorted(_REGISTRY))}")
    return _REGISTRY[name]


def _check_name(name, what: str) -> str:
    if not isinstance(name, str) or not name.strip() or name != name.strip():
        raise ParameterError(f"{what} must be a non-empty string without surrounding spaces; "
                             f"got {name!r}")
    return name


def register_model(name: str, constructor: Callable[..., object],
                   parameters: Mapping[str, float] | None = None, *, description: str = "",
                   domains: Mapping[str, str] | None = None,
                   parameter_docs: Mapping[str, str] | None = None,
                   replace: bool = False) -> ModelEntry:
    """Register a user model so that :func:`builtin_model` (and design files) can build it.

    Parameters
    ----------
    name : str
        The registry name.
    constructor : callable
        ``constructor(**parameters) -> Plant`` (or a continuous python-control LTI). It is called
        with every parameter by keyword and must return a new plant on each call.
    parameters : mapping of str to float, optional
        Parameter names (Python identifiers) and their default values (finite reals).
    description : str
        One line.
    domains : mapping of str to str, optional
        ``'positive'`` (default), ``'nonnegative'`` or ``'real'`` per parameter.
    parameter_docs : mapping of str to str, optional
        One line per parameter.
    replace : bool
        Allow replacing an earlier *user* registration of ``name`` (built-in models cannot be
        replaced).

    Returns
    -------
    ModelEntry

    Raises
    ------
    ParameterError
        A bad name, a non-callable constructor, a parameter name that is not an identifier, a
        default outside its domain, an unknown domain, or ``name`` already registered.
    """
    return _register(name, constructor, parameters, description=description, domains=domains,
                     parameter_docs=parameter_docs, replace=replace, builtin=False)


def _register(name, constructor, parameters, *, description, domains, parameter_docs, replace,
              builtin) -> ModelEntry:
    _check_name(name, "name")
    if not callable(constructor):
        raise ParameterError(f"constructor of model {name!r} must be callable; got "
                             f"{type(constructor).__name__}")
    if name in _REGISTRY:
        if _REGISTRY[name].builtin:
            raise ParameterError(f"model {name!r} is built in and cannot be replaced; choose "
                                 f"another name")
        if not replace:
            raise ParameterError(f"model {name!r} is already registered; pass replace=True "
                                 f"to replace it")
    parameters = dict(parameters or {})
    domains = dict(domains or {})
    for key in parameters:
        if not isinstance(key, str) or not key.isidentifier() or keyword.iskeyword(key):
            raise ParameterError(f"parameter names of model {name!r} must be Python "
                                 f"identifiers; got {key!r}")
    stray = sorted(set(domains) - set(parameters))
    if stray:
        raise ParameterError(f"domains of model {name!r} name unknown parameter(s) {stray}; "
                             f"parameters: {list(parameters)}")
    for key in parameters:
        domain = domains.setdefault(key, "positive")
        if domain not in DOMAINS:
            raise ParameterError(f"domain of {name}.{key} must be one of {list(DOMAINS)}; "
                                 f"got {domain!r}")
    if not isinstance(description, str) or "\n" in description:
        raise ParameterError(f"description of model {name!r} must be one line of text")
    entry = ModelEntry(name=name, constructor=constructor, defaults=parameters,
                       description=description,
                       domains=MappingProxyType(domains),
                       parameter_docs=MappingProxyType(dict(parameter_docs or {})),
                       builtin=builtin)
    defaults = entry.resolve(parameters)           # validates every default in its domain
    entry = dataclasses.replace(entry, defaults=MappingProxyType(defaults))
    _REGISTRY[name] = entry
    return entry


def unregister_model(name: str) -> None:
    """Remove a user-registered model (built-in models cannot be removed).

    Parameters
    ----------
    name : str
        The name it was registered under.
    """
    if _entry(name).builtin:
        raise ParameterError(f"model {name!r} is built in and cannot be removed")
    del _REGISTRY[name]


# the generic mechanical examples ------------------------------------------------------------
def mass_spring_damper_plant(m: float = 1.0, k: float = 100.0, c: float = 2.0) -> Plant:
    r"""One mass on a spring and damper to ground: :math:`m\ddot x + c\dot x + kx = F`, y = x.

    States ``(x, v)`` [m, m/s] (declared units), input ``F`` [N], output ``x`` [m]. Defaults:
    1 kg, 100 N/m, 2 N s/m (natural frequency 10 rad/s, damping ratio 0.1).

    Parameters
    ----------
    m : float, optional
        Mass [kg].
    k : float, optional
        Spring stiffness [N/m].
    c : float, optional
        Damping [N s/m].
    """
    m = positive(m, "m")
    k = nonnegative(k, "k")
    c = nonnegative(c, "c")
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    B = np.array([[0.0], [1.0 / m]])
    C = np.array([[1.0, 0.0]])
    sys = control.ss(A, B, C, np.zeros((1, 1)), states=["x", "v"], inputs=["F"], outputs=["x"])
    return Plant.from_statespace(sys, name="mass_spring_damper",
                                 units={"x": "m", "v": "m/s", "F": "N"},
                                 params={"m": m, "k": k, "c": c})


def two_mass_plant(m1: float = 1.0, m2: float = 0.5, k: float = 200.0, c: float = 1.0,
                   k1: float = 0.0, c1: float = 0.0) -> Plant:
    r"""A two-mass drive: force on mass 1, output the position of mass 2 (module docstring).

    States ``(x1, v1, x2, v2)`` [m, m/s, m, m/s], input ``F`` [N], output ``x2`` [m]; declared
    metric ``stretch`` :math:`= x_1 - x_2` [m], the deflection of the coupling (the simulation
    reports its peak per trial, ``max_abs_stretch``).

    .. math::

        A = \begin{bmatrix} 0&1&0&0\\ -(k+k_1)/m_1 & -(c+c_1)/m_1 & k/m_1 & c/m_1\\
            0&0&0&1\\ k/m_2 & c/m_2 & -k/m_2 & -c/m_2 \end{bmatrix},\quad
        B = \begin{bmatrix}0\\ 1/m_1\\ 0\\ 0\end{bmatrix},\quad
        C = \begin{bmatrix}0&0&1&0\end{bmatrix}

    Defaults: 1 kg motor side, 0.5 kg load, 200 N/m, 1 N s/m (anti-resonance
    :math:`\sqrt{k/m_2} = 20` rad/s, resonance :math:`\sqrt{k(m_1+m_2)/(m_1 m_2)} \approx 24.5`
    rad/s), free mounting (:math:`k_1 = c_1 = 0`).

    Parameters
    ----------
    m1, m2 : float, optional
        The masses [kg] (force on mass 1, output mass 2).
    k, c : float, optional
        Stiffness [N/m] and damping [N s/m] of the coupling.
    k1, c1 : float, optional
        Stiffness and damping of mass 1 to ground (default: none).
    """
    m1, m2 = positive(m1, "m1"), positive(m2, "m2")
    k, c = nonnegative(k, "k"), nonnegative(c, "c")
    k1, c1 = nonnegative(k1, "k1"), nonnegative(c1, "c1")
    A = np.array([[0.0, 1.0, 0.0, 0.0],
                  [-(k + k1) / m1, -(c + c1) / m1, k / m1, c / m1],
                  [0.0, 0.0, 0.0, 1.0],
                  [k / m2, c / m2, -k / m2, -c / m2]])
    B = np.array([[0.0], [1.0 / m1], [0.0], [0.0]])
    C = np.array([[0.0, 0.0, 1.0, 0.0]])
    sys = control.ss(A, B, C, np.zeros((1, 1)), states=["x1", "v1", "x2", "v2"], inputs=["F"],
                     outputs=["x2"])
    return Plant.from_statespace(
        sys, name="two_mass",
        units={"x1": "m", "v1": "m/s", "x2": "m", "v2": "m/s", "F": "N", "stretch": "m"},
        metrics={"stretch": [1.0, 0.0, -1.0, 0.0]},
        params={"m1": m1, "m2": m2, "k": k, "c": c, "k1": k1, "c1": c1})


# built-in entries -----------------------------------------------------------------------------
_TABLE1 = ("M", "m", "l", "I", "g", "b")
_MOBILE = _TABLE1 + ("r", "track", "J", "b_yaw")
_ROBOT_DEFAULTS = RobotParameters().as_dict()
_NONNEGATIVE_ROBOT = ("b", "b_yaw")


def _robot_entry(name, build, names, description, extra=None):
    extra = extra or {}
    defaults = {n: _ROBOT_DEFAULTS[n] for n in names}
    domains = {n: ("nonnegative" if n in _NONNEGATIVE_ROBOT else "positive") for n in names}
    docs = {n: RobotParameters.describe(n) for n in names}
    for key, (default, domain, doc) in extra.items():
        defaults[key], domains[key], docs[key] = default, domain, doc
    _register(name, build, defaults, description=description, domains=domains,
              parameter_docs=docs, replace=False, builtin=True)


def _robot_parameters(values: dict) -> RobotParameters:
    return RobotParameters().replace(**{k: v for k, v in values.items()
                                        if k in _ROBOT_DEFAULTS})


_robot_entry("planar", lambda **p: planar_robot(_robot_parameters(p)), _TABLE1,
             "planar two-wheeled self-balancing robot (paper eqs 1-2, 8): force in, (x, theta) out")
_robot_entry("mobile", lambda **p: mobile_robot(_robot_parameters(p)), _MOBILE,
             "mobile two-wheeled self-balancing robot (paper Section 5): wheel torques in, "
             "(X, Y, psi) out")
_robot_entry(
    "mobile_balanced",
    lambda speed, yaw_rate, **p: balanced_mobile_robot(_robot_parameters(p), speed=speed,
                                                       yaw_rate=yaw_rate),
    _MOBILE,
    "the mobile robot with its LQR balance loop closed about a steady motion: torque "
    "commands in, (X, Y, psi) out",
    extra={"speed": (0.0, "real", "steady forward speed the balance loop holds [m/s]"),
           "yaw_rate": (0.0, "real", "steady yaw rate the balance loop holds [rad/s]")})
_register("mass-spring-damper", mass_spring_damper_plant, {"m": 1.0, "k": 100.0, "c": 2.0},
          description="one mass on a spring and damper to ground: force in, position out",
          domains={"m": "positive", "k": "nonnegative", "c": "nonnegative"},
          parameter_docs={"m": "mass [kg]", "k": "spring stiffness to ground [N/m]",
                          "c": "viscous damping to ground [N s/m]"},
          replace=False, builtin=True)
_register("two-mass", two_mass_plant,
          {"m1": 1.0, "m2": 0.5, "k": 200.0, "c": 1.0, "k1": 0.0, "c1": 0.0},
          description="two-mass spring-damper drive: force on mass 1 in, position of mass 2 out",
          domains={"m1": "positive", "m2": "positive", "k": "nonnegative", "c": "nonnegative",
                   "k1": "nonnegative", "c1": "nonnegative"},
          parameter_docs={"m1": "driven (motor-side) mass [kg]", "m2": "load mass [kg]",
                          "k": "coupling stiffness between the masses [N/m]",
                          "c": "coupling damping between the masses [N s/m]",
                          "k1": "mounting stiffness of mass 1 to ground [N/m]",
                          "c1": "viscous damping of mass 1 to ground [N s/m]"},
          replace=False, builtin=True)
