"""Design files: an ILC problem, a learning law and its certificate in one TOML file.

:class:`Design` holds an :class:`~ilc_analysis.problem.ILCProblem`, a
:class:`~ilc_analysis.laws.LearningLaw` on it and the certificate of what was verified;
:func:`load_design` / :func:`save_design` read and write it (``docs/design-file.md``,
:data:`DESIGN_FORMAT`); :meth:`Design.check` (:class:`DesignCheck`,
:class:`CertificateComparison`) re-verifies the certificate on exactly the operator it was
computed on, :meth:`Design.certify` certifies a design on its own operator and
:func:`certified_design` keeps a synthesis certificate about that operator. Old gains files
(:func:`ilc_analysis.laws.save_gains`) load as a Design without a problem. The plant of a file
is one of :data:`PLANT_KINDS` (:func:`plant_from_spec`), or measured FRF data (``[plant].frf``:
:func:`save_frf_design`, :func:`load_frf_design`, :func:`check_frf_design`; run on the
machine or on a simulation model with :func:`load_frf_run`).

A design file may name a registered scenario instead of holding its signals:
:func:`register_scenario` adds a :class:`Scenario` to :data:`SCENARIOS`. This stage registers
none: a package that provides scenarios registers them when it is imported (the paper's circle,
``"paper"``, by :mod:`ilc_analysis.paper`; the command line imports it).

Every error in a file is a :class:`~ilc_analysis.exceptions.DesignFileError` naming the key
path (``[law].beta``) and the expected form.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._design import CertificateComparison, Design, DesignCheck, certified_design
from ._file import DESIGN_FORMAT, load_design, save_design
from ._frf_file import (
    FRFDesignCheck,
    check_frf_design,
    is_frf_design,
    load_frf_design,
    load_frf_run,
    save_frf_design,
)
from ._plant_spec import PLANT_KINDS, plant_from_spec
from ._signals import SCENARIOS, Scenario, register_scenario

__all__ = ["Design", "DesignCheck", "CertificateComparison", "load_design", "save_design",
           "certified_design", "DESIGN_FORMAT", "PLANT_KINDS", "plant_from_spec", "SCENARIOS",
           "Scenario", "register_scenario", "save_frf_design", "load_frf_design",
           "check_frf_design", "is_frf_design", "load_frf_run", "FRFDesignCheck"]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
