r"""``lift``: one entry point from a sampled plant to its :class:`LiftedSystem`.

* linear time-invariant plants (``dplant.matrices`` set): exact block Toeplitz of Markov
  parameters and the free response (:mod:`.lti_lifting`);
* nonlinear or time-varying plants: :math:`G = \partial y/\partial u` of the compiled CasADi
  trial map along ``u_nominal`` and :math:`d = y(u_{nom}) - G u_{nom}`, the LTV lifted model
  of deviations about that trial (:mod:`.trial_map`).
"""

from __future__ import annotations

from .._progress import progress
from ..model import DiscretePlant
from ._lifted_system import LiftedSystem
from ._lti_lifting import lift_lti
from ._trial_arguments import trial_arguments
from ._trial_map import lift_nonlinear

__all__ = ["lift"]


def lift(dplant: DiscretePlant, N: int, *, x0=None, u_nominal=None, w=None, t0: float = 0.0,
         shift: int | None = None) -> LiftedSystem:
    r"""The lifted trial :math:`y = G u + d` of a sampled plant (docs/theory.md §8).

    Parameters
    ----------
    dplant : DiscretePlant
        From :func:`ilc_analysis.model.discretize` or ``DiscretePlant.from_statespace``.
    N : int
        Trial length in samples, >= 1. Input window u(0..N-1), output window y(s..N-1+s).
    x0 : array_like, optional
        Initial state ``(n_x,)`` (default zero).
    u_nominal : array_like, optional
        Nominal input ``(N, n_u)`` the nonlinear lifting is taken along (default zero).
        Ignored by the exact LTI lifting, whose G does not depend on it.
    w : array_like, optional
        Known state disturbance ``(N, n_x)`` held over each sample (enters d).
    t0 : float
        Time of sample 0 [s].
    shift : int, optional
        The output-window shift s. Default: :func:`sampled_shift` (for nonlinear plants at
        ``(x0, u_nominal[0], t0)``).

    Returns
    -------
    LiftedSystem

    Raises
    ------
    ParameterError
        N < 1, N above :data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES` or a dense G
        above :data:`~ilc_analysis._validation.MAX_LIFTED_ENTRIES` (the message gives the
        estimated GiB), a non-DiscretePlant, a negative shift, or a trial that overflows.
    ShapeError
        ``x0``, ``u_nominal`` or ``w`` of the wrong shape (expected and found shapes given).

    Examples
    --------
    >>> import control
    >>> from ilc_analysis.model import DiscretePlant
    >>> dp = DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0]], [[1.0]], 0, 0.1))
    >>> lift(dp, 3).G
    array([[1.  , 0.  , 0.  ],
           [0.5 , 1.  , 0.  ],
           [0.25, 0.5 , 1.  ]])
    """
    # dense: also refuses a lifted matrix beyond the memory cap
    dplant, N, x0, u_nom, w, t0, shift = trial_arguments(
        dplant, N, x0=x0, u_nominal=u_nominal, w=w, t0=t0, shift=shift, dense=True)
    with progress(desc=f"lifting {dplant.name} (N = {N}, dense)", unit="step") as bar:
        if dplant.matrices is not None:
            out = lift_lti(dplant, N, shift, x0=x0, w=w, t0=t0)
        else:
            out = lift_nonlinear(dplant, N, shift, x0=x0, u_nominal=u_nom, w=w, t0=t0)
        bar.update()
    return out
