"""Any arm, early failures and said guesses (issue #37, Deliver 2-4).

* one-value-per-line logs (the Franka Emika Panda logs of Gaz et al.) read
  through :func:`~sklearn_gpcd.io.read_value_files` and the ``panda_gaz``
  preset, torque units carried by the column map;
* ``load_robot(urdf, joints=...)`` / ``gpcd --joints`` keep the arm's joints
  of a URDF with gripper fingers, and the API refuses a robot whose joint
  count does not match the data, naming ``--joints``;
* a layout guessed from a field count is said once, with its map;
* degrees, milliseconds and too-short recordings stop ``gpcd`` unless
  confirmed (``--units-confirmed``, ``--allow-short``); ``-o model.skops``
  without skops fails before any work.

Everything runs on files the tests write; the real Panda log (and pybullet's
Panda URDF) are used only when present.
"""

import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import make_inputs
from sklearn_gpcd.io import (Recording, RecordingWarning, load_recording, load_recordings,
                             read_csv, read_value_files, write_rtde_csv)
from sklearn_gpcd.robots import load_robot

PANDA_LOG = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "panda_gaz"


def _link(name, mass=1.0):
    return (f'<link name="{name}"><inertial><origin xyz="0 0 0.1"/><mass value="{mass}"/>'
            '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
            '</link>')


def _joint(name, kind, parent, child, axis="0 0 1"):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 0.3"/><axis xyz="{axis}"/>'
            '<limit lower="-3" upper="3" effort="10" velocity="2"/></joint>')


@pytest.fixture(scope="module")
def gripper_urdf(tmp_path_factory):
    """A 3-joint arm with a 2-finger gripper: 5 movable joints, like the Panda's 7 + 2."""
    parts = [_link("base")]
    for j in range(3):
        parts += [_link(f"link{j + 1}"), _joint(f"arm{j + 1}", "revolute",
                                                "base" if j == 0 else f"link{j}", f"link{j + 1}",
                                                "0 1 0" if j else "0 0 1")]
    for f in (1, 2):
        parts += [_link(f"finger{f}", 0.05),
                  _joint(f"finger{f}", "prismatic", "link3", f"finger{f}", "1 0 0")]
    path = tmp_path_factory.mktemp("urdf") / "gripper_arm.urdf"
    path.write_text('<robot name="gripper_arm">' + "".join(parts) + "</robot>")
    return path


def _write_value_files(folder, rec, names=("time", "positions", "velocity", "torques")):
    folder.mkdir(parents=True, exist_ok=True)
    for name, values in zip(names, (rec.time, rec.q, rec.qd, rec.current)):
        np.savetxt(folder / f"traj_{name}.txt", values.reshape(-1))
    return folder


def _moving(n_joints=3, n=400, dt=0.01, scale=1.0):
    t = np.arange(n) * dt
    q = scale * 0.5 * np.sin(np.outer(t, np.arange(1, n_joints + 1)))
    qd = scale * 0.5 * np.arange(1, n_joints + 1) * np.cos(np.outer(t, np.arange(1, n_joints + 1)))
    return Recording(time=t, q=q, qd=qd, current=q + 0.1, name="moving")


# ----------------------------------------------------------- value files
def test_value_files_are_read_sample_major_with_the_preset_units(tmp_path):
    rec = _moving(7)
    folder = _write_value_files(tmp_path / "rbt_log", rec)
    read = read_value_files(folder)
    np.testing.assert_allclose(read.q, rec.q)
    np.testing.assert_allclose(read.current, rec.current)
    assert read.units == "Nm" and read.metadata["column_map"] == "panda_gaz"
    # a folder of such files is one recording for load_recording(s), said once
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        both = load_recordings([folder, folder])
    guesses = [w for w in caught if "one-value-per-line" in str(w.message)]
    assert len(both) == 2 and len(guesses) == 1
    assert "panda_gaz" in str(guesses[0].message) and "--column-map" in str(guesses[0].message)
    # a file one value short is named, with the counts
    (folder / "traj_velocity.txt").write_text("\n".join(["0.0"] * (7 * 400 - 1)))
    with pytest.raises(ValueError, match="traj_velocity.txt: 2799 values, expected 400 "
                                         "samples x 7"):
        read_value_files(folder)


def test_a_dict_map_names_files_and_units(tmp_path):
    rec = _moving(2)
    folder = _write_value_files(tmp_path / "log", rec, ("t", "q", "v", "i"))
    read = read_value_files(folder, {"time": "traj_t.txt", "q": "traj_q.txt",
                                     "qd": "traj_v.txt", "current": "traj_i.txt",
                                     "units": "A"})
    assert read.n_joints == 2 and read.units == "A"
    with pytest.raises(ValueError, match="units must be one of"):
        read_value_files(folder, {"time": "traj_t.txt", "q": "traj_q.txt",
                                  "qd": "traj_v.txt", "current": "traj_i.txt", "units": "mA"})


def test_csv_column_map_carries_the_torque_units(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("t,q,qd,tau\n0.00,0.1,0,1.5\n0.01,0.1,0,1.6\n")
    spec = {"time": "t", "q": "q", "qd": "qd", "current": "tau"}
    assert read_csv(path, spec).units == "A"
    assert read_csv(path, {**spec, "units": "Nm"}).units == "Nm"


def test_a_guessed_layout_is_said_once_with_its_map(tmp_path):
    rec = _moving(6, n=200)
    paths = []
    for k in range(3):
        paths.append(tmp_path / f"run{k}.csv")
        np.savetxt(paths[-1], np.hstack([rec.time[:, None], rec.q, rec.qd, rec.current]),
                   delimiter=",")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        load_recordings(paths)
    guesses = [str(w.message) for w in caught if "headerless" in str(w.message)]
    assert len(guesses) == 1, guesses
    assert "ur10e_mamedov (time: 0, q: 1-6, qd: 7-12, current: 13-18" in guesses[0]


# ------------------------------------------------------ joints of a URDF
def test_load_robot_keeps_the_arm_joints(gripper_urdf):
    full = load_robot(gripper_urdf)
    assert full.n_joints == 5
    assert load_robot(gripper_urdf, joints=3).n_joints == 3
    named = load_robot(gripper_urdf, joints=["arm1", "arm2", "arm3"])
    np.testing.assert_allclose(named.rnea(np.zeros(3), np.zeros(3), np.zeros(3)),
                               load_robot(gripper_urdf, joints=3).rnea(
                                   np.zeros(3), np.zeros(3), np.zeros(3)))
    with pytest.raises(ValueError, match="no joint named hand; its joints are arm1"):
        load_robot(gripper_urdf, joints=["arm1", "hand"])
    with pytest.raises(ValueError, match="joints=6, but the model has 5"):
        load_robot(gripper_urdf, joints=6)


def test_the_api_refuses_a_robot_with_more_joints_than_the_data(gripper_urdf):
    X, _ = make_inputs(_moving(3))                 # augmented inputs of 3 joints
    with pytest.raises(ValueError, match=r"18 columns \(the inputs of 3 joints\).*--joints 3.*"
                                         r"has 5 joints"):
        RigidBodyFeatures(load_robot(gripper_urdf), joint=0).fit(X)
    phi = RigidBodyFeatures(load_robot(gripper_urdf, joints=3), joint=0).fit(X)
    assert phi.transform(X).shape[0] == len(X)


def test_gpcd_names_joints_when_the_log_has_fewer(gripper_urdf, tmp_path, capsys):
    csv = tmp_path / "three.csv"
    write_rtde_csv(_moving(3), csv)
    out = tmp_path / "m.joblib"
    assert main(["train", str(csv), "--robot", str(gripper_urdf), "--model", "sp_s",
                 "-o", str(out), "-q"]) == 2
    assert "--joints 3" in capsys.readouterr().err
    assert main(["train", str(csv), "--robot", str(gripper_urdf), "--joints", "3",
                 "--model", "sp_s", "--n-support", "30", "-o", str(out), "-q"]) == 0
    assert out.is_file()


# ------------------------------------------------------ early failures
def test_skops_output_without_skops_fails_before_reading(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "skops", None)       # as if not installed
    status = main(["train", str(tmp_path / "missing.csv"), "--robot", "ur10e",
                   "-o", str(tmp_path / "model.skops")])
    err = capsys.readouterr().err
    assert status == 2 and "skops, which is not installed" in err and ".joblib" in err
    assert "reading" not in err                           # nothing was read or fitted


@pytest.mark.parametrize("kind, make, flag", [
    ("degrees", lambda r: r.replace(q=np.rad2deg(r.q) + 30.0), "--units-confirmed"),
    ("units", lambda r: r.replace(time=r.time * 1000.0), "--time-scale 1e-3"),
    ("short", lambda r: Recording(time=r.time[:5], q=r.q[:5], qd=r.qd[:5],
                                  current=r.current[:5]), "--allow-short"),
])
def test_suspect_recordings_stop_gpcd_unless_accepted(kind, make, flag, tmp_path, capsys):
    csv = tmp_path / f"{kind}.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        write_rtde_csv(make(_moving(6, scale=2.0)), csv)
    args = ["train", str(csv), "--robot", "ur10", "--model", "sp_s", "-q",
            "-o", str(tmp_path / "m.joblib")]
    assert main(args) == 2
    err = capsys.readouterr().err
    confirm = "--allow-short" if kind == "short" else "--units-confirmed"
    assert str(csv) in err and flag in err and confirm in err
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        accepted = load_recordings([csv], accept=[kind])
    assert len(accepted) == 1


# ------------------------------------------------------ the real Panda log
@pytest.mark.realdata
def test_the_real_panda_log_and_a_gripper_urdf():
    if not (PANDA_LOG / "rbt_log").is_dir():
        pytest.skip("the Panda log of ../shared/data/real/panda_gaz is absent")
    spec = importlib.util.find_spec("pybullet_data")     # a Panda URDF with its fingers
    urdf = (Path(spec.origin).parent / "franka_panda" / "panda.urdf") if spec else None
    if urdf is None or not urdf.is_file():
        pytest.skip("no Panda URDF (pybullet_data's franka_panda/panda.urdf)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        rec = load_recording(PANDA_LOG / "rbt_log")
    assert (rec.n_samples, rec.n_joints, rec.units) == (20544, 7, "Nm")
    X, _ = make_inputs(rec.slice(0, 500))
    with pytest.raises(ValueError, match=r"--joints 7.*'panda' has 9 joints"):
        RigidBodyFeatures(load_robot(urdf), joint=0).fit(X)
    assert RigidBodyFeatures(load_robot(urdf, joints=7), joint=0).fit(X).n_joints_ == 7


# ------------------------------------------------------ units in the tables
def test_torque_units_reach_the_calibration_and_monitoring_tables(tmp_path):
    from sklearn_gpcd.monitoring import MonitorSession
    from sklearn_gpcd.workflow import calibrate_detector, calibration_report, train_model

    rng = np.random.default_rng(0)
    t = np.arange(600) * 0.01

    def rec(phase, units="Nm", push=0.0):
        q = np.sin(t + phase)[:, None]
        current = 2 * q + 0.05 * rng.normal(size=q.shape)
        current[300:330] += push
        return Recording(time=t, q=q, qd=np.cos(t + phase)[:, None], current=current,
                         target_current=2 * q, units=units, name=f"run{phase}")

    trained = train_model([rec(0.0)], model="sp_c", n_support=50)
    calibrated = calibrate_detector(trained, [rec(1.0), rec(2.0), rec(3.0)],
                                    robot=load_robot("ur10e"))
    text = calibration_report(calibrated.calibration)
    assert calibrated.calibration["units"] == "Nm"
    assert "thresholds [Nm]:" in text and "torque constants" not in text
    with pytest.raises(ValueError, match="in A and Nm|in Nm and A"):
        calibrate_detector(trained, [rec(1.0), rec(2.0, "A")])
    session = MonitorSession(calibrated.detector, calibrated.features)
    session.run_recording(rec(4.0, push=3.0), "run4.csv")
    assert session.events and "peak |m| [Nm]" in session.events_text()
