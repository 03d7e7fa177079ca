"""Tests of sklearn_gpcd.diagnosis: concealed effects in simulated recordings.

Each scenario injects effects into the simulator (the diagnosis only sees
the nominal model: the simulator's robot, torque constants, rotor inertias
and nominal friction) and checks that the diagnosis names them on the right
joints with parameters within 20 %, that the held-out nMSE improves, and
that a control run yields nothing. Every library effect alone, injected and
identified through the effect registry, is in ``tests/test_effect_registry.py``.
"""

import json

import numpy as np
import pytest

from sklearn_gpcd.datasets import (
    CurrentDelay,
    FrictionDelta,
    Payload,
    TorqueConstantError,
    default_friction,
    simulate_d1,
)
from sklearn_gpcd.datasets._extra_effects import delay_logged_current
from sklearn_gpcd.datasets.plant import drive_parameters
from sklearn_gpcd.diagnosis import (
    DiagnosedModel,
    DynamicsDiagnosis,
    NominalModel,
    Signals,
    align_recordings,
    effect_library,
    residual_breakdown,
)
from sklearn_gpcd.io import Recording
from sklearn_gpcd.robots import load_robot

N_TRAIN, N_TEST = 8, 5  # random targets: ~26 s and ~17 s of robot time


@pytest.fixture(scope="module")
def nominal():
    """The simulator's own nominal model: robot with its drive data and friction."""
    robot = load_robot("ur10")
    k, rotor = drive_parameters(robot)
    return load_robot("ur10", torque_constants=k, rotor_inertias=rotor), default_friction(robot)


def _one_hot(joint, value, n=6):
    out = [0.0] * n
    out[joint] = value
    return out


def _simulate(effects=(), delay=None, seed=1):
    train = simulate_d1("ur10", n_targets=N_TRAIN, effects=list(effects), random_state=seed)
    test = simulate_d1("ur10", n_targets=N_TEST, effects=list(effects), random_state=seed + 100)
    if delay:
        train, test = delay_logged_current(train, delay), delay_logged_current(test, delay)
    return train, test


def _diagnose(nominal, train):
    robot, friction = nominal
    return DynamicsDiagnosis(robot, friction=friction).fit(train)


def _check(diag, test, expected):
    """Every expected (name, joints, params) found, nothing else, held-out nMSE improved."""
    found = {}
    for fitted in diag.effects_:
        found.setdefault(fitted.name, []).append(fitted)
    assert sorted(found) == sorted(expected), [f"{f.name}{f.joints}" for f in diag.effects_]
    touched = set()
    for name, (joints, params) in expected.items():
        fits = found[name]
        if fits[0].effect.per_joint:
            assert sorted(f.target for f in fits) == sorted(joints), name
        else:
            assert set(joints) <= set(fits[0].joints), name
        touched |= set(joints)
        for key, truth in params.items():
            value = fits[0].parameters[key][0]
            assert value == pytest.approx(truth, rel=0.2), (name, key, value, truth)
    scores = diag.evaluate(test)
    before, after = np.array(scores["nmse_before"]), np.array(scores["nmse_after"])
    joints = sorted(touched)
    assert after[joints].sum() < 0.8 * before[joints].sum(), (before, after)
    return scores


# ------------------------------------------------------------ default scenarios
def test_control_yields_no_effect(nominal):
    train, test = _simulate()
    diag = _diagnose(nominal, train)
    assert diag.effects_ == []
    report = diag.report(test)
    assert "Nothing" in report.text()
    assert report.to_dict()["effects"] == []
    np.testing.assert_allclose(report.nmse_before, report.nmse_after)


def test_payload_found_with_mass_and_com(nominal):
    train, test = _simulate([Payload(3.0, com=(0.0, 0.03, 0.06))])
    diag = _diagnose(nominal, train)
    _check(diag, test, {"payload": ([1, 2, 3, 4], {"mass": 3.0, "com_y": 0.03, "com_z": 0.06})})
    mass, std = diag.effects_[0].parameters["mass"]
    assert 0 < std < 0.2


def test_coulomb_friction_found_on_its_joint(nominal):
    extra = _one_hot(2, 3.0)
    train, test = _simulate([FrictionDelta(coulomb=extra, static=extra)])
    _check(_diagnose(nominal, train), test, {"coulomb_friction": ([2], {"delta_coulomb": 3.0})})


def test_torque_constant_found(nominal):
    train, test = _simulate([TorqueConstantError([1, 1, 1, 0.85, 1, 1])])
    _check(_diagnose(nominal, train), test, {"torque_constant": ([3], {"scale": 0.85})})


def test_two_effects_payload_and_stribeck_both_found(nominal):
    train, test = _simulate([Payload(2.0, com=(0.0, 0.0, 0.05)),
                             FrictionDelta(static=_one_hot(1, 6.0))])
    expected = {"payload": ([1, 2, 3], {"mass": 2.0, "com_z": 0.05}),
                "stribeck_friction": ([1], {"delta_stribeck": 6.0,
                                            "stribeck_velocity": 0.02})}
    _check(_diagnose(nominal, train), test, expected)


def test_opposite_coulomb_and_viscous_changes_on_one_joint_both_found(nominal):
    # -3 Nm of Coulomb and +6 Nm s/rad of viscous friction cancel at 0.5 rad/s: tried one
    # at a time neither explains much; the pair is tested together (issue 39)
    train, test = _simulate([FrictionDelta(coulomb=_one_hot(1, -3.0), static=_one_hot(1, -3.0),
                                           viscous=_one_hot(1, 6.0))])
    _check(_diagnose(nominal, train), test,
           {"coulomb_friction": ([1], {"delta_coulomb": -3.0}),
            "viscous_friction": ([1], {"delta_viscous": 6.0})})


def test_delay_next_to_a_payload_is_named_as_a_delay(nominal):
    # the payload dominates the nominal residual of joints 2-4; the delay must still be
    # judged on the joint where it shows most, and named as a delay, not as friction
    train, test = _simulate([Payload(3.0, com=(0.0, 0.03, 0.06))], delay=0.032)
    diag = _diagnose(nominal, train)
    named = {f.name for f in diag.effects_}
    assert {"payload", "time_delay"} <= named, named
    assert not named & {"viscous_friction", "rotor_inertia"}, named
    fitted = {f.name: f for f in diag.effects_}
    assert fitted["time_delay"].parameters["delay"][0] == pytest.approx(0.032, rel=0.2)
    assert fitted["payload"].parameters["mass"][0] == pytest.approx(3.0, rel=0.2)


def test_every_named_effect_passes_the_held_out_test_given_the_others(nominal):
    # significance does not relax after a large finding: each reported effect's evidence
    # is its held-out test in the final model (all other effects in), and it passes it
    train, _ = _simulate([Payload(3.0, com=(0.0, 0.03, 0.06)),
                          TorqueConstantError([1, 1, 1, 0.85, 1, 1])], delay=0.016)
    diag = _diagnose(nominal, train)
    assert len(diag.effects_) >= 3
    for fitted in diag.effects_:
        assert fitted.evidence.eligible(diag.min_gain, diag.min_t), fitted.name
        assert fitted.joint_share >= diag.min_share, fitted.name


def test_logged_current_delay_found(nominal):
    train, test = _simulate(delay=0.016)
    _check(_diagnose(nominal, train), test, {"time_delay": ([0, 1, 2], {"delay": 0.016})})


def test_command_delay_is_not_a_missing_effect(nominal):
    """The simulator's CurrentDelay delays the current command: the logged current
    still drives the joints, so inverse dynamics has nothing to add."""
    train, _ = _simulate([CurrentDelay(0.004)])
    assert _diagnose(nominal, train).effects_ == []


# ---------------------------------------------------------- pair / base model
def test_pair_mode_simulated_and_real_runs(nominal):
    """Reference = a simulated run of the same trajectory, time-aligned by the package."""
    robot, friction = nominal
    real = simulate_d1("ur10", n_targets=N_TRAIN, effects=[Payload(2.5)], random_state=5)
    sim = simulate_d1("ur10", n_targets=N_TRAIN, random_state=5)
    sim = sim.slice(10, None)  # the simulated log starts later: needs alignment
    diag = DynamicsDiagnosis(robot, effects=["payload", "coulomb_friction", "viscous_friction",
                                             "torque_constant"]).fit(real, simulated=sim)
    assert [e.name for e in diag.effects_] == ["payload"]
    assert diag.effects_[0].parameters["mass"][0] == pytest.approx(2.5, rel=0.2)
    assert diag.training_summary_["alignment_lags"][0] == pytest.approx(-0.08, abs=0.01)


def test_base_model_diagnoses_against_a_refined_model(nominal):
    robot, _ = nominal
    train, _ = _simulate()
    first = DynamicsDiagnosis(robot, effects=["coulomb_friction", "viscous_friction",
                                              "stribeck_friction"]).fit(train)
    assert {e.name for e in first.effects_} >= {"coulomb_friction", "viscous_friction"}
    loaded = simulate_d1("ur10", n_targets=N_TRAIN, effects=[Payload(2.0)], random_state=7)
    second = DynamicsDiagnosis(base_model=first.model_,
                               effects=["payload", "coulomb_friction"]).fit(loaded)
    assert [e.name for e in second.effects_] == ["payload"]
    assert second.effects_[0].parameters["mass"][0] == pytest.approx(2.0, rel=0.2)


# ---------------------------------------------------------------- model / GP
def test_refined_model_as_parametric_mean(nominal):
    from sklearn_gpcd.gp import ParametricMean

    robot, friction = nominal
    train, _ = _simulate([Payload(3.0)])
    diag = _diagnose(nominal, train)
    X = np.hstack([train.q, train.qd, train.qdd])
    moving = np.all(np.abs(train.qd) > 1e-3, axis=1)
    pred = diag.model_.predict_states(X)
    assert pred.shape == (train.n_samples, 6)
    joint = 2
    mean = ParametricMean(features=diag.model_.joint_features(joint))
    mean.fit(X[moving], train.current[moving, joint])
    # the least-squares gains reproduce the diagnosed coefficients
    np.testing.assert_allclose(mean.coef_, diag.model_.feature_coefficients(joint),
                               rtol=0.1, atol=0.05)
    residual = train.current[moving, joint] - mean.predict(X[moving])
    assert np.std(residual) < 0.1
    assert isinstance(diag.model_.parametric_mean(joint), ParametricMean)


def test_predict_recording_matches_states(nominal):
    train, _ = _simulate([Payload(1.0)])
    diag = _diagnose(nominal, train)
    by_recording = diag.predict(train)
    by_states = diag.model_.predict_states(np.hstack([train.q, train.qd, train.qdd]))
    np.testing.assert_allclose(by_recording, by_states, atol=1e-9)


# ------------------------------------------------------------- report / locate
def test_report_json_and_text(nominal, tmp_path):
    train, test = _simulate([Payload(2.0)])
    report = _diagnose(nominal, train).report(test)
    path = tmp_path / "out.json"
    report.to_json(path)
    data = json.loads(path.read_text())
    assert set(data) >= {"effects", "nmse_before", "nmse_after"}
    effect = data["effects"][0]
    assert set(effect) >= {"name", "joints", "parameters", "explained_variance", "evidence"}
    assert effect["name"] == "payload" and len(data["nmse_before"]) == 6
    assert data["nmse_heldout"] is True
    text = report.text()
    assert "payload of 2" in text and "held-out" in text
    # the evidence per recording: the payload's held-out gain on the training run
    gains = effect["stability"]["heldout_gain_per_recording"][0]
    assert len(gains) == 1 and gains[0] > 0.5
    assert "Held-out gain per recording (given the other effects):" in text


def test_report_plot(nominal, tmp_path):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    train, test = _simulate([Payload(2.0)])
    path = tmp_path / "fig.png"
    _diagnose(nominal, train).report(test).plot(path)
    assert path.stat().st_size > 1000


def test_residual_breakdown_locates_the_regime():
    robot = load_robot("ur10")
    nominal = NominalModel(robot)
    n = 400
    t = np.arange(n) * 0.01
    qd = np.zeros((n, 6))
    qd[100:300, 2] = 0.5
    X = np.hstack([np.zeros((n, 6)), qd, np.zeros((n, 6))])
    signals = Signals.from_states(nominal, X)
    signals.time = t
    residual = np.zeros((n, 6))
    residual[100:300, 2] = 1.0  # error only while joint 2 moves
    b = residual_breakdown(signals, residual)
    assert b.regimes["moving"]["share_of_error"][2] == pytest.approx(1.0)
    assert b.regimes["rest"]["share_of_error"][2] == pytest.approx(0.0)
    assert b.worst() == (2, "moving")
    assert b.rms_moving[2] == pytest.approx(1.0)


def test_align_recordings_recovers_the_lag():
    t = np.arange(0, 20, 0.008)
    q = np.column_stack([np.sin(0.7 * t + k) for k in range(6)])
    sim = Recording(time=t, q=q, qd=np.gradient(q, t, axis=0), current=3 * q)
    shift = 37
    real = Recording(time=t[:-shift] + 100.0, q=q[shift:], qd=sim.qd[shift:],
                     current=3 * q[shift:])
    ref, tau = align_recordings(sim, real)
    assert tau == pytest.approx(shift * 0.008, abs=1e-3)
    np.testing.assert_allclose(ref[5:-5], real.current[5:-5], atol=1e-3)


# --------------------------------------------------------------------- errors
def test_unknown_effect_name_raises():
    with pytest.raises(ValueError, match="unknown effect 'gravity'"):
        effect_library(["gravity"])


def test_missing_torque_constants_raise():
    with pytest.raises(ValueError, match="no torque constants"):
        NominalModel("ur5")


def test_wrong_joint_count_raises(nominal):
    rec = Recording(time=np.arange(40) * 0.01, q=np.zeros((40, 2)), qd=np.zeros((40, 2)),
                    current=np.zeros((40, 2)), name="two.csv")
    with pytest.raises(ValueError, match="'two.csv' has 2 joints"):
        DynamicsDiagnosis(nominal[0]).fit(rec)


def test_bad_parameters_raise(nominal):
    train, _ = _simulate()
    with pytest.raises(ValueError, match="n_splits"):
        DynamicsDiagnosis(nominal[0], n_splits=1).fit(train)
    with pytest.raises(ValueError, match="min_gain"):
        DynamicsDiagnosis(nominal[0], min_gain=2.0).fit(train)


def test_pair_mode_needs_one_simulated_run_per_recording(nominal):
    train, test = _simulate()
    with pytest.raises(ValueError, match="one simulated run per real recording"):
        DynamicsDiagnosis(nominal[0]).fit([train, test], simulated=[train])


def test_time_effects_skipped_on_bare_states(nominal):
    diag = DiagnosedModel(NominalModel(nominal[0]), [])
    assert diag.predict_states(np.zeros((3, 18))).shape == (3, 6)


@pytest.mark.realdata
def test_real_loaded_ur10e_run_carries_a_payload(ur10e_dir):
    """The "load_2600" run (presumably 2.6 kg) against the unloaded UR10e model."""
    import warnings

    from sklearn_gpcd.io import RecordingWarning, load_recording

    path = ur10e_dir / "identification_data" / "ur-20_01_13-load_2600.csv"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        rec = load_recording(path)
    diag = DynamicsDiagnosis(load_robot("ur10e")).fit(rec)
    payload = [e for e in diag.effects_ if e.name == "payload"]
    assert payload, [e.name for e in diag.effects_]
    assert 2.0 < payload[0].parameters["mass"][0] < 3.2


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("control", ["ur-20_02_19_14harm50sec.csv",
                                     "ur-20_02_19_15harm50sec.csv", "ur-20_01_31-unload.csv"])
def test_real_unloaded_ur10e_run_carries_no_payload(ur10e_dir, control):
    """An unloaded run against a model calibrated on the other unloaded runs: no payload."""
    import warnings

    from sklearn_gpcd.io import RecordingWarning, load_recording

    names = ["ur-20_02_19_14harm50sec.csv", "ur-20_02_19_15harm50sec.csv",
             "ur-20_01_31-unload.csv"]
    folder = ur10e_dir / "identification_data"
    if not all((folder / n).is_file() for n in names):
        pytest.skip(f"unloaded runs not found in {folder}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        recs = {n: load_recording(folder / n) for n in names}
    robot = load_robot("ur10e")
    calibration = DynamicsDiagnosis(robot).fit([recs[n] for n in names if n != control])
    diag = DynamicsDiagnosis(base_model=calibration.model_).fit(recs[control])
    assert "payload" not in [e.name for e in diag.effects_]
