"""scikit-learn kernels for the semi-parametric collision-detection GP.

Real subclasses of ``sklearn.gaussian_process.kernels.Kernel``, composable
with sklearn's ``+``, ``*``, ``ConstantKernel`` and ``WhiteKernel``:

* :class:`ARDRBF` -- squared-exponential ARD kernel on chosen columns (Eq. 11);
* :class:`QuasiStaticGate` -- a kernel switched on at low velocity (Eq. 14-17);
* :class:`ParametricKernel` -- :math:`\\phi \\Sigma \\phi^T` of a linear model
  with Gaussian weights (Sec. III-A);
* :func:`resolve_columns` -- column names to indices in a kernel tree;
* :func:`contract_gradient` -- the log-marginal-likelihood gradient
  contraction in O(n^2) memory;
* :mod:`sklearn_gpcd.kernels.plan` -- the compiled kernel algebra: one
  registry from kernel type to node (Gram matrix, gradient contraction,
  one-row prediction, gated blocks, initial hyperparameters) used by the
  fit, ``predict``, the optimizer and the streaming monitor.

Examples
--------
The kernel of the proposed model (Eq. 17) for one joint of a 1-joint robot,
on the augmented inputs ``[q, qd, qdd, e_q, de_q, i_c]`` of Eq. 13:

>>> from sklearn.gaussian_process.kernels import ConstantKernel as C, WhiteKernel
>>> from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate
>>> kinetic = C() * ARDRBF([1.0, 1.0, 1.0], columns=["q_0", "qd_0", "qdd_0"])
>>> static = QuasiStaticGate(C() * ARDRBF(1.0), velocity_column="qd_0")
>>> kernel = kinetic + static + WhiteKernel()
>>> kernel.theta.shape
(7,)
"""

from .ard import ARDRBF
from .columns import resolve_columns
from .contraction import contract_gradient
from .gate import QuasiStaticGate
from .parametric import ParametricKernel
from .plan import OpaqueKernelWarning

__all__ = [
    "ARDRBF",
    "QuasiStaticGate",
    "ParametricKernel",
    "resolve_columns",
    "contract_gradient",
    "OpaqueKernelWarning",
]
