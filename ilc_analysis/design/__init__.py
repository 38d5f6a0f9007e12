r"""Design files: an ILC problem, a learning law and its certificate in one TOML file.

:class:`Design` holds an :class:`~ilc_analysis.problem.ILCProblem`, a
:class:`~ilc_analysis.laws.LearningLaw` on it and the certificate of what was verified;
:func:`load_design` / :func:`save_design` read and write it (``docs/design-file.md``);
:meth:`Design.check` re-verifies the certificate on exactly the operator it was computed on.
Old gains files (:func:`ilc_analysis.law.save_gains`) load as a Design without a problem.

Every error in a file is a :class:`~ilc_analysis.exceptions.DesignFileError` naming the key
path (``[law].beta``) and the expected form.
"""

from ..exceptions import DesignFileError
from .design import (
    CERTIFIED_NUMBERS,
    CHECK_RTOL,
    CertificateComparison,
    Design,
    DesignCheck,
    certified_design,
    operator_fingerprint,
)
from .file import DESIGN_FORMAT, design_document, is_gains_file, load_design, save_design
from .plant_spec import PLANT_KINDS, plant_from_spec
from .signals import SCENARIOS, Scenario

__all__ = ["Design", "DesignCheck", "CertificateComparison", "load_design", "save_design",
           "design_document", "is_gains_file", "operator_fingerprint", "DesignFileError",
           "DESIGN_FORMAT", "CERTIFIED_NUMBERS", "CHECK_RTOL", "PLANT_KINDS", "plant_from_spec",
           "SCENARIOS", "Scenario", "certified_design"]
