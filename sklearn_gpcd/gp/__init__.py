"""Semi-parametric Gaussian Process regression (Dalla Libera et al., Sec. III-IV).

* :class:`ParametricMean` -- the rigid-body + friction mean with deterministic
  parameters (Eq. 8-10, :math:`\\bar\\phi` of Eq. 17);
* :class:`SemiParametricGPRegressor` -- one GP per output on the residual of
  the mean, hyperparameters by maximum marginal likelihood;
* :func:`make_p_f`, :func:`make_sp_s`, :func:`make_sp_p` -- the paper's three
  estimators P_f, SP_S and SP_P built from a feature layout;
* :func:`make_sp_c` -- our extension: the controller's target current as the
  parametric mean, a GP correction on top;
* :func:`resolve_n_support` -- how many support rows ``n_support`` (an int,
  ``"auto"`` or None) stands for on a given number of training rows;
* :func:`compile_predictor` -- one input row at a time, in preallocated
  buffers (the streaming monitor's prediction).
"""

from .compiled import compile_predictor
from .factories import make_p_f, make_sp_c, make_sp_p, make_sp_s
from ._posterior import GPPosterior
from .mean import ParametricMean
from .regressor import SemiParametricGPRegressor
from ._support import resolve_n_support

__all__ = [
    "SemiParametricGPRegressor",
    "ParametricMean",
    "GPPosterior",
    "make_p_f",
    "make_sp_s",
    "make_sp_p",
    "make_sp_c",
    "resolve_n_support",
    "compile_predictor",
]
