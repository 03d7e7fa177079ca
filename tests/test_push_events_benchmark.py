"""``benchmarks/push_events.py``: its scoring on a made-up push file, and a clean
exit without the data."""

import numpy as np
import pytest
from sklearn.utils import Bunch

from sklearn_gpcd.io import Recording

from _synthetic import benchmark_module


@pytest.fixture(scope="module")
def bench():
    return benchmark_module("push_events")


def _push_file():
    """Two pushes on joint 1 (+ at 1-2 s, + at 4-5 s) at 100 Hz; a monitor that
    catches the first with its own sign, the second only through a mirror image
    after it, and raises one event outside them."""
    t = np.arange(0, 8, 0.01)
    push = ((t >= 1) & (t < 2)) | ((t >= 4) & (t < 5))
    current = np.zeros((len(t), 1)) + 1.0 * push[:, None]
    rec = Recording(time=t, q=np.zeros((len(t), 1)), qd=np.zeros((len(t), 1)),
                    current=current, target_current=np.zeros((len(t), 1)))
    signal = np.zeros((len(t), 1))
    signal[(t >= 1.1) & (t < 2.0), 0] = 2.0           # the push itself
    signal[(t >= 5.1) & (t < 5.5), 0] = -2.0          # the mirror of the second
    signal[(t >= 7.0) & (t < 7.2), 0] = 2.0           # outside both
    alarms = np.abs(signal) > 1.0
    event = alarms[:, 0].copy()
    onset = event & ~np.concatenate([[False], event[:-1]])
    mon = Bunch(alarms=alarms, signal=signal, ratio=np.abs(signal), event=event,
                event_onset=onset)
    labelled = [{"start_s": 1.0, "stop_s": 2.0, "tail_stop_s": 2.0},
                {"start_s": 4.0, "stop_s": 5.0, "tail_stop_s": 5.0}]
    return mon, rec, labelled


def test_pushes_are_scored_from_the_events(bench):
    mon, rec, labelled = _push_file()
    scored, outside = bench.score_pushes(mon, rec, labelled)
    assert [e["detected"] for e in scored] == [True, True]
    assert scored[0]["delay_s"] == pytest.approx(0.1) and not scored[0]["mirror"]
    assert scored[1]["delay_s"] == pytest.approx(1.1) and scored[1]["mirror"]
    assert [e["n_events"] for e in scored] == [1, 1]
    assert outside == [pytest.approx(7.0)]


def test_a_contact_that_follows_another_is_its_own_event(bench):
    """Two pushes with no gap between their events (the second begins while the
    first is still open, ``event_onset``): one event each, the second onset in
    both windows counts for the later push only."""
    mon, rec, _ = _push_file()
    t = rec.time
    mon.event = (t >= 1.1) & (t < 3.5)
    mon.event_onset = np.isclose(t, 1.1) | np.isclose(t, 2.6)
    mon.alarms = mon.event[:, None].copy()
    mon.signal = np.where(mon.alarms, 2.0, 0.0)
    labelled = [{"start_s": 1.0, "stop_s": 2.0, "tail_stop_s": 2.5},
                {"start_s": 2.5, "stop_s": 3.4, "tail_stop_s": 3.4}]
    scored, outside = bench.score_pushes(mon, rec, labelled)
    assert [e["n_events"] for e in scored] == [1, 1]
    assert outside == []
    mon.event_onset = np.isclose(t, 1.1)            # one event over both pushes
    scored, _ = bench.score_pushes(mon, rec, labelled)
    assert [e["n_events"] for e in scored] == [1, 0]


def test_exits_cleanly_without_the_data(bench, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        bench.main(["--data", str(tmp_path / "missing"), "--output", str(tmp_path)])
    assert stop.value.code in (0, None)
    assert not (tmp_path / "push_events.json").exists()
