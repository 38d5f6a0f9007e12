r"""The one law layer: every learning law behind one interface, and the parameters of the PD law.

A :class:`LearningLaw` gives its lifted form :class:`LiftedLaw` (previous-trial matrix L1,
current-trial feedback L2, lifted Q-filter, forgetting a) on a
:class:`~ilc_analysis.lifting.LiftedSystem`, from which :meth:`LiftedLaw.operator` builds

.. math::

    T = (I + L_2G)^{-1}\,Q\,\big((1-a)I - L_1G\big)

(the one place, delegating to :func:`ilc_analysis.lifting.learning_operator`); its frequency
response :class:`LawResponse` when law and plant are LTI; and its between-trial ``update`` on
measured data.

The law's parameters live here too: :class:`PDGains`, the forgetting factor
(:class:`FixedForgetting`, :class:`VariableForgetting`; ``values()`` is the range analysis and
synthesis read), the Q-filter (:class:`QFilter`) and the PD gains file
(:func:`load_gains`, :func:`save_gains`). A law's description (:func:`describe_law`,
:func:`law_from_description`, the kinds of :data:`LAW_KINDS`) is what a design file stores.

Laws: :class:`PDLaw` (eq 11 of the paper), :class:`QLLaw` (heuristic Q/L filters, non-causal and
zero-phase allowed, :meth:`QLLaw.inverse_model`, with ``dc_cutoff`` for a loop whose
controller integrates), :class:`GradientLaw`, :class:`NormOptimalLaw` (Amann/Owens and
Gunnarsson-Norrlöf, optional step size), :class:`TimeReversalLaw` (model-free, extra
experiments), :class:`ConstrainedNormOptimalLaw` (norm-optimal with input, rate and output
bounds, an input weight and a step size: a QP per trial through CasADi; its lifted form is the
unconstrained law), :class:`NonlinearNormOptimalLaw`
(Gauss-Newton on the nonlinear trial map with model correction; its lifted form is the
linearized norm-optimal law, :meth:`NonlinearNormOptimalLaw.linearized`).

:func:`ilc_analysis.testing.check_law` checks any law (a user's own included) against the
specifications every law must meet: its lifted form reproduces its ``update``, its description
rebuilds it, its frequency response is its lifted operator's on a long trial, and the analysis'
verdicts hold in simulation.

The PD law and the index convention
-----------------------------------
The open-closed-loop PD-ILC law with forgetting (eq 11) is

.. math::

    u_{i+1}(t) = a(i,t)\,u_0(t) + (1-a(i,t))\,u_i(t)
        + \Phi_1\dot e_i(t) + \Psi_1 e_i(t) + \Phi_2\dot e_{i+1}(t) + \Psi_2 e_{i+1}(t),

with :math:`e_i = y_d - y_i`. The variable forgetting factor (eq 12) is

.. math::

    a(i,t) = \frac{1-\delta}{5^{\max_j[\Lambda e_{i,j}^2(t)]}},

the max taken over the output channels j at each t (the toolkit's documented reading).

Sampled-data convention (used identically by lifting, simulation, analysis and synthesis):
With sample time :math:`T_s`, trial length N and the sampled relative degree (shift) s >= 1:

* lifted input :math:`u = [u(0); \dots; u(N-1)]`, lifted output and error
  :math:`y = [y(s); \dots; y(N-1+s)]`, :math:`e = y_d - y` on the same window;
* derivative: backward difference :math:`\dot e(j) \approx (e(j) - e(j-1))/T_s`; the error just
  before the window is taken as zero (Assumption 2: :math:`x_i(0) = x_d(0)`);
* previous-trial (open-loop) term at sample k uses :math:`e_i(k+s+\ell)` and its difference,
  :math:`\ell` = ``lead`` >= 0 extra samples of anticipation; indices past the trial are zero;
* current-trial (closed-loop) term at sample k uses the error *measured* at sample k,
  :math:`e_{i+1}(k)` (lifted index k - s), and its difference; errors before the window
  (k < s) are zero. It is causal: u(k) depends on y(j) only for j <= k;
* forgetting: :math:`a(i,k)` is evaluated from :math:`e_i(k+s)` (the aligned error).

In lifted form, with :math:`A_i = \mathrm{diag}(a(i,k)) \otimes I`,

.. math::

    u_{i+1} = (I + L_2 G)^{-1}\left[(I - A_i - L_1 G)u_i + A_i u_0 + (L_1 + L_2)(y_d - d)\right].
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._base import LawOperators, LawResponse, LearningLaw, LiftedLaw
from ._constrained import ConstrainedNormOptimalLaw, InfeasibleTrialError, TrialCertificate
from ._forgetting import FixedForgetting, VariableForgetting
from ._gains import PDGains
from ._gains_file import load_gains, save_gains
from ._gradient import GradientLaw, TimeReversalLaw
from ._nonlinear import GaussNewtonCertificate, NonlinearNormOptimalLaw
from ._norm_optimal import NormOptimalLaw
from ._pd import PDLaw
from ._qfilter import QFilter
from ._ql import LTIFilter, QLLaw
from ._registry import LAW_KINDS, InverseModelLaw, describe_law, law_from_description

__all__ = [
    "LearningLaw", "LiftedLaw", "LawOperators", "LawResponse", "PDLaw", "PDGains",
    "FixedForgetting", "VariableForgetting", "QFilter", "QLLaw", "LTIFilter", "InverseModelLaw",
    "GradientLaw",
    "TimeReversalLaw", "NormOptimalLaw", "ConstrainedNormOptimalLaw", "TrialCertificate",
    "InfeasibleTrialError", "NonlinearNormOptimalLaw", "GaussNewtonCertificate", "LAW_KINDS",
    "describe_law", "law_from_description", "load_gains", "save_gains",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
