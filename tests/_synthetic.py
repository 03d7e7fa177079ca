"""Synthetic runs shared by the detection and streaming test modules."""

import numpy as np
from sklearn_gpcd.detection import AlarmRule, Regimes


def augmented_run(n_samples, n_joints, rng, period=0.008):
    """Inputs x^a (Eq. 13) and currents of a move-rest-move-rest run.

    Every joint rests (|qd| = 0, all gates open) in the 2nd and 4th quarter.
    """
    t = np.arange(n_samples) * period
    phase = rng.uniform(0, np.pi, n_joints)
    moving = (np.arange(n_samples) // (n_samples // 4)) % 2 == 0
    qd = np.where(moving[:, None], np.cos(t[:, None] + phase), 0.0)
    q = np.cumsum(qd, axis=0) * period
    qdd = np.gradient(qd, period, axis=0)
    e_q = 1e-3 * np.sin(3 * t[:, None] + phase)
    de_q = np.gradient(e_q, period, axis=0)
    clean = 2.0 * np.sin(q) + 0.5 * np.tanh(50 * qd) + 0.1 * qdd
    i_c = clean + 0.05
    X = np.hstack([q, qd, qdd, e_q, de_q, i_c])
    current = clean + 0.02 * rng.normal(size=clean.shape)
    return X, current


def assert_raw_stream_equals_batch(detector, features, recording):
    """Raw samples through StreamingMonitor.update_raw == the batch detector.

    Returns the streaming result (a Bunch, see ``replay_recording``).
    """
    from sklearn_gpcd.detection import StreamingMonitor, stack_currents

    out = StreamingMonitor(detector, features=features).replay_recording(recording)
    Z = stack_currents(features.transform(recording), recording.current)
    batch = detector.monitoring_signal(Z)
    assert np.array_equal(out.prediction, detector.predict(Z))
    np.testing.assert_allclose(out.signal, batch.signal, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(out.regime, batch.regime)
    return out


def simulated_interaction():
    """A simulated UR10 interaction test (pushes at rest) and a collision-free D2 run."""
    from sklearn_gpcd import datasets

    rec = datasets.simulate_interaction_test("ur10", n_turns=0.2, rest_duration=8.0, random_state=0)
    free = datasets.simulate_d2("ur10", n_targets=2, n_turns=0.3, random_state=1)
    return rec, free


def controller_detector():
    """The controller's current as the model, per-joint regime thresholds, rest
    reference: a detector that calibrates in milliseconds on simulated runs."""
    from sklearn_gpcd.detection import CollisionDetector
    from sklearn_gpcd.dynamics import ControllerCurrent

    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0, min_duration=5,
                     regimes=Regimes(rest_reference=5.0))
    return CollisionDetector(ControllerCurrent(6), n_joints=6, sample_time="auto", rules=rule)


#: The fast band of the multi-band tests: 10 Hz first order, debounce 2.
FAST = {"filter_cutoff": 10.0, "filter_order": 1, "min_duration": 2}


def banded(detector, *bands):
    """``detector`` with its (single) rule followed by one rule per override in
    ``bands`` (default: :data:`FAST`): several bands on one model."""
    from sklearn.base import clone

    rule = detector.rules if detector.rules is not None else AlarmRule()
    extra = [clone(rule).set_params(**band) for band in (bands or (FAST,))]
    return clone(detector).set_params(rules=[clone(rule), *extra])


def benchmark_module(name):
    """The script ``benchmarks/<name>.py`` as a module (its folder on the path, for
    the benchmarks' shared helpers)."""
    import importlib.util
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    sys.path.insert(0, str(script.parent))
    spec = importlib.util.spec_from_file_location(name, script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
