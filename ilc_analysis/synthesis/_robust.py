r"""Robust synthesis: the set of plants a certificate covers, whatever they model.

Robust synthesis minimises (and certifies) the worst case over a finite set of plants on the
same trial: the problem's own plant first, then each further one. This module turns that set
into what each method works on (:func:`method_plants`). The set is a list of plants, or one of
two uncertainty descriptions a certificate records (``certificate['uncertainty']``) so that
:meth:`ilc_analysis.design.Design.check` rebuilds the same set and re-checks it:

:class:`ParameterBox`
    A relative box :math:`p_k \in [(1-\epsilon)p_k^0, (1+\epsilon)p_k^0]` on named
    parameters of a registry model (:data:`ilc_analysis.model.BUILTIN_MODELS`): its
    :math:`2^K` **vertices**, or ``samples`` points drawn uniformly (seeded). What is covered
    is exactly that finite set: the lifted operator is not convex in physical parameters, so
    neither the vertices nor samples prove anything between them (:attr:`ParameterBox.covers`
    says so in the certificate).
:class:`MultiplicativeUncertainty`
    For an LTI problem, every plant :math:`G_\Delta = G(I + \Delta)` with
    :math:`\|\Delta\| \le w` on the trial (any stable :math:`\Delta(z)` with
    :math:`\sup_\omega \sigma_{\max}\Delta(e^{j\omega}) \le w`: the lifted operator of a
    causal LTI system is a finite section of its Toeplitz operator, whose norm is at most the
    H-infinity norm). The synthesis works on the sampled members :math:`\Delta = \pm wI`;
    the certificate adds a bound proven for the whole set (:func:`multiplicative_bound`): for
    a PD law without current-trial feedback :math:`T_\Delta = T - QL_1G\Delta`, so

    .. math::

        \sup_{\|\Delta\|\le w}\|T_\Delta\|_2 \le \|T\|_2 + w\,\|QL_1G\|_2,

    with :math:`\|T\|_2` the worst over the forgetting values (for a variable factor the
    proven per-sample bound, since :math:`QL_1G\Delta` does not depend on the factor).

The robot's parameter vertices and liftings lived here before; the old names
(``parameter_vertices``, ``parameter_samples``, ``robot_liftings``, ``UNCERTAIN_PARAMETERS``)
are the paper's now (:mod:`ilc_analysis.paper`) and resolve here until 0.3.0 with a
deprecation warning (the package's table of renamed names, :mod:`ilc_analysis._renames`).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import control
import numpy as np

from .._deprecation import deprecated_names
from .._progress import tracked
from .._renames import RENAMED
from .._validation import positive_int, real
from ..analysis._verdicts import threshold_verdict
from ..exceptions import InternalError, ParameterError
from ..lifting import LiftedSystem
from ..model import BUILTIN_MODELS, Plant, builtin_model, discretize
from ..problem import ILCProblem

__all__ = ["method_plants", "continuous_linearization", "discrete_linearization",
           "ParameterBox", "MultiplicativeUncertainty", "uncertainty_from_dict",
           "multiplicative_bound", "MAX_BOX_PARAMETERS", "MAX_BOX_SAMPLES"]

#: Most parameters a box may vary by its vertices (2**10 = 1024 plants); more need samples.
MAX_BOX_PARAMETERS = 10
#: Most sampled points of a box.
MAX_BOX_SAMPLES = 1000
#: Relative tolerance within which a box's nominal plant reproduces the problem's lifted G.
_CENTRE_RTOL = 1e-9

#: the robot's names that lived here (moved to the paper; module docstring)
__getattr__ = deprecated_names(__name__, RENAMED[__name__])


def continuous_linearization(problem: ILCProblem) -> control.StateSpace:
    r"""The continuous linearisation :math:`(A, B, C, D)` of the problem's plant at its initial
    state and first nominal input (the operating point of the trial's start).

    Raises
    ------
    ParameterError
        If the plant is sampled (the paper-level condition is a continuous-time one).
    """
    plant = problem.plant
    if isinstance(plant, control.StateSpace) and not plant.isdtime(strict=True):
        return plant
    if not isinstance(plant, Plant):
        raise ParameterError(f"method 'paper' needs a continuous plant (its coupling "
                             f"H = C A^(r-1) B); problem {problem.name!r} has a "
                             f"{type(plant).__name__}")
    return plant.linearize(np.asarray(problem.x0)[:plant.n_x],
                           np.asarray(problem.u_nominal)[0])


def discrete_linearization(problem: ILCProblem) -> control.StateSpace:
    """The sampled LTI system of the problem: its own if it is LTI, else the zero-order-hold
    sampling of :func:`continuous_linearization`."""
    if problem.is_lti:
        return problem.lti_system
    return discretize(continuous_linearization(problem), problem.ts)


def _same_trial(problem: ILCProblem, other: ILCProblem, where: str) -> None:
    if other.N != problem.N or other.ts != problem.ts:
        raise ParameterError(f"{where}: a robust plant must be on the same trial (N = "
                             f"{problem.N}, ts = {problem.ts:g}); got N = {other.N}, ts = "
                             f"{other.ts:g}")


def method_plants(problem: ILCProblem, plants, method: str) -> list:
    r"""What ``method`` works on for the problem and the further plants of a robust set.

    Parameters
    ----------
    problem : ILCProblem
        The nominal problem (first in the set).
    plants : sequence or None
        Further plants on the same trial: ILCProblems; for ``'lifted'`` also LiftedSystems;
        for ``'paper'`` continuous, for ``'frequency'`` sampled control.StateSpace systems.
    method : {'lifted', 'frequency', 'paper'}

    Returns
    -------
    list
        LiftedSystems (``'lifted'``), sampled StateSpace systems (``'frequency'``) or
        continuous linearisations (``'paper'``), the problem's first.

    Raises
    ------
    ParameterError
        For a plant of another kind or on another trial (named by its index).
    """
    own = {"lifted": lambda p: p.lifted, "frequency": discrete_linearization,
           "paper": continuous_linearization}[method]
    out = [own(problem)]
    for k, plant in enumerate(tracked(() if plants is None else plants,
                                      desc=f"robust set ({method})", unit="plant")):
        where = f"plants[{k}]"
        if isinstance(plant, ILCProblem):
            _same_trial(problem, plant, where)
            out.append(own(plant))
        elif method == "lifted" and isinstance(plant, LiftedSystem):
            out.append(plant)
        elif method != "lifted" and isinstance(plant, control.StateSpace) and (
                plant.isdtime(strict=True) == (method == "frequency")):
            out.append(plant)
        else:
            kinds = {"lifted": "an ILCProblem or a LiftedSystem",
                     "frequency": "an ILCProblem or a sampled control.StateSpace",
                     "paper": "an ILCProblem or a continuous control.StateSpace"}[method]
            raise ParameterError(f"{where}: a robust plant of method {method!r} must be "
                                 f"{kinds}; got {type(plant).__name__}")
    return out


def _check_spread(value, name: str) -> float:
    """A relative half-width in (0, 1)."""
    v = real(value, name)
    if not 0.0 < v < 1.0:
        raise ParameterError(f"{name} must be in (0, 1); got {value!r}")
    return v


@dataclass(frozen=True)
class ParameterBox:
    r"""A relative box on named parameters of a registry model or a module plant: its vertices
    or samples.

    .. math::

        p_k \in [(1-\epsilon)\,p_k^0,\ (1+\epsilon)\,p_k^0], \qquad k \in \text{parameters},

    the other parameters at :math:`p^0`. The set covered is the problem's own plant and
    :meth:`parameter_sets`: the :math:`2^K` vertices (``samples`` None) or ``samples`` points
    drawn uniformly in the box by ``numpy.random.default_rng(seed)``. Nothing between them is
    covered (the lifted operator is not convex in the parameters; :attr:`covers`).

    Parameters
    ----------
    model : str
        A key of :data:`ilc_analysis.model.BUILTIN_MODELS`, or the
        ``'package.module:function'`` of a module plant (a design file's ``[plant] module``,
        its ``kwargs`` the parameters) built by ``factory``.
    spread : float
        Relative half-width :math:`\epsilon`, in (0, 1).
    nominal : mapping of str to float, optional
        The centre's parameters overriding the model's defaults (a design file's
        ``[plant.parameters]``); :attr:`centre` holds every parameter.
    parameters : sequence of str, optional
        The parameters varied (default: every parameter whose nominal value is not zero).
    samples : int, optional
        Draw this many points instead of taking the vertices.
    seed : int
        Seed of the samples.
    factory : callable, optional
        For a module plant: called with every parameter as keyword arguments, it returns the
        plant (running the user's code: the caller opted in, e.g. ``allow_code``).

    Raises
    ------
    ParameterError
        An unknown model (or a module plant without ``factory``) or parameter, a spread
        outside (0, 1), a varied parameter that is not a number or is zero (a relative box
        around 0 is the point 0), more than :data:`MAX_BOX_PARAMETERS`
        parameters for vertices, or ``samples`` outside 1 .. :data:`MAX_BOX_SAMPLES`.
    """

    model: str
    spread: float
    nominal: Mapping[str, float] = field(default_factory=dict)
    parameters: tuple[str, ...] | None = None
    samples: int | None = None
    seed: int = 0
    factory: Callable | None = field(default=None, compare=False, repr=False)

    @property
    def is_module(self) -> bool:
        """``model`` names a module function (``'package.module:function'``), not a registry
        model."""
        return isinstance(self.model, str) and ":" in self.model

    def build(self, parameters: Mapping) -> object:
        """The plant of the model with ``parameters`` (every parameter): the registry's
        :func:`~ilc_analysis.model.builtin_model`, or ``factory(**parameters)``.

        Parameters
        ----------
        parameters : mapping
            Every parameter of the model.
        """
        if self.is_module:
            if self.factory is None:
                raise InternalError("__post_init__ refuses a module box without a factory")
            return self.factory(**parameters)
        return builtin_model(self.model, **parameters)

    def __post_init__(self) -> None:
        if self.is_module:
            if not callable(self.factory):
                raise ParameterError(f"model {self.model!r} names a module function: pass it as "
                                     f"factory= (imported under the trust model: the design "
                                     f"file's allow_code / --allow-code)")
        elif not isinstance(self.model, str) or self.model not in BUILTIN_MODELS:
            raise ParameterError(f"model must be a registry model (one of "
                                 f"{sorted(BUILTIN_MODELS)}) or a module function "
                                 f"'package.module:function' with factory=; got "
                                 f"{self.model!r}")
        object.__setattr__(self, "spread", _check_spread(
            self.spread, "spread (relative half-width of the parameter box)"))
        if not isinstance(self.nominal, Mapping):
            raise ParameterError(f"nominal must be a mapping of parameter name to value; got "
                                 f"{type(self.nominal).__name__}")
        centre = dict(self.nominal) if self.is_module else \
            BUILTIN_MODELS[self.model].resolve(dict(self.nominal))
        object.__setattr__(self, "nominal", centre)
        numeric = {k: v for k, v in centre.items()
                   if isinstance(v, int | float) and not isinstance(v, bool)
                   and math.isfinite(v)}
        names = tuple(k for k, v in numeric.items() if v != 0) if self.parameters is None \
            else tuple(self.parameters)
        unknown = [n for n in names if n not in numeric]
        if unknown or not names or len(set(names)) != len(names):
            raise ParameterError(f"parameters must be distinct names of numeric parameters of "
                                 f"model {self.model!r} ({', '.join(numeric) or 'none'}); got "
                                 f"{list(names)}")
        zero = [n for n in names if centre[n] == 0]
        if zero:
            raise ParameterError(f"parameters {zero} of model {self.model!r} are 0: a relative "
                                 f"box around 0 holds only 0; vary other parameters")
        object.__setattr__(self, "parameters", names)
        if self.samples is None:
            if len(names) > MAX_BOX_PARAMETERS:
                raise ParameterError(f"parameters: {len(names)} parameters have 2^"
                                     f"{len(names)} vertices; at most {MAX_BOX_PARAMETERS} "
                                     f"for vertices: name fewer, or draw samples")
        else:
            object.__setattr__(self, "samples", positive_int(
                self.samples, "samples (points drawn in the box)", maximum=MAX_BOX_SAMPLES))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) \
                or self.seed < 0:
            raise ParameterError(f"seed must be an integer >= 0; got {self.seed!r}")

    @property
    def centre(self) -> dict:
        """Every parameter of the model at the centre :math:`p^0`."""
        return dict(self.nominal)

    @property
    def members(self) -> str:
        """``'vertices'`` or ``'samples'``."""
        return "vertices" if self.samples is None else "samples"

    @property
    def covers(self) -> str:
        """What a certificate over this box proves (and what it does not)."""
        names = ", ".join(self.parameters or ())
        box = f"{names} within +-{self.spread:g} (relative) of model {self.model!r}"
        if self.samples is None:
            return (f"the nominal plant and the {2 ** len(self.parameters or ())} vertices of "
                    f"the box {box}; not the points between them (the lifted operator is not "
                    f"convex in the parameters)")
        return (f"the nominal plant and {self.samples} points drawn uniformly in the box {box} "
                f"(seed {self.seed}): a sampled check, not a proof for the box")

    def parameter_sets(self) -> list[dict[str, float]]:
        """The further plants' parameters (every parameter of the model): the vertices, in
        the order of ``itertools.product((-1, +1), ...)``, or the samples."""
        centre = self.centre
        names = self.parameters or ()
        if self.samples is None:
            factors = np.array(list(itertools.product((-1.0, 1.0), repeat=len(names))))
            factors = 1.0 + self.spread * factors
        else:
            rng = np.random.default_rng(self.seed)
            factors = rng.uniform(1 - self.spread, 1 + self.spread,
                                  size=(self.samples, len(names)))
        return [{**centre, **{n: centre[n] * float(f) for n, f in zip(names, row, strict=True)}}
                for row in factors]

    def plants(self) -> list:
        """The further plants, :meth:`build` of each parameter set."""
        return [self.build(p) for p in self.parameter_sets()]

    def problems(self, problem: ILCProblem) -> list[ILCProblem]:
        """The further problems: ``problem`` on each plant of the box (same trial, reference,
        initial state, loop and nominal trajectory).

        Parameters
        ----------
        problem : ILCProblem
            The nominal problem; its plant must be the model at :attr:`centre`.

        Raises
        ------
        ParameterError
            If the box's centre is not the problem's plant: the lifted G of the model at
            :attr:`centre` differs from ``problem.lifted.G``.
        """
        described = problem.describe()
        centre = ILCProblem.from_description(described, plant=self.build(self.centre))
        G, G0 = problem.lifted.G, centre.lifted.G
        if G.shape != G0.shape or not np.allclose(G0, G, rtol=_CENTRE_RTOL,
                                                  atol=_CENTRE_RTOL * np.abs(G).max()):
            raise ParameterError(f"the parameter box is centred on model {self.model!r} with "
                                 f"{self.centre}, which is not the problem's plant (its lifted "
                                 f"G differs); give the problem's own model and parameters")
        return [ILCProblem.from_description(described, plant=plant)
                for plant in tracked(self.plants(), desc="parameter box", unit="plant")]

    def systems(self, problem: ILCProblem, method: str) -> list:
        """:meth:`problems` (what :func:`method_plants` takes for every method).

        Parameters
        ----------
        problem : ILCProblem
            The nominal problem.
        method : str
            The synthesis method (every method takes problems).
        """
        return self.problems(problem)

    def as_dict(self) -> dict:
        """Plain (TOML-safe) data; :func:`uncertainty_from_dict` reads it back."""
        d = {"kind": "parameter-box", "model": self.model, "spread": float(self.spread),
             "nominal": self.centre,
             "parameters": list(self.parameters or ()), "members": self.members}
        if self.samples is not None:
            d.update(samples=int(self.samples), seed=int(self.seed))
        return d


@dataclass(frozen=True)
class MultiplicativeUncertainty:
    r"""Every plant :math:`G_\Delta = G(I + \Delta)`, :math:`\|\Delta\| \le w`, of an LTI
    problem (module docstring).

    ``Δ`` acts at the learned signal (the input of the trial's G: the plant input, or the
    reference or input of the loop the learning drives), so G is the map the learning sees.
    The synthesis works on the sampled members :math:`G(1 \pm w)` (:meth:`systems`); the
    certificate's proof over the whole set is :func:`multiplicative_bound`.

    Parameters
    ----------
    weight : float
        :math:`w`, in (0, 1).

    Raises
    ------
    ParameterError
        A weight outside (0, 1).
    """

    weight: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "weight", _check_spread(
            self.weight, "weight (bound w of the multiplicative uncertainty)"))

    @property
    def covers(self) -> str:
        """What a certificate over this set proves."""
        return (f"every G(I + Delta) with ||Delta|| <= {self.weight:g} on the trial (any "
                f"stable Delta(z) with sup_w sigma_max Delta(e^jw) <= {self.weight:g}): proven "
                f"by ||T||_2 + w ||Q L1 G||_2 (multiplicative_bound); the synthesis minimised "
                f"the sampled members G(1 - w), G(1 + w)")

    def _check(self, problem: ILCProblem, method: str) -> None:
        if method != "lifted":
            raise ParameterError(f"multiplicative uncertainty: method {method!r} is not "
                                 f"supported; use method 'lifted' (the bound is proven on the "
                                 f"lifted operator)")
        if not problem.is_lti:
            raise ParameterError(f"multiplicative uncertainty needs an LTI problem; problem "
                                 f"{problem.name!r} is nonlinear (vary named parameters with a "
                                 f"ParameterBox instead)")

    def systems(self, problem: ILCProblem, method: str) -> list[LiftedSystem]:
        """The sampled members :math:`G(1 - w)` and :math:`G(1 + w)` (lifted systems).

        Parameters
        ----------
        problem : ILCProblem
            The nominal (LTI) problem.
        method : str
            The synthesis method (``'lifted'`` only).

        Raises
        ------
        ParameterError
            For a method other than ``'lifted'`` or a nonlinear problem.
        """
        self._check(problem, method)
        ls = problem.lifted
        return [dataclasses.replace(ls, G=ls.G * (1.0 + s * self.weight)) for s in (-1, 1)]

    def as_dict(self) -> dict:
        """Plain (TOML-safe) data; :func:`uncertainty_from_dict` reads it back."""
        return {"kind": "multiplicative", "weight": float(self.weight),
                "members": "vertices"}


def uncertainty_from_dict(data, where: str = "uncertainty", *, factory=None):
    """The :class:`ParameterBox` or :class:`MultiplicativeUncertainty` of ``as_dict()``'s
    data (e.g. a certificate's ``uncertainty``); ``factory``: the function a box on a module
    plant (``model = 'package.module:function'``) builds its plants with.

    Raises
    ------
    ParameterError
        For data that is not one of the two forms (the key is named).
    """
    if not isinstance(data, Mapping) or data.get("kind") not in ("parameter-box",
                                                                "multiplicative"):
        raise ParameterError(f"{where} must be a table with kind 'parameter-box' or "
                             f"'multiplicative'; got {data!r:.120}")
    d = dict(data)
    try:
        if d["kind"] == "multiplicative":
            extra = set(d) - {"kind", "weight", "members"}
            if extra:
                raise ParameterError(f"unknown key(s) {sorted(extra)}")
            return MultiplicativeUncertainty(d["weight"])
        allowed = {"kind", "model", "spread", "nominal", "parameters", "members", "samples",
                   "seed"}
        if set(d) - allowed:
            raise ParameterError(f"unknown key(s) {sorted(set(d) - allowed)}")
        box = ParameterBox(d["model"], d["spread"], nominal=d.get("nominal", {}),
                           parameters=tuple(d["parameters"]) if "parameters" in d else None,
                           samples=d.get("samples"), seed=d.get("seed", 0), factory=factory)
    except (KeyError, TypeError) as exc:
        raise ParameterError(f"{where}: missing or malformed entry ({exc})") from exc
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from exc
    if d.get("members", box.members) != box.members:
        raise ParameterError(f"{where}.members must be {box.members!r} for these entries; got "
                             f"{d.get('members')!r}")
    return box


@dataclass(frozen=True)
class MultiplicativeBound:
    """:func:`multiplicative_bound`'s result."""

    nominal: float
    """the worst ||T||_2 the bound starts from (over the forgetting values, or their proven
    per-sample bound)"""
    coupling: float
    """||Q L1 G||_2 of the nominal plant"""
    weight: float
    """w"""
    bound: float
    """nominal + w coupling: no plant of the set has a larger ||T||_2"""
    verdict: str
    """the bound against min(target, 1): 'holds', else 'unknown' (a bound proves only
    below the threshold)"""

    def as_dict(self) -> dict:
        return {"multiplicative_bound": self.bound, "multiplicative_coupling": self.coupling}


def multiplicative_bound(problem: ILCProblem, law, nominal: float, weight: float,
                         target: float) -> MultiplicativeBound:
    r"""A bound on :math:`\|T_\Delta\|_2` proven for every :math:`G(I+\Delta)`,
    :math:`\|\Delta\|\le w` (module docstring):

    .. math::

        \sup_{\|\Delta\|\le w}\|T_\Delta\|_2 \le \text{nominal} + w\,\|QL_1G\|_2,

    valid for a PD law without current-trial feedback (:math:`L_2 = 0`), where
    :math:`T = Q((I - A) - L_1G)` is affine in G.

    Parameters
    ----------
    problem : ILCProblem
        The nominal (LTI) problem; G is ``problem.lifted.G``.
    law : PDLaw
        The law (its gains, lead and Q-filter).
    nominal : float
        An upper bound of :math:`\|T\|_2` of the nominal plant over the law's forgetting (the
        worst over constant factors, or the proven per-sample bound of a variable factor).
    weight : float
        w.
    target : float
        The certificate's target: the verdict is the bound's against min(target, 1).

    Raises
    ------
    ParameterError
        For a law that is not a PD law, or one with current-trial gains (T is then not affine
        in G and this bound does not apply).
    """
    from ..laws import PDLaw
    from ..laws._gains import learning_operators

    if not isinstance(law, PDLaw):
        raise ParameterError(f"the multiplicative bound covers PD laws; got "
                             f"{type(law).__name__}")
    gains = law.gains
    if np.any(np.asarray(gains.Phi2)) or np.any(np.asarray(gains.Psi2)):
        raise ParameterError("the multiplicative bound needs a law without current-trial "
                             "feedback (Phi2 = Psi2 = 0): with it T is not affine in G")
    ls = problem.lifted
    L1, _ = learning_operators(gains, ls.N, ls.shift, ls.ts, n_u=ls.n_u, n_y=ls.n_y)
    M = np.asarray(L1 @ ls.G)
    if law.q_filter is not None:
        M = law.q_filter.lifted_matrix(ls.N, ls.n_u, ls.ts) @ M
    coupling = float(np.linalg.norm(M, 2))
    bound = float(nominal) + float(weight) * coupling
    verdict = "holds" if math.isfinite(bound) and threshold_verdict(
        bound, min(float(target), 1.0)) == "holds" else "unknown"
    return MultiplicativeBound(float(nominal), coupling, float(weight), bound, verdict)
