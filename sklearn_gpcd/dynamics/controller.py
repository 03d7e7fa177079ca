"""The robot controller's own current model as parametric features.

Industrial controllers already compute the current each joint should draw:
a UR logs it as ``target_current`` (RTDE), the paper's :math:`i_c` (the last
block of :math:`x^a`, Eq. 13). It is the vendor's model, identified on the
very arm, so it is the best parametric prior there is: used as the feature
map :math:`\\phi_\\ell(x) = [\\,i_{c,\\ell}\\,]` of a
:class:`~sklearn_gpcd.gp.ParametricMean`, the GP of the semi-parametric
model (Sec. III-A) only learns the correction on top of it,

.. math:: i_\\ell = w_\\ell\\, i_{c,\\ell} + f_\\ell(x) + e .

This is our extension of the paper (which uses the rigid-body features
there); :func:`~sklearn_gpcd.gp.make_sp_c` builds it.
"""

from numbers import Integral

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, TransformerMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from ..layout import AUGMENTED_BLOCKS, column_index
from .._persistence import VersionedStateMixin


class ControllerFeatures(VersionedStateMixin, TransformerMixin, BaseEstimator):
    """Select one joint's controller signal (e.g. ``i_c``) as the feature map.

    Parameters
    ----------
    joint : int
        Joint (0-based).
    n_joints : int
        Number of joints of the input layout (:mod:`sklearn_gpcd.layout`).
    block : str, default="i_c"
        Block of the augmented layout to select (``"i_c"``: the controller's
        target current).

    Attributes
    ----------
    column_ : int
        Column of ``X`` selected.
    friction_columns_ : list of int
        Empty: the controller's model has no separate friction column.
    n_features_in_ : int
        Columns of ``X`` seen in ``fit``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import ControllerFeatures
    >>> X = np.arange(12.0).reshape(1, 12)         # augmented layout, 2 joints
    >>> ControllerFeatures(joint=1, n_joints=2).fit_transform(X).tolist()
    [[11.0]]
    """

    _parameter_constraints = {
        "joint": [Interval(Integral, 0, None, closed="left")],
        "n_joints": [Interval(Integral, 1, None, closed="left")],
        "block": [StrOptions(set(AUGMENTED_BLOCKS))],
    }

    def __init__(self, joint, n_joints, block="i_c"):
        self.joint = joint
        self.n_joints = n_joints
        self.block = block

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Check the layout and find the column.

        Parameters
        ----------
        X : array-like of shape (n_samples, 6 * n_joints)
            Inputs in the augmented layout.
        y : None
            Ignored.

        Returns
        -------
        self : ControllerFeatures
        """
        X = validate_data(self, X, dtype=np.float64)
        if self.joint >= self.n_joints:
            raise ValueError(f"joint must be in [0, {self.n_joints}), got {self.joint!r}")
        self.column_ = column_index(self.block, self.joint, self.n_joints)
        if self.column_ >= X.shape[1]:
            raise ValueError(
                f"X has {X.shape[1]} columns; the {self.block} block of {self.n_joints} "
                f"joints needs the augmented layout ({6 * self.n_joints} columns)"
            )
        self.friction_columns_ = []
        return self

    def transform(self, X):
        """The selected column, shape (n_samples, 1).

        Parameters
        ----------
        X : array-like of shape (n_samples, 6 * n_joints)

        Returns
        -------
        Phi : ndarray of shape (n_samples, 1)
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        return X[:, [self.column_]]


class ControllerCurrent(VersionedStateMixin, RegressorMixin, BaseEstimator):
    """The controller's expected current as a predictor: the peer to beat.

    Predicts :math:`\\hat i_\\ell = i_{c,\\ell}`, the target current the
    controller logs (UR ``i_des``), with nothing learned, so that the
    robot's own residual :math:`i - i_{des}` goes through exactly the same
    detector (filter, debounce, regimes, thresholds) as a learned model:
    ``CollisionDetector(ControllerCurrent(6), n_joints=6)``.

    Parameters
    ----------
    n_joints : int
        Number of joints; ``X`` is in the augmented layout.

    Attributes
    ----------
    columns_ : list of int
        The ``i_c`` columns of ``X``.
    n_features_in_ : int
        Columns of ``X`` seen in ``fit``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import ControllerCurrent
    >>> X = np.arange(12.0).reshape(1, 12)              # 2 joints, augmented
    >>> ControllerCurrent(2).fit(X, np.zeros((1, 2))).predict(X).tolist()
    [[10.0, 11.0]]
    """

    _parameter_constraints = {"n_joints": [Interval(Integral, 1, None, closed="left")]}

    def __init__(self, n_joints):
        self.n_joints = n_joints

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y):
        """Check the layout (nothing is learned).

        Parameters
        ----------
        X : array-like of shape (n_samples, 6 * n_joints)
        y : array-like of shape (n_samples, n_joints)
            Ignored apart from its shape.

        Returns
        -------
        self : ControllerCurrent
        """
        X, y = validate_data(self, X, y, multi_output=True, dtype=np.float64)
        if X.shape[1] != 6 * self.n_joints:
            raise ValueError(
                f"X has {X.shape[1]} columns; ControllerCurrent(n_joints={self.n_joints}) "
                f"needs the augmented layout ({6 * self.n_joints} columns)"
            )
        self.columns_ = [column_index("i_c", j, self.n_joints) for j in range(self.n_joints)]
        return self

    def predict(self, X):
        """The logged target currents.

        Parameters
        ----------
        X : array-like of shape (n_samples, 6 * n_joints)

        Returns
        -------
        y : ndarray of shape (n_samples, n_joints), or (n_samples,) for one joint
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        out = X[:, self.columns_]
        return out[:, 0] if self.n_joints == 1 else out
