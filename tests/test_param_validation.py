"""Every estimator declares ``_parameter_constraints`` and validates them in ``fit``.

sklearn's ``check_param_validation`` sets each parameter to values outside
its constraints and expects ``fit`` to raise ``InvalidParameterError`` naming
it, before any data is read (so it runs on estimators whose data the generic
checks cannot build, e.g. recordings or the augmented layout).
"""

import pytest
from sklearn.utils.estimator_checks import check_param_validation

from sklearn_gpcd.detection import CollisionDetector, CollisionThresholdCV
from sklearn_gpcd.diagnosis import DynamicsDiagnosis
from sklearn_gpcd.dynamics import (
    ControllerCurrent,
    ControllerFeatures,
    MomentumObserver,
    RigidBodyFeatures,
)
from sklearn_gpcd.features import CausalFeatures, InverseDynamicsFeatures
from sklearn_gpcd.gp import ParametricMean, SemiParametricGPRegressor

ESTIMATORS = [
    RigidBodyFeatures("ur5"),
    ControllerFeatures(joint=0, n_joints=1),
    ControllerCurrent(1),
    MomentumObserver("ur10"),
    CausalFeatures(),
    InverseDynamicsFeatures(),
    DynamicsDiagnosis("ur10"),
    ParametricMean(),
    SemiParametricGPRegressor(),
    CollisionDetector(),
    CollisionThresholdCV(CollisionDetector(), {"rules__contamination": [0.01]}),
]


@pytest.mark.parametrize("estimator", ESTIMATORS, ids=lambda e: type(e).__name__)
def test_invalid_parameters_are_refused_in_fit(estimator):
    assert set(estimator._parameter_constraints) == set(estimator.get_params(deep=False))
    check_param_validation(type(estimator).__name__, estimator)
