"""A quick detector and recordings for the live-monitoring and model-file tests.

A linear regressor on the causal inputs of simulated 500 Hz UR10e runs stands
in for a GP (the session, the link and the files are under test, not the
model); pushes are current bumps the controller's target current does not
explain.
"""

import numpy as np
from sklearn.linear_model import LinearRegression

from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
from sklearn_gpcd.features import CausalFeatures

RATE = 500.0
#: Push amplitude [A] and length [s] (2 A on one joint for 0.3 s).
PUSH_A, PUSH_S = 2.0, 0.3


def free_runs(n=3, n_targets=2):
    """Collision-free 500 Hz UR10e runs (seeds 0..n-1)."""
    return [simulate_d1("ur10e", n_targets=n_targets, sample_rate=RATE, random_state=s)
            for s in range(n)]


def linear_bundle(recordings):
    """``(detector, features)``: per-joint thresholds at 1.5x the largest excursion."""
    features = CausalFeatures().fit(recordings)
    X = np.vstack([stack_currents(features.transform(r), r.current) for r in recordings])
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=1.5, filter_cutoff=10.0,
                     min_duration=5)
    detector = CollisionDetector(LinearRegression(), n_joints=6, sample_time=1 / RATE,
                                 rules=rule).fit(X)
    return detector, features


def with_pushes(recording, starts, joint=1):
    """``recording`` with a push at each of ``starts`` [s from its start]."""
    t = recording.time - recording.time[0]
    current = recording.current.copy()
    for start in starts:
        current[(t >= start) & (t < start + PUSH_S), joint] += PUSH_A
    return recording.replace(current=current)
