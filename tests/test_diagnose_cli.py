"""Tests of ``gpcd diagnose``."""

import json

import pytest

from sklearn_gpcd.cli import build_parser, main
from sklearn_gpcd.datasets import Payload, simulate_d1
from sklearn_gpcd.io import write_rtde_csv


@pytest.fixture(scope="module")
def csv_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("diagnose")
    train, test = folder / "train.csv", folder / "test.csv"
    write_rtde_csv(simulate_d1("ur10", n_targets=6, effects=[Payload(3.0)], random_state=1), train)
    write_rtde_csv(simulate_d1("ur10", n_targets=4, effects=[Payload(3.0)], random_state=2), test)
    return train, test


def test_diagnose_writes_json_and_prints_report(csv_files, tmp_path, capsys):
    train, test = csv_files
    out = tmp_path / "out.json"
    status = main(["diagnose", "--robot", "ur10", str(train), "--test", str(test),
                   "--json", str(out), "--effects", "payload,coulomb_friction,viscous_friction,"
                   "rotor_inertia,stribeck_friction"])
    assert status == 0
    data = json.loads(out.read_text())
    assert set(data) >= {"effects", "nmse_before", "nmse_after"}
    names = [e["name"] for e in data["effects"]]
    assert "payload" in names
    payload = data["effects"][names.index("payload")]
    assert payload["parameters"]["mass"] == pytest.approx(3.0, rel=0.2)
    assert payload["joints"] == [0, 1, 2, 3, 4, 5]
    assert sum(data["nmse_after"]) < sum(data["nmse_before"])
    text = capsys.readouterr().out
    assert "What is missing" in text and "payload of" in text


def test_diagnose_plot(csv_files, tmp_path):
    pytest.importorskip("matplotlib")
    train, test = csv_files
    png = tmp_path / "fig.png"
    assert main(["diagnose", "--robot", "ur10", str(train), "--test", str(test),
                 "--plot", str(png), "--effects", "payload"]) == 0
    assert png.stat().st_size > 1000


def test_diagnose_robot_accepts_urdf_path(ur10_urdf):
    args = build_parser().parse_args(["diagnose", "--robot", str(ur10_urdf), "a.csv"])
    assert args.robot.n_joints == 6 and args.train == ["a.csv"]


def test_diagnose_bad_torque_constants(csv_files, capsys):
    train, _ = csv_files
    assert main(["diagnose", "--robot", "ur10", str(train), "--torque-constants", "1,2,x"]) == 2
    assert "--torque-constants must be comma-separated numbers" in capsys.readouterr().err


def test_diagnose_wrong_number_of_torque_constants(csv_files, capsys):
    train, _ = csv_files
    assert main(["diagnose", "--robot", "ur10", str(train), "--torque-constants", "1,2"]) == 2
    assert "torque_constants needs 6" in capsys.readouterr().err


def test_diagnose_unknown_robot_fails_at_parse_time(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["diagnose", "--robot", "nonsense", "a.csv"])
    assert "unknown robot" in capsys.readouterr().err


def test_diagnose_missing_file(tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv" in capsys.readouterr().err
