"""Persistence: joblib and skops round trips, stored versions, skops trust.

Every round trip must give bit-identical outputs (``np.array_equal``), not
merely close ones: a loaded model is the same model.
"""

import pickle
import warnings
import zipfile

import joblib
import numpy as np
from numpy.testing import assert_allclose
import pinocchio as pin
import pytest
import sklearn
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import InconsistentVersionWarning
from sklearn.linear_model import Ridge
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import FunctionTransformer, PolynomialFeatures

import sklearn_gpcd
from sklearn_gpcd import _persistence
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    CollisionThresholdCV,
    MonitorStatus,
    StreamingMonitor,
    stack_currents,
)
from sklearn_gpcd.diagnosis import DiagnosedModel, DynamicsDiagnosis, NominalModel
from sklearn_gpcd.dynamics import FrictionColumns, RigidBodyFeatures
from sklearn_gpcd.features import InverseDynamicsFeatures
from sklearn_gpcd.gp import (
    ParametricMean,
    SemiParametricGPRegressor,
    make_p_f,
    make_sp_p,
    make_sp_s,
)
from sklearn_gpcd.persistence import (
    GPCDVersionWarning,
    MalformedFileError,
    UntrustedTypesError,
    load,
    save,
)

skops_io = pytest.importorskip("skops.io")

FORMATS = ["joblib", "skops"]
N_JOINTS = 6
FACTORIES = {"P_f": make_p_f, "SP_S": make_sp_s, "SP_P": make_sp_p}


# ----------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def recording():
    """A short simulated UR10 run (the paper's D1 with 2 targets, ~960 rows)."""
    return simulate_d1("ur10", n_targets=2, random_state=0)


@pytest.fixture(scope="module")
def data(recording):
    """Training rows (every 8th) and test rows (the others) of x^a and i."""
    X = InverseDynamicsFeatures().fit_transform(recording)
    train = np.zeros(len(X), dtype=bool)
    train[::8] = True
    return X[train], recording.current[train], X[~train], recording.current[~train]


def fitted_gp(name, data):
    """P_f / SP_S / SP_P with a (trusted) linear parametric mean, 60 support rows."""
    X, Y, _, _ = data
    features = [PolynomialFeatures(degree=1)] * N_JOINTS
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # convergence on a tiny set is not the point
        return FACTORIES[name](
            features, N_JOINTS, friction_columns=None, n_support=60, random_state=0
        ).fit(X, Y)


@pytest.fixture(scope="module")
def detector(data):
    X, Y, _, _ = data
    regressor = make_sp_p(None, N_JOINTS, n_support=60, random_state=0, max_iter=50)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return CollisionDetector(regressor, n_joints=N_JOINTS, normalize="std",
                                 rules=AlarmRule(threshold="std", filter_cutoff=5.0,
                                                 min_duration=3)).fit(stack_currents(X, Y))


def round_trip(obj, fmt, tmp_path, **load_params):
    """``obj`` saved and loaded again (our own pickles are trusted explicitly)."""
    return load(save(obj, tmp_path / f"model.{fmt}"), trust_pickle=fmt == "joblib",
                **load_params)


def bumped(X, Y, start=100, stop=160, amps=0.8):
    """Detector input with a collision-like current offset on rows start:stop."""
    Y = Y.copy()
    Y[start:stop] += amps
    return stack_currents(X, Y)


class UserRegressor(RegressorMixin, BaseEstimator):
    """A regressor defined outside the trusted packages (predicts the mean)."""

    def fit(self, X, y):
        self.mean_ = np.mean(y, axis=0)
        return self

    def predict(self, X):
        return np.tile(self.mean_, (len(X), 1))


# ------------------------------------------------------------ round trips
@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("name", list(FACTORIES))
def test_gp_round_trip_gives_identical_predictions(name, fmt, data, tmp_path):
    gp = fitted_gp(name, data)
    copy = round_trip(gp, fmt, tmp_path)
    X_test = data[2]
    mean, std = gp.predict(X_test, return_std=True)
    mean2, std2 = copy.predict(X_test, return_std=True)
    assert np.array_equal(mean, mean2) and np.array_equal(std, std2)
    assert np.array_equal(gp.predict(X_test[:1]), copy.predict(X_test[:1]))  # lean path
    assert np.array_equal(gp.log_marginal_likelihood_value_, copy.log_marginal_likelihood_value_)
    assert [repr(k) for k in copy.kernel_] == [repr(k) for k in gp.kernel_]
    assert copy.get_params(deep=False).keys() == gp.get_params(deep=False).keys()


@pytest.mark.parametrize("fmt", FORMATS)
def test_gp_file_leaves_out_the_cholesky_factor(fmt, data, tmp_path):
    """A model file holds what prediction needs, not the n x n factor: the
    std, which needs it, is rebuilt exactly from the support rows."""
    X, Y, X_test, _ = data
    gp = make_sp_p(None, N_JOINTS, n_support=300, random_state=0, max_iter=20)  # all 120 rows
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp.fit(X, Y)
    factors = sum(out.posterior.L.nbytes for out in gp._outputs)  # 6 x 120^2 floats
    path = save(gp, tmp_path / f"model.{fmt}")
    if fmt == "skops":  # no stored array as large as one joint's factor (120^2 floats)
        with zipfile.ZipFile(path) as archive:
            arrays = [i.file_size for i in archive.infolist() if i.filename.endswith(".npy")]
        assert max(arrays) < factors / N_JOINTS
    else:
        assert path.stat().st_size < factors / 2  # the support rows, 6 x 120 x 36 floats
    copy = load(path, trust_pickle=fmt == "joblib")
    assert all(out.posterior._L is None for out in copy._outputs)
    assert np.array_equal(copy.predict(X_test), gp.predict(X_test))
    mean, std = gp.predict(X_test, return_std=True)
    mean2, std2 = copy.predict(X_test, return_std=True)
    assert np.array_equal(mean, mean2)
    assert_allclose(std2, std, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("fmt", FORMATS)
def test_detector_round_trip_gives_identical_decisions(fmt, detector, data, tmp_path):
    copy = round_trip(detector, fmt, tmp_path)
    Z = bumped(data[2], data[3])
    for method in ("decision_function", "score_samples", "predict"):
        assert np.array_equal(getattr(copy, method)(Z), getattr(detector, method)(Z)), method
    assert np.array_equal(copy.thresholds_, detector.thresholds_)
    assert (detector.predict(Z) == -1).any()  # the comparison covers alarms too


@pytest.mark.parametrize("fmt", FORMATS)
def test_streaming_monitor_resumes_where_it_was_saved(fmt, detector, data, tmp_path):
    Z = bumped(data[2][:300], data[3][:300])  # std per tick: keep it short
    monitor = StreamingMonitor(detector)
    monitor.replay(Z[:120])  # mid-collision: filter and debounce state are non-trivial
    copy = round_trip(monitor, fmt, tmp_path)
    assert copy.status is monitor.status and isinstance(copy.status, MonitorStatus)
    assert copy.n_ticks == monitor.n_ticks == 120
    rest_copy, rest = copy.replay(Z[120:]), monitor.replay(Z[120:])
    for key, value in rest.items():
        if key == "bands":
            for band_copy, band in zip(rest_copy.bands, value):
                for name, array in band.items():
                    assert np.array_equal(band_copy[name], array), (key, name)
        else:
            assert np.array_equal(rest_copy[key], value), key
    assert (rest.prediction == -1).any() and (rest.prediction == 1).any()
    # the copy still writes its inputs into the row buffer it checks
    assert copy.update(np.full(Z.shape[1], np.nan)) == MonitorStatus.SENSOR_FAULT


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_monitor_saved_with_the_removed_motion_envelope_is_refused(fmt, detector, tmp_path):
    monitor = StreamingMonitor(detector)
    assert round_trip(monitor, fmt, tmp_path).n_ticks == 0  # without the ring: loads
    # what a band of a monitor saved before issue 45 removed the envelope held
    monitor.bands[0]._envelope = np.ones((25, detector.n_joints))
    with pytest.raises(MalformedFileError, match="motion envelope.*gpcd calibrate"):
        round_trip(monitor, fmt, tmp_path)


@pytest.mark.parametrize("fmt", FORMATS)
def test_pipeline_from_recordings_round_trip(fmt, recording, tmp_path):
    pipe = Pipeline([
        ("features", InverseDynamicsFeatures()),
        ("gp", make_sp_p(None, N_JOINTS, n_support=40, optimizer=None, random_state=0)),
    ])
    part = recording.slice(0, 300)
    pipe.fit(part, part.current)
    copy = round_trip(pipe, fmt, tmp_path)
    rest = recording.slice(300, 600)
    assert np.array_equal(copy.predict(rest), pipe.predict(rest))
    assert isinstance(copy.named_steps["features"], InverseDynamicsFeatures)


@pytest.mark.parametrize("fmt", FORMATS)
def test_pipeline_ending_in_a_detector_round_trip(fmt, data, tmp_path):
    X, Y, X_test, Y_test = data
    pipe = Pipeline([
        ("identity", FunctionTransformer()),
        ("detector",
         CollisionDetector(Ridge(), n_joints=N_JOINTS, rules=AlarmRule(contamination=0.01))),
    ]).fit(stack_currents(X, Y))
    copy = round_trip(pipe, fmt, tmp_path)
    Z = bumped(X_test, Y_test)
    assert np.array_equal(copy.decision_function(Z), pipe.decision_function(Z))
    assert np.array_equal(copy.predict(Z), pipe.predict(Z))


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("factory", [make_p_f, make_sp_p], ids=["P_f", "SP_P"])
def test_rigid_body_features_round_trip(factory, fmt, data, tmp_path):
    """Estimators holding a Robot (a pinocchio.Model) survive both formats,
    and a skops file needs no ``trusted=`` for them."""
    X, Y, X_test, _ = data
    features = [RigidBodyFeatures("ur10", joint=j) for j in range(N_JOINTS)]
    gp = factory(features, N_JOINTS, optimizer=None, n_support=60, random_state=0).fit(X, Y)
    path = save(gp, tmp_path / f"model.{fmt}")
    if fmt == "skops":
        untrusted = skops_io.get_untrusted_types(file=path)
        assert not [name for name in untrusted if name.startswith("pinocchio")], untrusted
    copy = load(path, trust_pickle=fmt == "joblib")
    robots = [mean.features_.robot_ for mean in copy.mean_]
    assert len(robots) == N_JOINTS
    assert all(isinstance(robot.model, pin.Model) for robot in robots)
    assert robots[0].model is not gp.mean_[0].features_.robot_.model
    mean, std = gp.predict(X_test, return_std=True)
    mean2, std2 = copy.predict(X_test, return_std=True)
    assert np.array_equal(mean2, mean) and np.array_equal(std2, std)


# ----------------------------------------------------------------- versions
def stateful_objects(detector):
    """One instance of every class that records its version."""
    return [
        SemiParametricGPRegressor(),
        ParametricMean(),
        CollisionDetector(),
        CollisionThresholdCV(CollisionDetector(Ridge(), rules=AlarmRule()),
                             {"rules__min_duration": [1, 3]}),
        InverseDynamicsFeatures(),
        RigidBodyFeatures("ur10"),
        FrictionColumns(coulomb_width=0.01),
        DynamicsDiagnosis(),
        DiagnosedModel(NominalModel("ur10"), []),
        StreamingMonitor(detector),
    ]


def test_every_stateful_object_stores_the_versions(detector):
    for obj in stateful_objects(detector):
        state = obj.__getstate__()
        assert state["_sklearn_gpcd_version"] == sklearn_gpcd.__version__, type(obj)
        assert state["_sklearn_version"] == sklearn.__version__, type(obj)
        again = pickle.loads(pickle.dumps(obj))
        assert "_sklearn_gpcd_version" not in vars(again), type(obj)
        assert "_sklearn_version" not in vars(again), type(obj)


@pytest.mark.parametrize("fmt", FORMATS)
def test_same_version_loads_without_warning(fmt, detector, tmp_path):
    path = save(detector, tmp_path / f"det.{fmt}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load(path, trust_pickle=True)


@pytest.mark.parametrize("fmt", FORMATS)
def test_other_package_version_warns_on_load(fmt, detector, tmp_path, monkeypatch):
    with monkeypatch.context() as patch:
        patch.setattr(_persistence, "__version__", "0.0.1")
        path = save(detector, tmp_path / f"det.{fmt}")
    with pytest.warns(GPCDVersionWarning, match="saved with sklearn-gpcd 0.0.1") as record:
        copy = load(path, trust_pickle=True)
    names = {w.message.estimator_name for w in record if w.category is GPCDVersionWarning}
    assert {"CollisionDetector", "SemiParametricGPRegressor"} <= names
    assert all(w.message.original_version == "0.0.1" for w in record
               if w.category is GPCDVersionWarning)
    assert "_sklearn_gpcd_version" not in vars(copy)


@pytest.mark.parametrize("fmt", FORMATS)
def test_other_sklearn_version_warns_on_load(fmt, tmp_path, monkeypatch):
    gp = SemiParametricGPRegressor(optimizer=None).fit(np.eye(3), np.arange(3.0))
    with monkeypatch.context() as patch:
        patch.setattr(sklearn, "__version__", "0.1")
        path = save(gp, tmp_path / f"gp.{fmt}")
    with pytest.warns(InconsistentVersionWarning, match="from version 0.1 when"):
        load(path, trust_pickle=True)


def test_pickle_without_a_version_warns():
    gp = SemiParametricGPRegressor()
    state = {k: v for k, v in gp.__getstate__().items() if k != "_sklearn_gpcd_version"}
    with pytest.warns(GPCDVersionWarning, match="unknown"):
        SemiParametricGPRegressor.__new__(SemiParametricGPRegressor).__setstate__(state)


# ------------------------------------------------------------- skops trust
def test_untrusted_type_in_a_skops_file_is_refused(data, tmp_path):
    X, Y, X_test, Y_test = data
    det = CollisionDetector(UserRegressor(), n_joints=N_JOINTS).fit(stack_currents(X, Y))
    path = save(det, tmp_path / "det.skops")
    name = f"{UserRegressor.__module__}.UserRegressor"
    with pytest.raises(UntrustedTypesError, match="not trusted") as info:
        load(path)
    assert info.value.types == [name]  # only it: our own and sklearn types are trusted
    assert name in str(info.value) and "det.skops" in str(info.value)
    Z = stack_currents(X_test, Y_test)
    for trusted in ([name], [UserRegressor]):
        copy = load(path, trusted=trusted)
        assert np.array_equal(copy.decision_function(Z), det.decision_function(Z))


def test_library_functions_are_not_trusted_but_ufuncs_are(tmp_path):
    path = save(FunctionTransformer(np.linalg.norm), tmp_path / "norm.skops")
    with pytest.raises(UntrustedTypesError, match=r"numpy\.linalg\.norm"):
        load(path)
    assert load(save(FunctionTransformer(np.sin), tmp_path / "sin.skops")).func is np.sin


# ------------------------------------------------------------------ errors
def test_unknown_extension_is_an_error(tmp_path):
    with pytest.raises(ValueError, match=r"model\.txt.*extension '\.txt'.*\.joblib"):
        save(Ridge(), tmp_path / "model.txt")
    with pytest.raises(ValueError, match="extension ''"):
        load(tmp_path / "model")


def test_file_that_is_not_a_skops_archive(tmp_path):
    path = tmp_path / "model.skops"
    path.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="model.skops is not a skops file"):
        load(path)


def test_bad_trusted_item(tmp_path):
    path = save(Ridge(), tmp_path / "ridge.skops")
    with pytest.raises(TypeError, match="trusted must hold type names"):
        load(path, trusted=[3])


def test_missing_skops_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "skops.io", None)
    with pytest.raises(ImportError, match=r"sklearn-gpcd\[persist\]"):
        save(Ridge(), tmp_path / "ridge.skops")
    joblib_path = save(Ridge(), tmp_path / "ridge.joblib")  # joblib needs no skops
    assert isinstance(joblib.load(joblib_path), Ridge)
