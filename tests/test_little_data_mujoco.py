"""Little calibration data on the MuJoCo plant (issue 38): ``gpcd calibrate`` on 20 s
of collision-free logs warns with a number; the plant's pushes and controller signals.

The plant and the benchmark live in ``benchmarks/`` (``_mujoco_plant.py``,
``little_data_mujoco.py``); MuJoCo is not a dependency of the package, so
these tests skip when it is not installed.
"""

import re
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def bench():
    pytest.importorskip("mujoco")
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import _mujoco_plant
        import little_data_mujoco
    finally:
        sys.path.remove(str(BENCHMARKS))
    return _mujoco_plant, little_data_mujoco, little_data_mujoco.plant_setup()


def test_push_is_labelled_and_moves_the_current_only_while_it_acts(bench):
    from sklearn_gpcd.datasets import Contact

    plant, bm, (robot, k, rotor) = bench
    ref = bm.task_reference(robot, 5.0, 3)
    push = Contact(link=3, start=2.0, duration=1.0, force=[0.0, 0.0, -150.0],
                   point=robot.model.inertias[3].lever)
    free = plant.simulate(robot, k, rotor, random_state=3, reference=ref, log_targets=True)
    pushed = plant.simulate(robot, k, rotor, random_state=3, reference=ref, contacts=[push],
                            log_targets=True)
    window = pushed.metadata["contacts"][0]
    inside = (pushed.time >= window["start"]) & (pushed.time < window["stop"])
    assert np.array_equal(pushed.labels > 0, inside)
    before = pushed.time < window["start"]
    assert np.array_equal(pushed.current[before], free.current[before])
    assert np.abs(pushed.current - free.current)[inside].max() > 1.0  # A, a 150 N push
    # the target current is the feed-forward: the push does not enter it
    np.testing.assert_allclose(pushed.target_current, free.target_current)
    np.testing.assert_allclose(pushed.target_q, free.target_q)


def test_gpcd_calibrate_on_20_s_of_mujoco_logs_warns_with_a_number(bench, tmp_path, capsys):
    from sklearn_gpcd.cli import main
    from sklearn_gpcd.io import write_rtde_csv

    plant, bm, (robot, k, rotor) = bench
    ident = plant.simulate(robot, k, rotor, n_targets=4, random_state=5)
    write_rtde_csv(ident, tmp_path / "ident.csv")
    logs = []
    for seed in (11, 12):  # two 10 s logs of the task, 20 s of data
        rec = plant.simulate(robot, k, rotor, random_state=seed,
                             reference=bm.task_reference(robot, 10.0, seed))
        rec = rec.slice(0, int(np.searchsorted(rec.time, 10.0)))
        write_rtde_csv(rec, tmp_path / f"free{seed}.csv")
        logs.append(str(tmp_path / f"free{seed}.csv"))
    assert main(["train", str(tmp_path / "ident.csv"), "--robot", "ur10", "--model", "p_f",
                 "-o", str(tmp_path / "model.skops"), "-q"]) == 0
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        status = main(["calibrate", str(tmp_path / "model.skops"), *logs,
                       "-o", str(tmp_path / "detector.skops"), "-q"])
    err = capsys.readouterr().err
    assert status == 0, err
    found = re.search(r"warning: the calibration data lasts (\d+) s.* by (\d+) per hour", err)
    assert found, err
    assert int(found.group(1)) <= 20 and int(found.group(2)) > 0
