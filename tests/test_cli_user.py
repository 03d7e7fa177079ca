"""``gpcd`` on a user's own recordings (issue #15): clean behaviour and ``gpcd train``."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.cli import build_parser, main, parse_args
from sklearn_gpcd.datasets import simulate_d1, simulate_joint1_cyclic
from sklearn_gpcd.io import Recording, load_recording, write_rtde_csv

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real" / "ur10e_mamedov"
ENV = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def _gpcd(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "sklearn_gpcd.cli", *map(str, args)],
                          capture_output=True, text=True, env=ENV, **kwargs)


def _mamedov_csv(rec, path, order=("time", "q", "qd", "current", "target_current",
                                   "target_torque")):
    """Write ``rec`` headerless in the ur10e_mamedov layout (or another column order;
    ``"extra"`` is a column of ones)."""
    columns = {"time": rec.time[:, None], "extra": np.ones((rec.n_samples, 1))}
    blocks = [columns[k] if k in columns else getattr(rec, k) for k in order]
    np.savetxt(path, np.hstack(blocks), delimiter=",", fmt="%.9g")
    return path


@pytest.fixture(scope="module")
def sims(tmp_path_factory):
    """Small simulated recordings: a UR10e D1 (RTDE CSV, robot in its comment line as
    ``gpcd simulate`` writes it),
    the same run headerless in the UR10e preset layout, and in a custom 26-field
    layout that no preset knows."""
    folder = tmp_path_factory.mktemp("user")
    rec = simulate_d1("ur10e", n_targets=8, random_state=3)
    assert rec.n_samples > 2000  # more rows than n_support="auto" keeps
    rtde = write_rtde_csv(rec, folder / "d1.csv", robot_comment=True)
    preset = _mamedov_csv(rec, folder / "d1_mamedov.csv")
    custom = _mamedov_csv(rec, folder / "d1_custom.csv",
                          order=("time", "current", "q", "qd", "target_current", "extra"))
    anonymous = write_rtde_csv(rec.replace(metadata={}), folder / "anonymous.csv")
    return {"rec": rec, "rtde": rtde, "preset": preset, "custom": custom,
            "anonymous": anonymous, "folder": folder}


CUSTOM_MAP = {"time": 0, "current": [1, 2, 3, 4, 5, 6], "q": [7, 8, 9, 10, 11, 12],
              "qd": [13, 14, 15, 16, 17, 18], "target_current": [19, 20, 21, 22, 23, 24]}


# ------------------------------------------------------------------ Ctrl-C
def test_keyboard_interrupt_exits_130_with_one_line(monkeypatch, capsys):
    import sklearn_gpcd.cli.reproduce as verb

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(verb, "run_robots", interrupted)
    assert main(["robots"]) == 130
    captured = capsys.readouterr()
    assert captured.err.splitlines() == ["gpcd robots: interrupted"]


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # a background runner may ignore SIGINT


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigint_during_a_run_exits_130_without_traceback(tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-m", "sklearn_gpcd.cli", "reproduce", "--quick", "-o",
         str(tmp_path / "out")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=ENV, preexec_fn=_default_sigint)
    first = proc.stdout.readline()  # the run has started (progress line)
    assert first, proc.stderr.read()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    assert err.strip().splitlines() == ["gpcd reproduce: interrupted"]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_ctrl_c_during_a_parallel_fit_interrupts_every_process_quietly(sims, tmp_path):
    """Ctrl-C signals the whole foreground process group, joblib workers included."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "sklearn_gpcd.cli", "train", str(sims["rtde"]), "--n-jobs", "2",
         "--model", "sp_s", "-o", str(tmp_path / "m.joblib")], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, env=ENV, preexec_fn=_default_sigint,
        start_new_session=True)
    seen = []
    for line in proc.stderr:  # wait until the fit has started
        seen.append(line)
        if line.startswith("fitting"):
            break
    assert seen and seen[-1].startswith("fitting"), "".join(seen)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    assert err.strip().splitlines() == ["gpcd train: interrupted"]


# ------------------------------------------------------------------ stderr noise
@pytest.mark.parametrize("name", ["some.csv", "broken.urdf"])
def test_bad_urdf_prints_one_gpcd_line_and_no_library_noise(tmp_path, name):
    bad = tmp_path / name
    bad.write_text("0.0,1.0,2.0\n<robot name='x'><link></robot>\n")
    result = _gpcd("simulate", "--robot", bad, "-o", tmp_path / "x.csv")
    assert result.returncode == 2
    err = result.stderr
    assert "XML" not in err and "urdfdom" not in err and ".cpp" not in err, err
    assert err.strip().splitlines()[-1].startswith("gpcd simulate: error: argument --robot")


# ------------------------------------------------------------------ output paths
@pytest.mark.parametrize("argv", [
    ["simulate", "-o", "{missing}/x.csv"],
    ["simulate", "-o", "{folder}"],
    ["reproduce", "-o", "{file}"],
    ["diagnose", "a.csv", "--plot", "{missing}/fig.png"],
    ["diagnose", "a.csv", "--json", "{missing}/out.json"],
    ["train", "a.csv", "-o", "{missing}/model.skops"],
    ["train", "a.csv", "-o", "{folder}/model.txt"],
])
def test_output_paths_are_checked_before_any_work(argv, tmp_path, capsys, monkeypatch):
    from sklearn_gpcd.cli import _args, diagnose, reproduce, train

    def no_work(*args, **kwargs):
        raise AssertionError("work started before the output path was checked")

    for module, name in ((reproduce, "run_simulate"), (reproduce, "run_reproduce"),
                         (diagnose, "run"), (train, "run"), (diagnose, "read_recordings"),
                         (train, "read_recordings"), (_args, "read_recordings")):
        monkeypatch.setattr(module, name, no_work)
    (tmp_path / "file").write_text("x")
    argv = [a.format(missing=tmp_path / "nope", folder=tmp_path, file=tmp_path / "file")
            for a in argv]
    assert main(argv) == 2  # main returns the usage error's status
    assert "error: argument" in capsys.readouterr().err


# ------------------------------------------------------------------ parsing
def test_test_option_does_not_swallow_positionals():
    args = build_parser().parse_args(["diagnose", "--test", "held.csv", "train.csv"])
    assert args.train == ["train.csv"] and args.test == ["held.csv"]
    args = parse_args(
        ["diagnose", "a.csv", "--test", "h1.csv", "b.csv", "--test", "h2.csv",
         "--simulated", "s.csv"])
    assert args.train == ["a.csv", "b.csv"] and args.test == ["h1.csv", "h2.csv"]
    assert args.simulated == ["s.csv"]
    args = parse_args(["train", "--robot", "ur10e", "a.csv", "-o", "m.skops", "b.csv"])
    assert args.recordings == ["a.csv", "b.csv"]
    with pytest.raises(SystemExit):
        parse_args(["diagnose", "a.csv", "--test", "h.csv", "b.csv", "--bogus"])


def test_diagnose_test_before_training_file_runs(sims, capsys):
    assert main(["diagnose", "--test", str(sims["rtde"]), str(sims["rtde"]),
                 "--effects", "payload"]) == 0
    assert "What is missing" in capsys.readouterr().out


# ------------------------------------------------------------------ robot from metadata
def test_diagnose_uses_the_robot_named_by_the_ur10e_preset(sims, capsys):
    assert load_recording(sims["preset"]).metadata["robot"] == "ur10e"
    assert main(["diagnose", str(sims["preset"]), "--effects", "payload"]) == 0
    assert "robot: ur10e" in capsys.readouterr().out


def test_diagnose_without_robot_in_metadata_requires_robot(sims, capsys):
    assert main(["diagnose", str(sims["anonymous"]), "--effects", "payload"]) == 2
    err = capsys.readouterr().err
    assert "--robot is required" in err and "anonymous.csv" in err
    assert main(["diagnose", str(sims["anonymous"]), "--robot", "ur10e",
                 "--effects", "payload"]) == 0


def test_explicit_robot_wins_over_metadata_with_a_warning(sims, capsys):
    assert main(["diagnose", str(sims["preset"]), "--robot", "ur10",
                 "--effects", "payload"]) == 0
    captured = capsys.readouterr()
    assert "robot: ur10\n" in captured.out
    assert "warning: the recordings name robot ur10e; using --robot ur10" in captured.err


@pytest.mark.realdata
def test_diagnose_real_ur10e_file_uses_ur10e(capsys):
    path = REAL / "identification_data" / "ur-20_02_05-20sec_8harm.csv"
    if not path.exists():
        pytest.skip("real UR10e data absent")
    assert main(["diagnose", str(path), "--effects", "payload"]) == 0
    assert "robot: ur10e" in capsys.readouterr().out


# ------------------------------------------------------------------ --column-map
@pytest.mark.parametrize("kind", ["json", "file", "preset"])
def test_column_map_option_on_diagnose(sims, kind, tmp_path, capsys):
    if kind == "preset":
        path, value = sims["preset"], "ur10e_mamedov"
    else:
        path, value = sims["custom"], json.dumps(CUSTOM_MAP)
        if kind == "file":
            (tmp_path / "map.json").write_text(value)
            value = str(tmp_path / "map.json")
    assert main(["diagnose", str(path), "--column-map", value, "--robot", "ur10e",
                 "--effects", "payload"]) == 0
    assert "What is missing" in capsys.readouterr().out


def test_custom_layout_without_column_map_fails_with_a_hint(sims, capsys):
    assert main(["diagnose", str(sims["custom"]), "--robot", "ur10e"]) == 2
    err = capsys.readouterr().err
    assert "26 fields" in err and "on the command line: --column-map" in err


@pytest.mark.parametrize("value, message", [
    ("not_a_preset", "neither a preset"),
    ("{bad json", "not valid JSON"),
    ("[1, 2]", "neither a preset"),
])
def test_bad_column_map_is_a_usage_error(value, message, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["train", "a.csv", "-o", "m.skops", "--column-map", value])
    assert message in capsys.readouterr().err


def test_every_subcommand_that_reads_recordings_has_column_map():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, sp in sub.choices.items():
        dests = {a.dest for a in sp._actions}
        if any(a.dest in ("train", "recordings") for a in sp._actions):
            assert "column_map" in dests, name


# ------------------------------------------------------------------ Recording repr
def test_recording_repr_is_a_short_summary():
    rec = simulate_joint1_cyclic(random_state=0)
    text = repr(rec)
    assert str(rec) == text
    assert len(text) < 300 and "\n" not in text
    assert f"{rec.n_samples} samples x 6 joints" in text
    assert "array" not in text and "..." not in text
    assert text.startswith("Recording(") and rec.name in text


# ------------------------------------------------------------------ gpcd train
def test_train_p_f_with_robot_from_metadata(sims, tmp_path, capsys):
    from sklearn_gpcd.workflow import load_model

    out = tmp_path / "pf.joblib"
    assert main(["train", str(sims["rtde"]), "--model", "p_f", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "trained P_F for robot ur10e (6 joints) on 1 recording(s)" in captured.out
    assert "causal inputs" in captured.out and "GP support 2000 rows per joint" in captured.out
    assert "fitting P_F (6 joints)" in captured.err and "done in" in captured.err
    trained = load_model(out, trust_pickle=True)
    model, rec = trained.regressor, sims["rec"]
    X = trained.features.transform(load_recording(sims["rtde"]))
    assert model.predict(X).shape == rec.current.shape
    assert len(model.support_indices_[0]) == 2000 < len(X)
    # P_f reads only [q, qd, qdd]: its file requires none of the controller's signals
    assert {k: trained.training[k] for k in ("model", "inputs", "n_support", "optimizer",
                                             "seed", "robot", "signals")} == {
        "model": "p_f", "inputs": "causal", "n_support": 2000, "optimizer": "auto",
        "seed": 0, "robot": "ur10e", "signals": []}
    bare = load_recording(sims["rtde"]).replace(target_q=None, target_qd=None,
                                                target_current=None)
    np.testing.assert_array_equal(model.predict(trained.features.transform(bare)),
                                  model.predict(X))


def test_train_inputs_optimizer_and_seed_options(sims, tmp_path, capsys):
    """--inputs zero-phase fits on make_inputs' rows; the default fits on the causal rows the
    detector computes; --optimizer and --seed reach the regressor; all are recorded."""
    from sklearn_gpcd.features import make_inputs
    from sklearn_gpcd.gp import make_sp_c
    from sklearn_gpcd.workflow import load_model, train_model

    rec = load_recording(sims["rtde"])
    paths = {}
    for inputs in ("causal", "zero-phase"):
        paths[inputs] = tmp_path / f"{inputs}.joblib"
        assert main(["train", str(sims["rtde"]), "--model", "sp_c", "--inputs", inputs,
                     "--n-support", "60", "--optimizer", "adam", "--seed", "3", "-q",
                     "--n-jobs", "1", "-o", str(paths[inputs])]) == 0
    assert "zero-phase inputs" in capsys.readouterr().out
    causal, zero = (load_model(paths[k], trust_pickle=True) for k in ("causal", "zero-phase"))
    assert (causal.training["inputs"], zero.training["inputs"]) == ("causal", "zero-phase")
    for trained in (causal, zero):
        assert trained.regressor.optimizer_ == "adam" == trained.training["optimizer"]
        assert trained.regressor.random_state == 3 == trained.training["seed"]
    # each is the factory fitted on its rows: causal rows (those the detector computes)
    # or make_inputs' zero-phase rows
    X_causal, (X_zero, y) = causal.features.transform(rec), make_inputs([rec])
    for trained, X in ((causal, X_causal), (zero, X_zero)):
        expected = make_sp_c(6, n_support=60, optimizer="adam", batch_size=60,
                             random_state=3, n_jobs=1).fit(X, y)
        np.testing.assert_array_equal(trained.regressor.predict(X_causal),
                                      expected.predict(X_causal))
    assert not np.array_equal(causal.regressor.predict(X_causal),
                              zero.regressor.predict(X_causal))
    # gpcd train is train_model with the same options
    direct = train_model([rec], model="sp_c", n_support=60, optimizer="adam", seed=3,
                         n_jobs=1)
    np.testing.assert_array_equal(direct.regressor.predict(X_causal),
                                  causal.regressor.predict(X_causal))


def test_train_coulomb_width_reaches_every_joint_and_is_recorded(sims, tmp_path, capsys):
    from sklearn_gpcd.workflow import load_model

    out = tmp_path / "pf.joblib"
    assert main(["train", str(sims["rtde"]), "--model", "p_f", "--coulomb-width", "0.02",
                 "--n-support", "50", "-q", "-o", str(out)]) == 0
    assert "Coulomb tanh(qd / 0.02)" in capsys.readouterr().out
    trained = load_model(out, trust_pickle=True)
    assert trained.training["coulomb_width"] == 0.02
    assert [mean.features.friction.coulomb_width for mean in trained.regressor.mean] == [0.02] * 6
    sign = main(["train", str(sims["rtde"]), "--model", "p_f", "--n-support", "50", "-q",
                 "-o", str(tmp_path / "sign.joblib")])
    signed = load_model(tmp_path / "sign.joblib", trust_pickle=True)  # our own pickle
    assert sign == 0 and signed.training["coulomb_width"] is None
    X = trained.features.transform(load_recording(sims["rtde"]))
    assert not np.array_equal(trained.regressor.predict(X), signed.regressor.predict(X))
    for args, message in ((["--model", "p_f", "--coulomb-width", "0"], "expected a number > 0"),
                          (["--model", "sp_c", "--coulomb-width", "0.01"], "has none")):
        capsys.readouterr()
        assert main(["train", str(sims["rtde"]), *args, "-q",
                     "-o", str(tmp_path / "bad.joblib")]) == 2
        assert message in capsys.readouterr().err


def test_train_sp_c_needs_the_target_current(sims, tmp_path, capsys):
    rec = load_recording(sims["rtde"]).replace(target_current=None)
    path = write_rtde_csv(rec, tmp_path / "no_ic.csv", robot_comment=True)
    assert main(["train", str(path), "--model", "sp_c", "-q",
                 "-o", str(tmp_path / "m.joblib")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs the target current" in err[0]


def test_train_sp_s_with_column_map_and_n_support(sims, tmp_path, capsys):
    pytest.importorskip("skops")
    from sklearn_gpcd.workflow import load_model

    out = tmp_path / "sps.skops"
    assert main(["train", str(sims["custom"]), "--column-map", json.dumps(CUSTOM_MAP),
                 "--robot", "ur10e", "--model", "sp_s", "--n-support", "150",
                 "-o", str(out), "-q"]) == 0
    captured = capsys.readouterr()
    assert "GP support 150 rows per joint, optimizer fmin_l_bfgs_b" in captured.out
    assert "fitting" not in captured.err and "ETA" not in captured.err  # -q: no bars
    assert len(load_model(out).regressor.support_indices_[0]) == 150


def test_train_progress_bar_has_an_eta(sims, tmp_path, capsys):
    assert main(["train", str(sims["rtde"]), str(sims["preset"]), "--model", "p_f",
                 "--n-support", "100", "-o", str(tmp_path / "m.joblib")]) == 0
    err = capsys.readouterr().err
    assert "reading training recordings" in err and "computing GP inputs" in err
    assert "ETA" in err


def test_train_rule_thins_long_logs_to_every_kth_row():
    from sklearn_gpcd.workflow import MAX_TRAIN_ROWS
    from sklearn_gpcd.workflow import training_rows as _training_rows

    assert _training_rows(41_707) == slice(0, 41_707, 1)
    rows = _training_rows(1_800_000)
    assert rows.step == 9 and len(range(1_800_000)[rows]) <= MAX_TRAIN_ROWS


def test_factories_never_default_to_an_exact_gp_on_all_rows():
    from sklearn_gpcd.gp import make_p_f, make_sp_p, make_sp_s
    from sklearn_gpcd.gp._support import AUTO_SUPPORT

    for factory in (make_p_f, make_sp_s, make_sp_p):
        assert factory(None, 2).n_support == "auto"
    rng = np.random.RandomState(0)
    X = rng.normal(size=(AUTO_SUPPORT + 500, 12))
    y = rng.normal(size=(len(X), 2))
    model = make_p_f(None, 2).fit(X, y)
    assert [len(s) for s in model.support_indices_] == [AUTO_SUPPORT] * 2
    exact = make_p_f(None, 2, n_support=None).fit(X[:300], y[:300])
    assert len(exact.support_indices_[0]) == 300


def test_n_support_auto_is_validated_and_keeps_small_sets_whole():
    from sklearn_gpcd.gp import SemiParametricGPRegressor

    X = np.linspace(0, 1, 50)[:, None]
    gp = SemiParametricGPRegressor(n_support="auto").fit(X, np.sin(X[:, 0]))
    assert len(gp.support_indices_) == 50
    with pytest.raises(ValueError, match="'auto'"):
        SemiParametricGPRegressor(n_support="all").fit(X, X[:, 0])


def test_train_without_robot_anywhere_needs_it_for_a_rigid_body_model(sims, tmp_path,
                                                                      capsys):
    # without a robot, only models that need none are fitted (tests/test_cli_train_auto.py)
    assert main(["train", str(sims["anonymous"]), "--model", "p_f",
                 "-o", str(tmp_path / "m.skops")]) == 2
    assert "--model p_f needs the robot's rigid-body model" in capsys.readouterr().err


def test_rtde_csv_keeps_the_robot_name(tmp_path):
    rec = Recording(time=[0.0, 0.002], q=[[0.1], [0.2]], qd=[[0.0], [0.0]],
                    current=[[1.0], [1.0]], metadata={"robot": "ur5e"})
    assert write_rtde_csv(rec, tmp_path / "plain.csv").read_text().startswith("timestamp,")
    path = write_rtde_csv(rec, tmp_path / "a.csv", robot_comment=True)
    assert path.read_text().splitlines()[0] == "# robot: ur5e"
    back = load_recording(path)
    assert back.metadata["robot"] == "ur5e" and back.equals(rec)


def test_train_records_the_largest_acceleration_for_the_braking_regime(sims, tmp_path,
                                                                       capsys):
    from sklearn_gpcd.layout import block_columns
    from sklearn_gpcd.workflow import load_model

    out = tmp_path / "sp_c.joblib"
    assert main(["train", str(sims["rtde"]), "--model", "sp_c", "--n-support", "50", "-q",
                 "-o", str(out)]) == 0
    trained = load_model(out, trust_pickle=True)
    X = trained.features.transform(load_recording(sims["rtde"]))
    limit = np.abs(X[:, block_columns("qdd", 6)]).max()
    assert trained.training["acceleration_limit"] == pytest.approx(limit)
    assert f"largest |qdd| of the training rows {limit:.3g} rad/s^2" in capsys.readouterr().out
