"""scikit-learn API conformance of the estimators in ``sklearn_gpcd.gp``."""

import numpy as np
from sklearn.preprocessing import PolynomialFeatures
from sklearn.utils.estimator_checks import parametrize_with_checks

from sklearn_gpcd.gp import ParametricMean, SemiParametricGPRegressor


def linear_and_sign(X):
    """A simple feature map ``[X, sign(X_0)]`` (module level so it pickles)."""
    return np.column_stack([X, np.sign(X[:, 0])])


@parametrize_with_checks(
    [
        SemiParametricGPRegressor(random_state=0),
        SemiParametricGPRegressor(mean=ParametricMean(), normalize_y=True, random_state=0),
        ParametricMean(),
        ParametricMean(linear_and_sign, friction_columns=[-1], velocity_column=0, sigma_v=0.1),
        ParametricMean(PolynomialFeatures(degree=1), alpha=1e-3, fit_intercept=True),
    ]
)
def test_sklearn_compatible(estimator, check):
    check(estimator)
