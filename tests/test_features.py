"""Tests of sklearn_gpcd.features: derivatives, GP inputs, quasi-static masks."""

import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import cumulative_trapezoid
from scipy.signal import butter, savgol_coeffs, sosfiltfilt
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.utils.estimator_checks import (
    check_get_params_invariance,
    check_no_attributes_set_in_init,
    check_parameters_default_constructible,
    check_set_params,
)

from sklearn_gpcd.layout import block_columns, column_names
from sklearn_gpcd.features import (
    InverseDynamicsFeatures,
    MissingSignalWarning,
    contiguous_segments,
    differentiate,
    lowpass,
    make_inputs,
    quasi_static_mask,
    regimes,
    targets,
)
from sklearn_gpcd.io import Recording

# --------------------------------------------------------------------------
# helpers


def ur10e_like_times(rng, n):
    """Time stamps with the UR10e RTDE jitter: mostly 10/12 ms, some 2-34 ms."""
    steps = rng.choice(
        [0.010, 0.012, 0.002, 0.020, 0.034], size=n - 1, p=[0.80, 0.15, 0.02, 0.02, 0.01]
    )
    return np.concatenate([[0.0], np.cumsum(steps)])


def sines(t):
    """A sum of sines in the robot's band (0.5-2.1 Hz) and its derivative."""
    f = np.array([0.5, 1.3, 2.1])
    a = np.array([1.0, 0.5, 0.2])
    p = np.array([0.0, 1.0, 2.0])
    w = 2 * np.pi * f
    x = np.sin(np.outer(t, w) + p) @ a
    dx = np.cos(np.outer(t, w) + p) @ (a * w)
    return x, dx


def rms(v):
    return float(np.sqrt(np.mean(np.square(v))))


def noise_gain(method, h):
    """RMS of the derivative of unit white noise through the method's filter.

    For a linear filter with impulse response ``g`` on a grid of step ``h``,
    white noise of standard deviation ``sigma`` gives a derivative error of
    RMS ``sigma * ||g||``. Computed on a uniform grid, independently of the
    test signal.
    """
    if method == "savgol":  # default window_length=21, polyorder=3
        return float(np.linalg.norm(savgol_coeffs(21, 3, deriv=1, delta=h)))
    impulse = np.zeros(1001)
    impulse[500] = 1.0  # default order=5, cutoff=7.5 Hz
    sos = butter(5, 7.5 * 2 * h, output="sos")
    return float(np.linalg.norm(np.gradient(sosfiltfilt(sos, impulse), h)))


def make_recording(n=60, n_joints=2, name="rec", seed=0, **signals):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    q = rng.normal(size=(n, n_joints))
    base = dict(time=t, q=q, qd=rng.normal(size=(n, n_joints)),
                current=rng.normal(size=(n, n_joints)), name=name)
    base.update(signals)
    return Recording(**base)


def full_recording(n=60, n_joints=2, name="full", seed=0):
    rng = np.random.default_rng(seed)
    shape = (n, n_joints)
    return make_recording(
        n, n_joints, name, seed,
        target_q=rng.normal(size=shape), target_qd=rng.normal(size=shape),
        target_current=rng.normal(size=shape),
    )


def load_ur10e(path):
    """Minimal parser of a 31-column UR10e CSV (no header)."""
    data = np.loadtxt(path, delimiter=",")
    return Recording(
        time=data[:, 0] - data[0, 0], q=data[:, 1:7], qd=data[:, 7:13],
        current=data[:, 13:19], target_current=data[:, 19:25], name=path.name,
    )


# --------------------------------------------------------------------------
# differentiation


@pytest.mark.parametrize("window_length, polyorder", [(5, 2), (7, 3), (11, 3), (9, 4)])
def test_savgol_exact_on_polynomials_uniform(window_length, polyorder):
    t = np.arange(40) * 0.01 + 3.0
    coefs = np.arange(1, polyorder + 2, dtype=float)  # degree == polyorder
    x = np.column_stack([np.polyval(coefs, t), np.polyval(-coefs[1:], t)])
    expected = np.column_stack(
        [np.polyval(np.polyder(coefs), t), np.polyval(np.polyder(-coefs[1:]), t)]
    )
    got = differentiate(t, x, window_length=window_length, polyorder=polyorder)
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-7)


def test_savgol_exact_on_cubic_irregular(rng):
    # Cubic-spline resampling reproduces cubics, so exactness survives jitter.
    t = ur10e_like_times(rng, 300)
    x = 0.5 * t**3 - 2 * t**2 + t - 1
    np.testing.assert_allclose(
        differentiate(t, x), 1.5 * t**2 - 4 * t + 1, rtol=1e-7, atol=1e-7
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_derivative_error_on_jittered_noisy_sines(seed):
    """Error bound: bias + noise, with the noise term from the filter's gain.

    sigma = 2e-3 is the UR10e velocity noise level relative to the signal
    (high-pass residual of measured qd ~1.5e-3 rad/s for qd RMS ~0.4 rad/s).
    A linear filter with impulse response g turns white noise into a
    derivative error of RMS sigma * ||g|| (``noise_gain``), so we expect
    RMS error ~ sqrt(bias^2 + (sigma * gain)^2) and allow
    1.5 * (bias_bound + sigma * gain), bias_bound = 0.5 % of the RMS
    derivative; the margin covers the resampling of the noise. Errors are
    measured 0.3 s away from the ends (filtfilt edge transient, documented),
    the whole signal gets twice the bound.
    """
    rng = np.random.default_rng(seed)
    t = ur10e_like_times(rng, 2000)
    inner = (t > 0.3) & (t < t[-1] - 0.3)
    x, dx = sines(t)
    sigma = 2e-3
    noisy = x + sigma * rng.standard_normal(t.size)
    h = np.median(np.diff(t))
    bias_bound = 0.005 * rms(dx)
    raw_error = rms((differentiate(t, noisy, "gradient") - dx)[inner])
    for method in ("savgol", "butter"):
        clean_error = rms((differentiate(t, x, method) - dx)[inner])
        assert clean_error < bias_bound, (method, clean_error, bias_bound)
        error = differentiate(t, noisy, method) - dx
        bound = 1.5 * (bias_bound + sigma * noise_gain(method, h))
        assert rms(error[inner]) < bound, (method, rms(error[inner]), bound)
        assert rms(error) < 2 * bound, (method, rms(error), bound)
        assert rms(error[inner]) < 0.3 * raw_error, (method, rms(error), raw_error)
    # The raw finite difference is accurate without noise ...
    assert rms((differentiate(t, x, "gradient") - dx)[inner]) < bias_bound
    # ... and amplifies it: sigma * sqrt(2) / (2 h) = 0.14 on a 10 ms grid.
    assert raw_error > 0.5 * sigma * np.sqrt(2) / (2 * h)


def test_differentiate_shapes_and_butter_options(rng):
    t = ur10e_like_times(rng, 400)
    x, dx = sines(t)
    one = differentiate(t, x, "butter", order=4, cutoff=7.5)
    two = differentiate(t, np.column_stack([x, 2 * x]), "butter", order=4, cutoff=7.5)
    assert one.shape == (400,)
    assert two.shape == (400, 2)
    np.testing.assert_allclose(two[:, 1], 2 * one, rtol=1e-10, atol=1e-10)
    inner = (t > 0.3) & (t < t[-1] - 0.3)
    assert rms((one - dx)[inner]) < 0.005 * rms(dx)


def test_lowpass_removes_noise_and_high_frequency(rng):
    # irregular times: white noise is cut to the pass band
    t = ur10e_like_times(rng, 1500)
    inner = (t > 0.5) & (t < t[-1] - 0.5)
    slow, _ = sines(t)
    sigma = 0.05
    filtered = lowpass(t, slow + sigma * rng.standard_normal(t.size), cutoff=5.0)
    # pass band 5 Hz of a ~50 Hz Nyquist band: residual ~ sigma * sqrt(0.1)
    assert rms((filtered - slow)[inner]) < 0.5 * sigma
    # uniform times: a 30 Hz tone is attenuated by (30/5)^-10 squared
    t = np.arange(1000) * 0.01
    slow, _ = sines(t)
    filtered = lowpass(t, slow + 0.3 * np.sin(2 * np.pi * 30 * t), cutoff=5.0)
    assert np.abs(filtered - slow)[50:-50].max() < 1e-3


@pytest.mark.parametrize(
    "time, x, kwargs, match",
    [
        ([0.0, 0.01, 0.01, 0.03], np.zeros(4), {"method": "gradient"},
         "strictly increasing; row 2"),
        ([0.0, 0.01, 0.005, 0.03], np.zeros(4), {"method": "gradient"}, "row 2"),
        (np.arange(5) * 0.01, [0, 1, np.nan, 3, 4], {}, "NaN or inf at row 2"),
        (np.arange(5) * 0.01, np.zeros(5), {}, "too short.*at least 21 \\(window_length\\)"),
        (np.arange(18) * 0.01, np.zeros(18), {"method": "butter"}, "needs at least 19"),
        (np.arange(50) * 0.01, np.zeros(50), {"method": "butter", "cutoff": 60.0},
         "Nyquist"),
        (np.arange(50) * 0.01, np.zeros(50), {"window_length": 10}, "odd"),
        (np.arange(50) * 0.01, np.zeros(50), {"method": "spline"}, "method must be"),
        (np.arange(50) * 0.01, np.zeros(49), {}, "49 rows"),
        ([0.0], [1.0], {}, "at least 2"),
    ],
)
def test_differentiate_errors(time, x, kwargs, match):
    with pytest.raises(ValueError, match=match):
        differentiate(time, x, **kwargs)


def test_differentiate_unknown_option():
    with pytest.raises(TypeError, match="cutoff.*'savgol'"):
        differentiate(np.arange(50) * 0.01, np.zeros(50), cutoff=5.0)


# --------------------------------------------------------------------------
# InverseDynamicsFeatures


@pytest.mark.parametrize("augmented", [True, False])
def test_feature_names_follow_layout(augmented):
    rec = full_recording(n_joints=3)
    features = InverseDynamicsFeatures(augmented=augmented).fit(rec)
    names = features.get_feature_names_out()
    assert list(names) == column_names(3, augmented)
    assert features.transform(rec).shape == (rec.n_samples, len(names))


def test_state_blocks_and_augmented_values():
    rec = full_recording(n_joints=2).replace(qdd=np.full((60, 2), 7.0))
    X = InverseDynamicsFeatures().fit_transform(rec)
    n = rec.n_joints
    np.testing.assert_array_equal(X[:, block_columns("q", n)], rec.q)
    np.testing.assert_array_equal(X[:, block_columns("qd", n)], rec.qd)
    np.testing.assert_array_equal(X[:, block_columns("qdd", n)], rec.qdd)
    np.testing.assert_array_equal(X[:, block_columns("e_q", n)], rec.target_q - rec.q)
    np.testing.assert_array_equal(X[:, block_columns("de_q", n)], rec.target_qd - rec.qd)
    np.testing.assert_array_equal(X[:, block_columns("i_c", n)], rec.target_current)

    flipped = InverseDynamicsFeatures(sign="actual-minus-target").fit_transform(rec)
    np.testing.assert_array_equal(flipped[:, 6:10], -X[:, 6:10])
    np.testing.assert_array_equal(flipped[:, 10:], X[:, 10:])


def test_missing_target_q_one_warning_and_zeros():
    rec = full_recording().replace(target_q=None)
    features = InverseDynamicsFeatures()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        X = features.fit_transform(rec)
    missing = [w for w in caught if issubclass(w.category, MissingSignalWarning)]
    assert len(missing) == 1
    message = str(missing[0].message)
    assert "target_q missing" in message and "e_q set to 0" in message
    assert "target_qd" not in message
    assert features.missing_signals_ == ("target_q",)
    np.testing.assert_array_equal(X[:, block_columns("e_q", 2)], 0.0)
    np.testing.assert_array_equal(X[:, block_columns("de_q", 2)], rec.target_qd - rec.qd)


def test_missing_target_qd_is_differentiated_from_target_q():
    t = np.arange(80) * 0.01
    target_q = np.column_stack([t**2, 1 - t**3])
    target_qd = np.column_stack([2 * t, -3 * t**2])
    rec = make_recording(80, target_q=target_q, target_current=np.ones((80, 2)))
    with pytest.warns(MissingSignalWarning, match="derivative of target_q"):
        X = InverseDynamicsFeatures().fit_transform(rec)
    np.testing.assert_allclose(X[:, block_columns("de_q", 2)], target_qd - rec.qd,
                               atol=1e-8)


def test_not_augmented_ignores_missing_targets():
    rec = make_recording()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        X = InverseDynamicsFeatures(augmented=False).fit_transform(rec)
    assert X.shape == (60, 6)


@pytest.mark.parametrize(
    "acceleration, expected",
    [("auto", "qdd"), ("measured", "qdd"), ("target", "target_qdd"),
     ("differentiate", "differentiated qd")],
)
def test_acceleration_sources(acceleration, expected):
    rng = np.random.default_rng(1)
    rec = make_recording(qdd=rng.normal(size=(60, 2)), target_qdd=rng.normal(size=(60, 2)))
    features = InverseDynamicsFeatures(augmented=False, acceleration=acceleration)
    qdd = features.fit_transform(rec)[:, 4:6]
    assert features.acceleration_sources_ == (expected,)
    reference = {
        "qdd": rec.qdd, "target_qdd": rec.target_qdd,
        "differentiated qd": differentiate(rec.time, rec.qd),
    }[expected]
    np.testing.assert_array_equal(qdd, reference)


def test_auto_acceleration_differentiates_qd_without_qdd():
    t = np.arange(100) * 0.01
    qd = np.column_stack([np.sin(t), t**2])
    rec = Recording(time=t, q=np.zeros((100, 2)), qd=qd, current=np.zeros((100, 2)))
    features = InverseDynamicsFeatures(augmented=False, differentiation="gradient")
    X = features.fit_transform(rec)
    assert features.acceleration_sources_ == ("differentiated qd",)
    np.testing.assert_allclose(X[:, 4:], np.gradient(qd, t, axis=0))


@pytest.mark.parametrize("acceleration, match", [("measured", "no qdd"),
                                                 ("target", "no target_qdd")])
def test_required_acceleration_missing(acceleration, match):
    with pytest.raises(ValueError, match=f"'rec' .*{match}"):
        InverseDynamicsFeatures(acceleration=acceleration).fit(make_recording())


def test_list_equals_concatenated_transforms():
    t = np.arange(100) * 0.01
    first = make_recording(100, name="a", seed=1).replace(qd=np.column_stack([t, t]))
    second = make_recording(100, name="b", seed=2).replace(
        qd=np.column_stack([5 - t, 3 + t])
    )
    features = InverseDynamicsFeatures(augmented=False).fit([first, second])
    stacked = features.transform([first, second])
    separate = np.vstack([features.transform(first), features.transform(second)])
    np.testing.assert_array_equal(stacked, separate)
    # Per-recording derivatives are exact on these linear velocities; a
    # derivative across the jump between the two recordings would not be.
    np.testing.assert_allclose(stacked[:, 4:], np.repeat([[1, 1], [-1, 1]], 100, axis=0),
                               atol=1e-9)
    joined = features.transform(Recording.concatenate([first, second]))
    assert np.abs(joined[:, 4:] - stacked[:, 4:]).max() > 10


def test_one_warning_for_many_recordings():
    recs = [make_recording(name=f"r{i}", seed=i) for i in range(5)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        InverseDynamicsFeatures().fit_transform(recs)
    assert len(caught) == 1
    assert "5 recording(s)" in str(caught[0].message)
    assert "'r0'" in str(caught[0].message) and "2 more" in str(caught[0].message)


def test_different_joint_counts_are_named():
    recs = [make_recording(name="six", n_joints=6), make_recording(name="seven", n_joints=7)]
    with pytest.raises(ValueError, match=r"'six' \(index 0\): 6, 'seven' \(index 1\): 7"):
        InverseDynamicsFeatures().fit(recs)
    with pytest.raises(ValueError, match="different numbers of joints"):
        targets(recs)


def test_transform_checks_fit():
    features = InverseDynamicsFeatures()
    with pytest.raises(NotFittedError):
        features.transform(full_recording())
    features.fit(full_recording(n_joints=2))
    with pytest.raises(ValueError, match="3 joints.*fitted on 2"):
        features.transform(full_recording(n_joints=3))


def test_bad_inputs_named():
    rec = full_recording()
    q = rec.q.copy()
    q[7, 1] = np.nan
    with pytest.raises(ValueError, match="'full'.*q is NaN or inf at row 7, joint 1"):
        InverseDynamicsFeatures().fit_transform(rec.replace(q=q))
    with pytest.raises(TypeError, match="item 1 is a ndarray"):
        InverseDynamicsFeatures().fit([rec, np.zeros((3, 3))])
    with pytest.raises(TypeError, match="got ndarray"):
        InverseDynamicsFeatures().fit(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="empty"):
        InverseDynamicsFeatures().fit([])
    short = make_recording(n=5, name="short")
    with pytest.raises(ValueError, match="'short'.*cannot differentiate qd.*too short"):
        InverseDynamicsFeatures(augmented=False).fit_transform(short)


@pytest.mark.parametrize(
    "params, match",
    [({"acceleration": "guess"}, "acceleration"), ({"differentiation": "fft"}, "differ"),
     ({"sign": "+"}, "sign"), ({"augmented": "yes"}, "augmented"),
     ({"differentiation_options": [11]}, "dict")],
)
def test_invalid_params_raise_in_fit_not_init(params, match):
    features = InverseDynamicsFeatures(**params)  # stored verbatim, no error
    assert features.get_params()[next(iter(params))] == next(iter(params.values()))
    with pytest.raises(ValueError, match=match):
        features.fit(full_recording())


def test_invalid_differentiation_option_raises_in_fit():
    features = InverseDynamicsFeatures(differentiation_options={"cutoff": 5.0})
    with pytest.raises(TypeError, match="cutoff"):
        features.fit(full_recording())


def test_sklearn_api_checks():
    # The common checks need 2-D array input (skipped for recording input,
    # as for text vectorizers); these are the data-free ones.
    name, est = "InverseDynamicsFeatures", InverseDynamicsFeatures()
    check_no_attributes_set_in_init(name, est)
    check_parameters_default_constructible(name, est)
    check_get_params_invariance(name, est)
    check_set_params(name, est)
    fitted = clone(InverseDynamicsFeatures(differentiation="butter")).fit(full_recording())
    assert fitted.get_params()["differentiation"] == "butter"


def test_set_output_pandas():
    pd = pytest.importorskip("pandas")
    rec = full_recording()
    frame = InverseDynamicsFeatures().set_output(transform="pandas").fit_transform(rec)
    assert isinstance(frame, pd.DataFrame)
    assert list(frame.columns) == column_names(2)


def test_targets_and_make_inputs():
    recs = [full_recording(name="a", seed=0), full_recording(n=30, name="b", seed=1)]
    X, y = make_inputs(recs, differentiation="gradient")
    assert X.shape == (90, 12)
    np.testing.assert_array_equal(y, np.vstack([recs[0].current, recs[1].current]))
    np.testing.assert_array_equal(targets(recs[1]), recs[1].current)
    expected = InverseDynamicsFeatures(differentiation="gradient").fit_transform(recs)
    np.testing.assert_array_equal(X, expected)


# --------------------------------------------------------------------------
# real UR10e data


@pytest.mark.realdata
def test_ur10e_static_pose(ur10e_dir):
    rec = load_ur10e(ur10e_dir / "validation_data" / "ur-20_01_17-p1.csv")
    features = InverseDynamicsFeatures()
    with pytest.warns(MissingSignalWarning) as record:
        X = features.fit_transform(rec)
    assert len(record) == 1
    message = str(record[0].message)
    assert "target_q missing" in message and "target_qd missing" in message
    assert "target_current" not in message
    assert features.missing_signals_ == ("target_q", "target_qd")
    assert np.isfinite(X).all()
    np.testing.assert_array_equal(X[:, block_columns("i_c", 6)], rec.target_current)
    # The robot stands still: the paper's gate (sigma_v = 1e-2) is on everywhere.
    assert quasi_static_mask(rec.qd, sigma_v=1e-2).mean() > 0.999


@pytest.mark.realdata
def test_ur10e_moving_accelerations(ur10e_dir):
    rec = load_ur10e(ur10e_dir / "validation_data" / "ur-20_01_17-ptp_10_points.csv")
    with pytest.warns(MissingSignalWarning, match="target_q missing.*target_qd missing"):
        X = InverseDynamicsFeatures().fit_transform(rec)
    qdd = X[:, block_columns("qdd", 6)]
    assert np.isfinite(qdd).all()
    # Two different filters agree on the accelerations, the joints really
    # accelerate, and integrating qdd gives qd back (no bias, no drift).
    qdd_butter = differentiate(rec.time, rec.qd, "butter")
    assert rms(qdd - qdd_butter) < 0.1 * rms(qdd)
    assert 0.1 < rms(qdd) < 5.0
    qd_again = rec.qd[0] + cumulative_trapezoid(qdd, rec.time, axis=0, initial=0)
    assert rms(qd_again - rec.qd) < 0.02 * rms(rec.qd)
    # point-to-point motion with stops: both regimes are present
    fraction = quasi_static_mask(rec.qd).mean()
    assert 0.1 < fraction < 0.9


# --------------------------------------------------------------------------
# masks and regimes


def test_quasi_static_mask_is_strict():
    qd = np.array([[0.0, 0.00999], [0.01, -0.01], [-0.5, 0.02]])
    np.testing.assert_array_equal(
        quasi_static_mask(qd), [[True, True], [False, False], [False, False]]
    )
    assert quasi_static_mask(qd[:, 0], sigma_v=0.6).all()
    with pytest.raises(ValueError, match="sigma_v"):
        quasi_static_mask(qd, sigma_v=0.0)
    with pytest.raises(ValueError, match=r"NaN or inf at index \(1, 0\)"):
        quasi_static_mask([[0.0], [np.nan]])


def test_regimes_on_constructed_profile():
    # joint 0: rest, creep, moving +, fast reversal, moving -, long stop,
    # moving + again (a stop, not a reversal); joint 1: an acceleration spike.
    segments = [
        ("rest", [0.0] * 20), ("creep", [0.005] * 20), ("moving", [0.3] * 20),
        ("ramp", [0.2, 0.05, -0.05, -0.2]), ("moving", [-0.3] * 20),
        ("rest", [0.0] * 30), ("moving", [0.3] * 20),
    ]
    qd0 = np.concatenate([v for _, v in segments])
    n = qd0.size
    qd1 = np.full(n, 0.5)
    qdd = np.zeros((n, 2))
    qdd[40:43, 1] = 8.0
    qdd[10, 0] = 8.0  # during a reversal-free rest: high acceleration wins
    labels = regimes(np.column_stack([qd0, qd1]), qdd, reversal_window=4)

    j0 = labels[:, 0]
    assert set(j0[:10]) == {"rest"} and j0[10] == "braking"
    assert set(j0[11:20]) == {"rest"}
    assert set(j0[20:40]) == {"creep"}
    assert set(j0[40:59]) == {"moving"}
    # reversal: moving samples 60 (+0.2) ... 63 (-0.2) are adjacent in the
    # moving set (61, 62 are still moving at |0.05| >= sigma_v), flip at
    # 61 -> 62; window 4 marks 61 - 2 ... 62 + 2.
    np.testing.assert_array_equal(np.flatnonzero(j0 == "reversal"), np.arange(59, 65))
    assert set(j0[65:84]) == {"moving"}
    assert set(j0[84:114]) == {"rest"}  # 30-sample stop > window: no reversal
    assert set(j0[114:]) == {"moving"}
    j1 = labels[:, 1]
    np.testing.assert_array_equal(np.flatnonzero(j1 != "moving"), [40, 41, 42])
    assert set(j1[40:43]) == {"braking"}
    # away from the event labels, rest + creep is exactly the paper's gate
    qd = np.column_stack([qd0, qd1])
    plain = ~np.isin(labels, ["reversal", "braking"])
    np.testing.assert_array_equal(
        np.isin(labels, ["rest", "creep"])[plain], quasi_static_mask(qd)[plain]
    )
    # without qdd there is no braking label
    assert "braking" not in regimes(qd, reversal_window=4)


def test_reversal_through_quasi_static_band():
    # velocity passes zero slowly: 3 quasi-static samples between the signs
    qd = np.array([0.3, 0.1, 0.005, 0.0, -0.005, -0.1, -0.3, -0.3, -0.3, -0.3])
    labels = regimes(qd, reversal_window=4)
    # moving samples 1 and 5 are 4 apart -> reversal from 1 - 2 to 5 + 2
    np.testing.assert_array_equal(np.flatnonzero(labels == "reversal"), np.arange(0, 8))
    labels = regimes(qd, reversal_window=3)  # too slow for a 3-sample window
    assert "reversal" not in labels
    assert list(labels[2:5]) == ["creep", "rest", "creep"]


def test_regimes_validation():
    qd = np.zeros((5, 2))
    with pytest.raises(ValueError, match="qdd has shape"):
        regimes(qd, np.zeros((5, 3)))
    with pytest.raises(ValueError, match="sigma_rest"):
        regimes(qd, sigma_rest=0.1)
    with pytest.raises(ValueError, match="reversal_window"):
        regimes(qd, reversal_window=0)
    assert regimes(qd, sigma_rest=1e-2).shape == (5, 2)


@pytest.mark.parametrize(
    "mask, expected",
    [([], []), ([0, 0], []), ([1, 1, 1], [(0, 3)]), ([1, 0, 0, 1], [(0, 1), (3, 4)]),
     ([False, True, True, False], [(1, 3)])],
)
def test_contiguous_segments(mask, expected):
    assert contiguous_segments(np.asarray(mask, dtype=bool)) == expected


@given(st.lists(st.booleans(), max_size=60))
def test_contiguous_segments_rebuild_mask(values):
    mask = np.array(values, dtype=bool)
    rebuilt = np.zeros_like(mask)
    segments = contiguous_segments(mask)
    for start, stop in segments:
        rebuilt[start:stop] = True
    np.testing.assert_array_equal(rebuilt, mask)
    gaps = [b[0] - a[1] for a, b in zip(segments, segments[1:])]
    assert all(g > 0 for g in gaps)  # maximal runs: separated by a False


def test_contiguous_segments_rejects_2d():
    with pytest.raises(ValueError, match="1-D"):
        contiguous_segments(np.zeros((3, 2), dtype=bool))
