"""Issue acceptance: the paper's human-interaction test on the simulator (Sec. V-B).

SP_P is trained on a small D1 (collision-free random targets), its detector
is calibrated on a collision-free D2 run it was not trained on, and then it
watches the interaction test: a circle, then rest, with four pushes on link 1
(two while moving, two at rest). Every push must raise an alarm, and no
sample outside the pushes may alarm — in the rest phases (including the
stretch after the last push) or while moving.

Detection runs on the causal path (``CausalFeatures``: no look-ahead), the
one that can run on the robot; the model is trained on the zero-phase inputs.
"""

import numpy as np
import pytest
from _synthetic import assert_raw_stream_equals_batch

from sklearn_gpcd import datasets
from sklearn_gpcd.detection import StreamingMonitor, stack_currents
from sklearn_gpcd.experiments.paper import (
    PaperConfig,
    _commanded_rest,
    build_estimators,
    make_detector,
)
from sklearn_gpcd.features import CausalFeatures, make_inputs
from sklearn_gpcd.robots import load_robot

CONFIG = PaperConfig(d1_targets=12, d2_targets=3, n_support=400, batch_size=200,
                     rest_duration=12.0)


@pytest.fixture(scope="module")
def interaction():
    robot = load_robot("ur10")
    d1 = datasets.simulate_d1(robot, n_targets=CONFIG.d1_targets, random_state=1)
    d2 = datasets.simulate_d2(robot, n_targets=CONFIG.d2_targets, n_turns=0.5, random_state=2)
    test = datasets.simulate_interaction_test(robot, n_turns=0.5,
                                          rest_duration=CONFIG.rest_duration, random_state=3)
    sp_p = build_estimators(robot, CONFIG, random_state=0, n_jobs=2)["SP_P"]
    sp_p.fit(*make_inputs(d1))
    causal = CausalFeatures().fit(d1)
    detector = make_detector(sp_p, robot.n_joints).fit(
        stack_currents(causal.transform(d2), d2.current))
    Z = stack_currents(causal.transform(test), test.current)
    return detector, Z, test, causal


def test_every_push_is_detected(interaction):
    detector, Z, test, _ = interaction
    alarms = detector.predict(Z) == -1
    rest = _commanded_rest(test, CONFIG.sigma_v)
    kinds = []
    for k in range(1, 5):
        push = test.labels == k
        assert alarms[push].any(), f"push {k} was not detected"
        kinds.append("rest" if rest[push].all() else "moving")
    assert kinds == ["moving", "moving", "rest", "rest"]


def test_no_alarm_outside_the_pushes(interaction):
    detector, Z, test, _ = interaction
    alarms = detector.predict(Z) == -1
    free = test.labels == 0
    rest = _commanded_rest(test, CONFIG.sigma_v)
    assert (free & rest).sum() > 1000  # the rest phases are really checked
    assert not alarms[free & rest].any(), "false alarm in a collision-free rest phase"
    assert not alarms[free & ~rest].any(), "false alarm while moving"


def test_streaming_monitor_agrees_with_batch(interaction):
    detector, Z, _, _ = interaction
    out = StreamingMonitor(detector).replay(Z)
    assert np.array_equal(out.prediction, detector.predict(Z))


def test_raw_samples_through_the_monitor_agree_with_batch(interaction):
    """From raw robot samples (t, q, qd, i, targets) to decisions == batch, sample for sample."""
    detector, _, test, causal = interaction
    out = assert_raw_stream_equals_batch(detector, causal, test)
    assert (out.prediction == -1).any()
