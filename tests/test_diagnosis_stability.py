"""Block-bootstrap stability of the selection (``diagnosis/stability.py``)."""

import json

import numpy as np

from sklearn_gpcd.diagnosis import NominalModel, Signals, effect_library, forward_selection
from sklearn_gpcd.diagnosis.selection import build_candidates, fold_index, fold_statistics
from sklearn_gpcd.diagnosis.stability import block_index, resample, shortlist, stability


def _case(extra):
    rng = np.random.default_rng(0)
    nominal = NominalModel("ur10")
    X = np.hstack([rng.uniform(-1, 1, (600, 12)), np.zeros((600, 6))])
    s = Signals.from_states(nominal, X)
    s.current = s.reference + 0.05 * rng.normal(size=(600, 6))
    s.current[:, 1] += extra * np.sign(s.qd[:, 1])
    cands, design = build_candidates(s, nominal, effect_library(
        ["coulomb_friction", "viscous_friction"]))
    mask = np.ones((600, 6), dtype=bool)
    residual = s.current - s.reference
    stats = fold_statistics(cands, design, residual, mask, fold_index(s, 5), 5, s.current)
    return nominal, s, cands, design, residual, mask, stats


def _stability(extra):
    nominal, s, cands, design, residual, mask, stats = _case(extra)
    selected, history = forward_selection(stats, cands)

    class Named:  # what stability() reads of a fitted effect
        def __init__(self, c):
            self.name, self.target = c.effect.name, c.target

    settings = {"n_splits": 5, "min_gain": 0.02, "min_t": 3.0, "min_share": 0.01,
                "n_resamples": 10}
    return selected, stability(cands, design, residual, (mask, mask), s, s.current, nominal,
                               [Named(st.candidate) for st in selected], history, settings)


def test_strong_effect_is_named_in_every_resample_with_its_size():
    selected, table = _stability(0.3)
    assert [st.candidate.label for st in selected] == ["coulomb_friction[joint 2]"]
    row = table[("coulomb_friction", 1)]
    assert row["inclusion"] == 1.0
    low, mid, high = row["size"]  # delta_coulomb [Nm]: 0.3 A times K = 11.976 Nm/A
    assert low < 0.3 * 11.976 < high and high - low < 0.1 * mid
    assert 0.9 < row["gain"][0] <= row["gain"][2] < 1.0


def test_no_effect_gives_low_inclusion_everywhere():
    selected, table = _stability(0.0)
    assert selected == []
    assert all(row["inclusion"] <= 0.3 for row in table.values())


def test_resample_keeps_the_total_number_of_blocks():
    nominal, s, cands, design, residual, mask, stats = _case(0.0)
    blocks, per = block_index(s)
    assert sum(p.size for p in per) == blocks.max() + 1
    from sklearn_gpcd.diagnosis.stability import _reduce, block_statistics

    short = shortlist(cands, [], set())
    assert short == []
    reduced, sub, n = _reduce(cands, design, cands[:3])
    st = block_statistics(reduced, sub, n, residual, mask, blocks, blocks.max() + 1,
                          s.current)
    rs = resample(st, per, 5, np.random.default_rng(1))
    # equal blocks (30 samples each): a resample has as many rows as the data
    assert rs.counts.sum() == st.counts.sum() and rs.gram.shape[0] == 5
    assert rs.counts[0].sum() != st.counts.sum() / 5 or not np.allclose(rs.rss, 0)


def test_thresholded_selection_names_the_true_term_and_nothing_on_noise():
    from sklearn_gpcd.diagnosis.stability import thresholded_selection

    settings = {"min_gain": 0.02, "min_t": 3.0, "min_share": 0.01}
    *_, cands, _, _, _, stats = _case(0.3)
    assert [st.candidate.label for st in thresholded_selection(stats, cands, settings)] == \
        ["coulomb_friction[joint 2]"]
    *_, cands, _, _, _, stats = _case(0.0)
    assert thresholded_selection(stats, cands, settings) == []


def test_thresholded_selection_drops_the_weaker_of_two_rival_terms():
    # a Coulomb step on joint 2 and no viscous term: both variants of joint 2 do well alone
    # (sign(qd) and qd correlate) but given the Coulomb term the viscous one adds nothing
    from sklearn_gpcd.diagnosis.stability import best_variants, thresholded_selection

    *_, cands, _, _, _, stats = _case(0.3)
    start = {c.label for c in best_variants(stats, cands, stats)}
    assert {"coulomb_friction[joint 2]", "viscous_friction[joint 2]"} <= start
    kept = thresholded_selection(stats, cands, {"min_gain": 0.02, "min_t": 3.0,
                                                "min_share": 0.01})
    assert [st.candidate.label for st in kept] == ["coulomb_friction[joint 2]"]


def test_recording_gains_are_high_where_the_effect_is_and_nil_where_it_is_not():
    from types import SimpleNamespace

    from sklearn_gpcd.diagnosis.selection import FoldStatistics
    from sklearn_gpcd.diagnosis.stability import recording_gains

    rng = np.random.default_rng(3)
    x = rng.normal(size=(60, 25))
    r = 0.1 * rng.normal(size=x.shape)
    r[:30] += 0.5 * x[:30]  # the effect is in the first recording only...
    stats = FoldStatistics((x * x).sum(1)[:, None, None, None], (x * r).sum(1)[:, None, None],
                           (r * r).sum(1)[:, None], np.full((60, 1), 25.0), np.ones(1))
    term = SimpleNamespace(columns=np.array([0]), joints=(0,))
    first, second = recording_gains(stats, [np.arange(30), np.arange(30, 60)], 5, [term])[0]
    # ... fitted on both, it removes most of the first recording's error and makes the
    # second one's worse (the pooled coefficient, about half the true one, is wrong there)
    assert first > 0.5 and second < 0.0


def test_confounded_alternatives_enter_a_resample_one_at_a_time():
    # told that the two terms of joint 2 cannot be told apart, only the stronger alone
    # (the Coulomb step that is there) enters; without that, both enter (test above)
    from sklearn_gpcd.diagnosis.stability import best_variants

    *_, cands, _, _, _, stats = _case(0.3)
    pair = {("coulomb_friction", 1): {("viscous_friction", 1): 0.95},
            ("viscous_friction", 1): {("coulomb_friction", 1): 0.95}}
    start = {c.label for c in best_variants(stats, cands, stats, confounded=pair)}
    assert "coulomb_friction[joint 2]" in start
    assert "viscous_friction[joint 2]" not in start


def test_group_inclusion_counts_a_resample_naming_any_member():
    from sklearn_gpcd.diagnosis.stability import _group_inclusion

    payload, forearm, delay = ("payload", None), ("link_mass", 2), ("time_delay", None)
    confounded = {payload: {forearm: 0.98}, forearm: {payload: 0.98}}
    resamples = [{payload, delay}, {forearm, delay}, {forearm, delay}, {delay}]
    labels = {payload: "payload", forearm: "link_mass[link 3]"}
    row = _group_inclusion(payload, {payload, delay}, confounded, resamples, labels)
    # each alone under a 60 % cut (25 % and 50 %), the group in 75 % of the resamples
    assert row["group_inclusion"] == 0.75
    assert row["group"] == {forearm: 0.5, payload: 0.25}
    assert row["member"] == forearm and row["correlations"] == {forearm: 0.98}
    # a named family is not an alternative of another named one
    both = _group_inclusion(payload, {payload, forearm}, confounded, resamples, labels)
    assert both["group"] == {payload: 0.25} and both["group_inclusion"] == 0.25


def test_a_payload_confounded_with_a_link_mass_is_kept_as_a_group():
    # the case of tests/test_diagnosis.py::test_delay_next_to_a_payload_is_named_as_a_delay:
    # the payload's columns correlate with a link mass's by 0.9 or more; its group is
    # named in most resamples and reported with each member's share
    from sklearn_gpcd.datasets import Payload, default_friction, simulate_d1
    from sklearn_gpcd.datasets._extra_effects import delay_logged_current
    from sklearn_gpcd.datasets.plant import drive_parameters
    from sklearn_gpcd.diagnosis import DynamicsDiagnosis
    from sklearn_gpcd.robots import load_robot

    robot = load_robot("ur10")
    k, rotor = drive_parameters(robot)
    train = delay_logged_current(simulate_d1(
        "ur10", n_targets=8, effects=[Payload(3.0, com=(0.0, 0.03, 0.06))], random_state=1),
        0.032)
    diag = DynamicsDiagnosis(load_robot("ur10", torque_constants=k, rotor_inertias=rotor),
                             friction=default_friction(robot)).fit(train)
    row = diag.stability_[("payload", None)]
    assert any(f[0] == "link_mass" and c >= 0.9 for f, c in row["correlations"].items())
    assert row["group_inclusion"] >= 0.6 and row["member"] == ("payload", None)
    report = json.loads(json.dumps(diag.report().to_dict()))  # JSON-ready
    entry = next(e for e in report["effects"] if e["name"] == "payload")
    assert set(entry["stability"]["group"][0]) >= {"payload"}
    assert entry["stability"]["group_inclusion"][0] == row["group_inclusion"]
