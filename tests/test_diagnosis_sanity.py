"""Input sanity, wording, plausibility and significance of the diagnosis (issue #16).

One test per defect found by trying the diagnosis as a new user would and on
physics it was not written against: recordings in degrees or milliseconds,
"-117 % better", joints numbered from 0, a spring "towards -88.2 rad", a
torque-constant scale of 0.05, a negative Stribeck peak, a 23.5 kg link
mass, effects named for a 0.1 % share of the residual, output paths found
unwritable only after the work.
"""

import json
import re

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import Payload, simulate_d1
from sklearn_gpcd.diagnosis import (
    Candidate,
    DynamicsDiagnosis,
    NominalModel,
    Signals,
    effect_library,
    forward_selection,
)
from sklearn_gpcd.diagnosis.effects import rated_payload
from sklearn_gpcd.diagnosis.report import relative_change
from sklearn_gpcd.diagnosis.selection import (
    build_candidates,
    fold_index,
    fold_statistics,
    plausibility_check,
    separating_excitation,
)
from sklearn_gpcd.io import Recording, write_rtde_csv


@pytest.fixture(scope="module")
def payload_run():
    return simulate_d1("ur10", n_targets=4, effects=[Payload(3.0)], random_state=3)


@pytest.fixture(scope="module")
def nominal():
    return NominalModel("ur10")


def _params(effect, **values):
    return {k: (v, 0.0) for k, v in values.items()}


# ------------------------------------------------------------------ units
def _replace(rec, **fields):
    data = {k: getattr(rec, k) for k in ("time", "q", "qd", "qdd", "current")}
    data.update(fields)
    return Recording(name=rec.name, units=rec.units, **data)


def test_recording_in_degrees_is_refused(payload_run):
    degrees = _replace(payload_run, q=np.rad2deg(payload_run.q))
    with pytest.raises(ValueError, match="degrees.*check_units=False"):
        DynamicsDiagnosis("ur10", effects=["payload"]).fit(degrees)


def test_recording_in_milliseconds_is_refused(payload_run):
    ms = _replace(payload_run, time=1000.0 * payload_run.time)
    with pytest.raises(ValueError, match="milliseconds"):
        DynamicsDiagnosis("ur10", effects=["payload"]).fit(ms)


def test_confirmed_units_are_diagnosed(payload_run):
    """check_units=False skips the refusal (the user vouches for the units)."""
    ms = _replace(payload_run, time=1000.0 * payload_run.time)
    diag = DynamicsDiagnosis("ur10", effects=["payload"], check_units=False).fit(ms)
    assert hasattr(diag, "model_")


def test_cli_refuses_degrees_unless_confirmed(payload_run, tmp_path, capsys):
    """`gpcd diagnose` on positions in degrees: exit 2 with a reason, not a spring at -88 rad."""
    path = tmp_path / "degrees.csv"
    write_rtde_csv(_replace(payload_run, q=np.rad2deg(payload_run.q)), path)
    status = main(["diagnose", "--robot", "ur10", str(path), "--effects", "joint_spring"])
    err = capsys.readouterr().err
    assert status == 2
    assert "error:" in err and "degrees" in err and "--units-confirmed" in err
    status = main(["diagnose", "--robot", "ur10", str(path), "--effects", "joint_spring",
                   "--units-confirmed"])
    out = capsys.readouterr().out
    assert status == 0
    assert "pulled it towards -8" not in out


def test_spring_towards_a_rest_position_in_degrees_is_implausible(nominal):
    spring = effect_library("joint_spring")[0]
    reason = spring.implausible(_params(spring, stiffness=20.0, rest_position=-88.2), 1,
                                nominal)
    assert reason is not None and "degrees" in reason
    assert spring.implausible(_params(spring, stiffness=20.0, rest_position=-1.57), 1,
                              nominal) is None
    assert spring.implausible(_params(spring, stiffness=-5.0, rest_position=0.0), 1,
                              nominal) is not None


@pytest.mark.parametrize("option,name", [("--json", "out.json"), ("--plot", "fig.png"),
                                          ("--plot", "fig.nope")])
def test_cli_output_paths_checked_before_work(payload_run, tmp_path, capsys, option, name):
    path = tmp_path / "train.csv"
    write_rtde_csv(payload_run, path)
    target = tmp_path / name if name.endswith(".nope") else tmp_path / "missing" / name
    status = main(["diagnose", "--robot", "ur10", str(path), option, str(target)])
    captured = capsys.readouterr()
    assert status == 2
    assert option in captured.err
    assert "What is missing" not in captured.out  # no diagnosis ran


# ---------------------------------------------------------------- wording
@pytest.mark.parametrize("before,after,words", [
    (0.29, 0.05, "0.29 -> 0.05, 83 % lower"),
    (0.1, 0.217, "0.1 -> 0.217, 117 % higher"),
    (0.5, 0.5, "0.5 -> 0.5, unchanged"),
])
def test_relative_change_in_plain_words(before, after, words):
    assert relative_change(before, after) == words


def test_report_text_counts_joints_from_one_json_from_zero(payload_run):
    diag = DynamicsDiagnosis("ur10", effects=["payload", "coulomb_friction"]).fit(payload_run)
    report = diag.report()
    text = report.text()
    assert "joint 0" not in text
    for j in range(1, 7):
        assert f"joint {j}: " in text
    assert "% better" not in text
    fit_lines = [line for line in text.split("3. Fit")[1].splitlines() if "   joint" in line]
    assert len(fit_lines) == 6
    for line in fit_lines:
        assert re.fullmatch(r"   joint \d: nMSE \S+ -> \S+, (\d+(\.\d+)? % (lower|higher)|unchanged)",
                            line), line
    data = json.loads(report.to_json())
    assert "0-based" in data["schema"]["joints"]
    payload = next(e for e in data["effects"] if e["name"] == "payload")
    assert min(payload["joints"]) == 0  # JSON indices start at 0
    assert "payload" in text and "on joints 1" in text


def test_candidate_labels_count_from_one():
    c = Candidate(effect_library("rotor_inertia")[0], 0, {}, (0,), np.array([0]), 6)
    assert c.label == "rotor_inertia[joint 1]"


# ----------------------------------------------------------- plausibility
def test_torque_constant_scale_005_is_rejected(nominal):
    check = plausibility_check(nominal)
    c = Candidate(effect_library("torque_constant")[0], 4, {}, (4,), np.array([0]), 4)
    assert "0.05" in check(c, np.array([19.0]))  # scale 1 / (1 + 19)
    assert check(c, np.array([-0.1])) is None  # scale 1.11


def test_negative_stribeck_peak_is_rejected(nominal):
    stribeck = effect_library("stribeck_friction")[0]
    reason = stribeck.implausible(_params(stribeck, delta_stribeck=-2.0,
                                          stribeck_velocity=0.003), 1, nominal)
    assert reason is not None and "negative" in reason
    assert stribeck.implausible(_params(stribeck, delta_stribeck=2.0, stribeck_velocity=0.02),
                                1, nominal) is None


def test_link_mass_heavier_than_the_link_is_rejected(nominal):
    link = effect_library("link_mass")[0]
    heavy = _params(link, delta_mass=23.5, delta_first_moment_x=0.0,
                    delta_first_moment_y=0.0, delta_first_moment_z=0.0)
    assert "23.5 kg" in link.implausible(heavy, 1, nominal)
    heavy["delta_mass"] = (2.0, 0.0)
    assert link.implausible(heavy, 1, nominal) is None


def test_payload_bounds(nominal):
    payload = effect_library("payload")[0]
    ok = _params(payload, mass=3.0, com_x=0.0, com_y=0.0, com_z=0.05)
    assert payload.implausible(ok, None, nominal) is None
    for mass in (-0.5, 2.5 * rated_payload(nominal.robot)):
        bad = dict(ok, mass=(mass, 0.0))
        assert "twice the rated payload" in payload.implausible(bad, None, nominal)


def test_total_friction_must_stay_positive():
    nominal = NominalModel("ur10", friction={"coulomb": [5.0] * 6, "viscous": [1.0] * 6})
    coulomb, viscous = effect_library(["coulomb_friction", "viscous_friction"])
    assert coulomb.implausible({"delta_coulomb": (-3.0, 0.1)}, 2, nominal) is None
    assert coulomb.implausible({"delta_coulomb": (-6.0, 0.1)}, 2, nominal) is not None
    assert viscous.implausible({"delta_viscous": (-1.5, 0.1)}, 2, nominal) is not None


def test_time_delay_and_tilt_bounds(nominal):
    tilt, delay = effect_library(["gravity_tilt", "time_delay"])  # library order
    assert delay.implausible({"delay": (0.25, 0.01)}, None, nominal) is not None
    assert delay.implausible({"delay": (0.016, 0.001)}, None, nominal) is None
    assert tilt.implausible({"roll": (0.3, 0.0), "pitch": (0.0, 0.0)}, None, nominal)


# ------------------------------------------------------------ significance
def _synthetic(tiny_viscous):
    """Joint 2 has 0.3 A of Coulomb friction, and ``tiny_viscous`` A s/rad of viscous."""
    rng = np.random.default_rng(0)
    nominal = NominalModel("ur10")
    X = np.hstack([rng.uniform(-1, 1, (600, 12)), np.zeros((600, 6))])
    s = Signals.from_states(nominal, X)
    s.current = s.reference + 1e-4 * rng.normal(size=(600, 6))
    s.current[:, 1] += 0.3 * np.sign(s.qd[:, 1]) + tiny_viscous * s.qd[:, 1]
    candidates, design = build_candidates(
        s, nominal, effect_library(["coulomb_friction", "viscous_friction"]))
    stats = fold_statistics(candidates, design, s.current - s.reference,
                            np.ones((600, 6), dtype=bool), fold_index(s, 5), 5, s.current)
    return stats, candidates


def test_a_consistent_but_tiny_share_is_not_a_finding():
    """Viscous friction worth ~0.1 % of the residual: t is huge, it is still not named."""
    stats, candidates = _synthetic(tiny_viscous=0.01)
    strict, _ = forward_selection(stats, candidates, min_share=0.01)
    assert [s.candidate.label for s in strict] == ["coulomb_friction[joint 2]"]
    loose, _ = forward_selection(stats, candidates, min_share=0.0)
    labels = sorted(s.candidate.label for s in loose)
    assert labels == ["coulomb_friction[joint 2]", "viscous_friction[joint 2]"]
    viscous = next(s for s in loose if s.candidate.effect.name == "viscous_friction")
    assert viscous.share < 0.01 and viscous.t > 3.0


def test_implausible_pick_is_reported_and_the_next_considered():
    stats, candidates = _synthetic(tiny_viscous=0.0)
    rejections = []

    def no_coulomb(candidate, theta):
        return "test bound" if candidate.effect.name == "coulomb_friction" else None

    selected, _ = forward_selection(stats, candidates, check=no_coulomb, rejections=rejections)
    assert all(s.candidate.effect.name != "coulomb_friction" for s in selected)
    assert rejections[0]["name"] == "coulomb_friction[joint 2]"
    assert rejections[0]["reason"] == "test bound" and rejections[0]["joints"] == [1]


def test_separating_excitation_names_joints_from_one():
    text = separating_excitation("rotor_inertia", "link_mass", [0, 1])
    assert text.startswith("on joints 1, 2")
    assert "oscillations" in text and "gravity" in text


# ---------------------------------------------------------- friction family
def _low_speed_states(seed, n=3000):
    """Random states with speeds spread over 3 decades; current = reference + noise.

    Returns the nominal model, the signals, joint 2's velocity and torque constant.
    """
    rng = np.random.default_rng(seed)
    nominal = NominalModel("ur10")
    qd = rng.uniform(-1, 1, (n, 6)) * 10 ** rng.uniform(-3.5, -0.5, (n, 6))
    X = np.hstack([rng.uniform(-1, 1, (n, 6)), qd, np.zeros((n, 6))])
    s = Signals.from_states(nominal, X)
    s.current = s.reference + 0.01 * rng.normal(size=(n, 6))
    return nominal, s, s.qd[:, 1], s.torque_constants[1]


def test_stribeck_peak_over_softening_dry_friction_is_found_with_both_signs():
    """A peak (+6 Nm at 0.04 rad/s) on friction that softens at lower speed (-8 Nm at
    0.004 rad/s): tried alone each is cancelled by the other; the pair is found, each with
    its physical sign."""
    nominal, s, v, k = _low_speed_states(1)
    n = s.n_samples
    s.current[:, 1] += (6.0 * np.sign(v) * np.exp(-(v / 0.04) ** 2)
                        - 8.0 * np.sign(v) * np.exp(-(v / 0.004) ** 2)) / k
    library = effect_library(["stribeck_friction", "friction_softening"])
    candidates, design = build_candidates(s, nominal, library)
    assert any(c.parts for c in candidates)
    stats = fold_statistics(candidates, design, s.current - s.reference,
                            np.ones((n, 6), dtype=bool), fold_index(s, 5), 5, s.current)
    check = plausibility_check(nominal)
    selected, _ = forward_selection(stats, candidates, check=check)
    # the pair enters as its two parts, each re-tested on its own in the backward pass
    assert [st.candidate.label for st in selected] == [
        "stribeck_friction[joint 2]", "friction_softening[joint 2]"]
    from sklearn_gpcd.diagnosis import joint_fit
    from sklearn_gpcd.diagnosis.selection import expand_composites

    model = joint_fit(s, nominal, expand_composites(selected), np.ones((n, 6), dtype=bool))
    fitted = {f.name: f.parameters for f in model.effects}
    assert fitted["stribeck_friction"]["delta_stribeck"][0] == pytest.approx(6.0, rel=0.2)
    assert fitted["stribeck_friction"]["stribeck_velocity"][0] == pytest.approx(0.04, rel=0.2)
    assert fitted["friction_softening"]["softening"][0] == pytest.approx(8.0, rel=0.2)


@pytest.mark.slow
def test_no_friction_drift_on_simulator_output_without_drift():
    """`gpcd simulate --scenario d2` then `gpcd diagnose --robot ur10` reported "friction drift
    0.00332 +- 0.0039 Nm per minute ... strong (t = 7.7)": a consistent but tiny held-out gain
    (a 0.0x % share of the residual) with a parameter that does not differ from zero."""
    from sklearn_gpcd.datasets import simulate_d2

    rec = simulate_d2("ur10", random_state=0)
    diag = DynamicsDiagnosis("ur10").fit(rec)
    assert "friction_drift" not in [e.name for e in diag.effects_]
    for fitted in diag.effects_:  # every named effect is a practical and significant finding
        assert fitted.joint_share >= diag.min_share


# ------------------------------------------------- significance that does not relax
def _drifting(viscous_rate):
    """Joint 2's dry friction drifts by 0.01 A/s; its viscous coefficient by ``viscous_rate``."""
    rng = np.random.default_rng(0)
    nominal = NominalModel("ur10")
    n = 1000
    X = np.hstack([rng.uniform(-1, 1, (n, 12)), np.zeros((n, 6))])
    s = Signals.from_states(nominal, X)
    s.time = np.linspace(0.0, 50.0, n)
    s.current = s.reference + 1e-4 * rng.normal(size=(n, 6))
    s.current[:, 1] += s.time * (0.01 * np.sign(s.qd[:, 1]) + viscous_rate * s.qd[:, 1])
    candidates, design = build_candidates(s, nominal, effect_library(["friction_drift"]))
    stats = fold_statistics(candidates, design, s.current - s.reference,
                            np.ones((n, 6), dtype=bool), fold_index(s, 5), 5, s.current)
    return stats, candidates


def test_extra_columns_of_a_variant_pass_the_test_on_their_own():
    """A dry-friction drift with a viscous drift worth ~0.03 % of the residual: the variant
    with both rates wins the forward step (the noise is tiny), but its viscous column alone
    is no finding; the backward pass keeps the dry-only variant and says why."""
    stats, candidates = _drifting(viscous_rate=0.0002)
    loose, _ = forward_selection(stats, candidates, min_share=0.0)
    assert [s.candidate.settings["with_viscous"] for s in loose] == [True]
    rejections = []
    strict, _ = forward_selection(stats, candidates, rejections=rejections)
    assert [s.candidate.settings["with_viscous"] for s in strict] == [False]
    # the rate in Nm/s: 0.01 A/s times joint 2's torque constant
    assert strict[0].theta[0] == pytest.approx(0.01 * 11.976, rel=0.05)
    assert "simpler variant" in rejections[-1]["reason"]
    # a viscous drift of its own size is kept
    stats, candidates = _drifting(viscous_rate=0.01)
    kept, _ = forward_selection(stats, candidates)
    assert [s.candidate.settings["with_viscous"] for s in kept] == [True]


def test_peak_next_to_an_exponential_softening_is_sized():
    """A peak next to dry friction that softens exponentially (a regularised constraint,
    MuJoCo's frictionloss) came out 22-40 % low with the Gaussian softening alone: the
    misfit of the shape went into the peak. The softening's shape is now a setting
    (opt-in)."""
    from sklearn_gpcd.diagnosis.effects import SOFTENING_SHAPES, FrictionSofteningEffect

    nominal, s, v, k = _low_speed_states(2)
    n = s.n_samples
    s.current[:, 1] += (3.0 * np.sign(v) * np.exp(-(v / 0.03) ** 2)
                        - 8.0 * np.sign(v) * np.exp(-np.abs(v) / 0.004)) / k
    library = effect_library(["stribeck_friction",
                              FrictionSofteningEffect(shapes=SOFTENING_SHAPES)])
    candidates, design = build_candidates(s, nominal, library)
    stats = fold_statistics(candidates, design, s.current - s.reference,
                            np.ones((n, 6), dtype=bool), fold_index(s, 5), 5, s.current)
    selected, _ = forward_selection(stats, candidates, check=plausibility_check(nominal))
    from sklearn_gpcd.diagnosis import joint_fit
    from sklearn_gpcd.diagnosis.selection import expand_composites

    model = joint_fit(s, nominal, expand_composites(selected), np.ones((n, 6), dtype=bool))
    fitted = {f.name: f for f in model.effects}
    assert fitted["stribeck_friction"].parameters["delta_stribeck"][0] == pytest.approx(
        3.0, rel=0.2)
    assert fitted["friction_softening"].settings["shape"] == "exponential"
    assert fitted["friction_softening"].parameters["softening"][0] == pytest.approx(8.0, rel=0.2)


def test_softening_shapes():
    from sklearn_gpcd.diagnosis.effects import SOFTENING_SHAPES, softening_shape

    v = np.array([-0.02, -0.001, 0.0, 0.001, 0.02])
    for shape in SOFTENING_SHAPES:
        col = softening_shape(v, 0.01, shape)
        assert col[2] == 0 and np.allclose(col, -col[::-1])  # odd, zero at rest
        assert 0.5 < col[3] <= 1.0 and abs(col[4]) < 0.2  # near 1 at rest, fades
    with pytest.raises(ValueError, match="unknown softening shape"):
        softening_shape(v, 0.01, "cubic")


def _simulator_nominal():
    from sklearn_gpcd.datasets import default_friction
    from sklearn_gpcd.datasets.plant import drive_parameters
    from sklearn_gpcd.robots import load_robot

    robot = load_robot("ur10")
    k, rotor = drive_parameters(robot)
    return load_robot("ur10", torque_constants=k, rotor_inertias=rotor), default_friction(robot)


def _lead(recording, seconds):
    """The recording with its current leading the state by ``seconds``."""
    t = recording.time
    current = np.column_stack([np.interp(t + seconds, t, recording.current[:, j])
                               for j in range(recording.current.shape[1])])
    return Recording(time=t, q=recording.q, qd=recording.qd, current=current,
                     units=recording.units, name=recording.name)


def test_a_lead_shorter_than_half_a_sample_is_not_a_delay():
    """PyBullet's logged current leads its state by about 1.4 ms at 125 Hz (which sample of
    the control cycle each carries); it was named a -1.4 ms delay in blind cases without
    any delay. A lead below half the sample period (4 ms here) is not a delay of the log; a
    longer one still is."""
    robot, friction = _simulator_nominal()
    run = simulate_d1("ur10", n_targets=8, random_state=1)
    assert np.median(np.diff(run.time)) == pytest.approx(0.008)
    # (a 3 ms lead removes 1.6 % of the held-out error here: below the default min_gain,
    # so the bar is lowered to reach the rule)
    short = DynamicsDiagnosis(robot, friction=friction, effects=["time_delay"],
                              min_gain=0.005).fit(_lead(run, 0.003))
    assert short.effects_ == []
    assert any("half the sample period" in r["reason"] for r in short.rejected_effects_)
    long = DynamicsDiagnosis(robot, friction=friction, effects=["time_delay"],
                             min_gain=0.005).fit(_lead(run, 0.012))
    assert [f.name for f in long.effects_] == ["time_delay"]
    assert long.effects_[0].parameters["delay"][0] == pytest.approx(-0.012, rel=0.2)


def test_torque_constant_a_run_cannot_show_is_said_so():
    """On the blind protocol's plants a 10-24 % torque-constant change of wrist joint 5,
    whose current is 98-99.8 % friction there, went unnamed and unmentioned. The report now
    lists the torque constants these recordings cannot tell from a friction change of the
    joint, from which size on they could, and the excitation that would; the gravity-loaded
    joints 1-3 are not listed, nor a joint whose constant was named."""
    from sklearn_gpcd.datasets import TorqueConstantError

    robot, friction = _simulator_nominal()
    control = DynamicsDiagnosis(robot, friction=friction).fit(
        simulate_d1("ur10", n_targets=8, random_state=1))
    said = {u["joints"][0]: u for u in control.unidentifiable_}
    assert {4, 5} <= set(said) and not {0, 1, 2} & set(said)
    assert said[4]["smallest_change"] > 0.1 and said[4]["friction_share"] > 0.9
    text = control.report().text()
    assert "Not identifiable from these recordings" in text and "joint 5" in text
    assert control.report().to_dict()["not_identifiable"][0]["effect"] == "torque_constant"
    # on this simulator nothing else competes for joint 5's residual: a 10 % change is named
    # (and then not listed)
    changed = DynamicsDiagnosis(robot, friction=friction).fit(
        simulate_d1("ur10", n_targets=8, effects=[TorqueConstantError([1, 1, 1, 1, 0.9, 1])],
                random_state=1))
    named = [f for f in changed.effects_ if f.name == "torque_constant"]
    assert [f.target for f in named] == [4]
    assert named[0].parameters["scale"][0] == pytest.approx(0.9, abs=0.02)
    assert 4 not in {u["joints"][0] for u in changed.unidentifiable_}
