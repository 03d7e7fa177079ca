"""Offline contact-event labels for the real UR10e recordings of Mamedov et al.

The recordings (github.com/shamilmamedov/dynamic_calibration; Mamedov et al.,
Frontiers in Robotics and AI 2020; no redistribution licence, so they are read
in place and never copied into the package) carry no collision labels. This
script derives them from the data and writes them, with this description, to
``benchmarks/labels/ur10e_events.json``. The labels are ground truth for
*scoring* detectors, so the method is deliberately **offline**: zero-phase
(``filtfilt``) filters, look-ahead and look-back searches are allowed.

Times are seconds after the first sample of each file. Joints are 1-based.

Method, push files (``collision_push_pose/*.csv``)
--------------------------------------------------
The robot holds a pose while a human pushes it; ``i_des`` is almost constant.

1. Residual ``r = i - i_des`` per joint, zero-phase Butterworth low-pass
   (order ``PUSH_ORDER``, cut-off ``PUSH_FC`` Hz): ``s``. Noise level
   ``sigma_j`` = 1.4826 MAD of ``r - s``. Rate ``d = ds/dt`` (``np.gradient``
   on the time column); its noise level ``sigma_d,j = g sigma_j`` where ``g``
   is the gain of the same filter-and-differentiate chain on white noise
   (estimated with a fixed-seed noise record, so it is deterministic).
2. Candidate samples: the held arm moves, ``max_j |qd_j| > QD_THR`` rad/s
   (only happens when something pushes it), or a fast current change on any
   joint, ``|d_j| > K_CAND sigma_d,j`` (K_CAND is high because the slow
   relaxation after a release reaches 10-18 sigma_d; push ramps reach
   80-420 on joints 1-5). Runs of candidate samples closer than
   ``MERGE_GAP`` s are merged into clusters ``[cs, ce]``.
3. For each cluster, a search window ``W = [cs - SEARCH, ce + SEARCH]`` (clipped
   to the neighbouring clusters). A joint *shows* the event when its peak rate
   in ``W`` exceeds ``K_RATE sigma_d,j`` and its smoothed residual spans more
   than ``K_AMP sigma_j`` and ``MIN_AMP`` A in ``W``. The timing comes from
   the *strong* joints (peak rate in ``W`` above ``K_CAND sigma_d,j``): their
   *active* samples are those with ``|d_j| > max(REL_RATE * peak rate,
   K_LO sigma_d,j)``, grouped in runs (gaps < ``ACT_GAP`` s bridged); of the
   runs that overlap ``[cs, ce]``, the first one's start is the onset (the
   knee of the push ramp, often 0.1-0.6 s before the arm moves) and the last
   one's end is the end of the fast release transient (the release
   overshoot). Event ``= [min(onsets, cs), max(ends, ce)]``.
4. Events closer than ``MERGE_GAP`` s are merged.
5. ``peak_A`` = max over showing joints of ``|s_j - b_j|`` inside the event,
   ``b_j`` the median of ``s_j`` over the ``BASE_WIN`` s before the onset;
   ``joints`` = showing joints whose ``|s_j - b_j|`` exceeds ``K_AMP sigma_j``
   and ``MIN_AMP``.
   After the release the residual of joint 1 (and a little of joints 2-3)
   relaxes slowly (1-3 s, controller integrator unwinding with the arm at
   rest): that slow tail is NOT part of the event; ``tail_stop_s`` gives the
   time it ends (first time ``|d_j|`` of every showing joint stays below
   ``K_LO sigma_d,j`` for ``TAIL_HOLD`` s, or the next event), for scorers that
   want a grace zone.

Method, moving-robot files (``collision_detection_data_2020/*.csv``)
--------------------------------------------------------------------
Repetitive motion; ``collision_free.csv`` is the same motion without contact.
There is no ``i_des``, so the residual is taken against a regression model.

1. Features of every sample: ``[q, sin q, cos q, qd, tanh(qd/0.02),
   tanh(qd/0.1), qdd]`` of all 6 joints (42 columns), ``qdd`` from
   ``qd`` low-passed at ``QDD_FC`` Hz (zero-phase), differentiated with
   ``np.gradient``, low-passed again. Model: standardised features, ridge
   (``alpha = RIDGE_ALPHA``), all 6 currents at once.
2. Pass 1: fit on ``collision_free.csv``. Residual ``e = i - model``,
   zero-phase low-passed in two bands: ``COLL_FC`` Hz (contacts lasting
   0.2-0.7 s) and ``IMP_FC`` Hz (the "impact band": 50-100 ms taps that the
   slow band halves). ``collision_free.csv``'s own residual is
   *cross-fitted* (2 time blocks, each predicted by a model fitted on the
   other one), so its sanity check is out of sample. Per joint and band,
   ``sigma`` = 1.4826 MAD of the filtered cross-fitted ``collision_free``
   residual; score ``z_j = (e_j - median_file(e_j)) / sigma_j``.
3. Events = union of per-joint hysteresis runs (``|z_j| > K_LO_COLL``
   containing a core sample ``|z_j| > K`` outside the first/last ``EDGE`` s,
   where the filters' edge transients live) with
   ``K = K_COLL`` in the slow band on all joints, and ``K = K_IMP`` in the
   impact band on joints 1-3 only (``IMP_JOINTS``): joints 4-6 carry a
   model error at their velocity reversals of up to 4.7-6.5 sigma (impact
   band) in ``collision_free`` and up to 7.5-8.6 sigma, once per motion
   cycle, in the collision runs, whereas joints 1-3 stay below 3.7 sigma in
   ``collision_free``. Runs closer than
   ``MERGE_GAP`` s are merged. ``detected_by`` says which band fired.
4. Pass 2 (the collision runs are a bit slower than ``collision_free``):
   refit on ``collision_free`` plus the samples of the three collision
   files more than ``GUARD`` s away from every pass-1 event, redo steps 2-3
   with the pass-1 sigmas (``collision_free`` still cross-fitted: each of
   its halves is predicted by a model that never saw it).
5. ``joints`` = joints whose ``|z_j|`` exceeds its band's ``K`` inside the
   event; ``peak_A`` = max over them of the filtered residual's deviation
   from its file median (slow band; impact band for impact-only events).
6. ``ambiguous`` (per file, NOT events): slow-band runs on joints 1-3 with
   ``K_UNSURE < |z| <= K_COLL`` and no event; e.g. a 1.6 s stretch of
   collision_2link where joint 1 draws ~0.35 A less than the model during
   constant-velocity motion (the signature of the labelled link-2 contacts,
   but at 7.6 sigma). Scorers may exclude these windows from both false
   alarms and hits.
   The sanity figure is ``collision_free``'s max ``|z_j|`` per band (must stay
   below ``K_COLL`` / ``K_IMP``), printed and stored in ``diagnostics``.

Parameters
----------
PUSH_FC, PUSH_ORDER : 4.0 Hz, 2
QD_THR : 1e-3 rad/s
K_CAND, K_RATE, K_LO, REL_RATE : 25, 8, 3, 0.1
K_AMP, MIN_AMP : 8, 0.05 A
SEARCH, MERGE_GAP, BASE_WIN, TAIL_HOLD, ACT_GAP : 1.0 s, 0.3 s, 0.3 s, 0.3 s, 0.15 s
QDD_FC, COLL_FC, RIDGE_ALPHA : 8 Hz, 3 Hz, 1.0
K_COLL, K_LO_COLL, GUARD, EDGE : 10, 4, 0.5 s, 0.25 s
IMP_FC, K_IMP, IMP_JOINTS, K_UNSURE : 6 Hz, 8, joints 1-3, 6

Every label was checked by eye on the figures (``--plot DIR``: one PNG per
file, every joint, labels shaded).

Run::

    python benchmarks/label_ur10e_events.py [--data DIR] [--plot DIR] [--output FILE]

Without the data it prints why and exits 0.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.signal import butter, filtfilt

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import real_data_path, require_data  # noqa: E402

DATASET = "ur10e_mamedov"
PUSH_FILES = ["collision_push_pose/ur-20_01_22-push_pose_1.csv",
              "collision_push_pose/ur-20_01_22-push_pose_2.csv"]
COLL_DIR = "collision_detection_data_2020/"
FREE_FILE = COLL_DIR + "collision_free.csv"
COLL_FILES = [COLL_DIR + f"collision_{n}.csv" for n in ("2link", "3link", "wrist")]

# push files
PUSH_FC, PUSH_ORDER = 4.0, 2
QD_THR = 1e-3
K_CAND, K_RATE, K_LO, REL_RATE = 25.0, 8.0, 3.0, 0.1
K_AMP, MIN_AMP = 8.0, 0.05
SEARCH, MERGE_GAP, BASE_WIN, TAIL_HOLD, ACT_GAP = 1.0, 0.3, 0.3, 0.3, 0.15
# moving-robot files
QDD_FC, COLL_FC, RIDGE_ALPHA = 8.0, 3.0, 1.0
K_COLL, K_LO_COLL, GUARD, EDGE = 10.0, 4.0, 0.5, 0.25
IMP_FC, K_IMP, IMP_JOINTS, K_UNSURE = 6.0, 8.0, (0, 1, 2), 6.0


# -- helpers ----------------------------------------------------------------
def _fs(t):
    return 1.0 / float(np.mean(np.diff(t)))


def lowpass(x, fc, fs, order=2):
    """Zero-phase Butterworth low-pass along axis 0."""
    b, a = butter(order, fc / (fs / 2.0))
    return filtfilt(b, a, x, axis=0)


def mad_sigma(x, axis=0):
    x = np.asarray(x)
    return 1.4826 * np.median(np.abs(x - np.median(x, axis=axis)), axis=axis)


def runs(mask):
    """``[(i0, i1), ...]`` inclusive index ranges of the True runs of ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(int)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def merge(intervals, t, gap):
    """Merge index intervals whose time gap is below ``gap`` s."""
    out = []
    for a, b in sorted(intervals):
        if out and t[a] - t[out[-1][1]] < gap:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _load(path):
    from sklearn_gpcd.io import load_recording

    rec = load_recording(path)
    return rec, np.asarray(rec.time, float) - float(rec.time[0])


# -- push files -------------------------------------------------------------
def _rate_gain(n, fs):
    """Noise gain ``g`` of low-pass + d/dt relative to the high-pass noise MAD."""
    w = np.random.RandomState(0).standard_normal(n)
    t = np.arange(n) / fs
    s = lowpass(w, PUSH_FC, fs, PUSH_ORDER)
    return mad_sigma(np.gradient(s, t)) / mad_sigma(w - s)


def label_push(path):
    rec, t = _load(path)
    if rec.target_current is None:
        raise ValueError(f"{path}: push labelling needs the target current")
    fs = _fs(t)
    r = np.asarray(rec.current) - np.asarray(rec.target_current)
    s = lowpass(r, PUSH_FC, fs, PUSH_ORDER)
    sig = mad_sigma(r - s)
    d = np.gradient(s, t, axis=0)
    sig_d = sig * _rate_gain(len(t), fs)
    qd_max = np.abs(np.asarray(rec.qd)).max(axis=1)
    cand = (qd_max > QD_THR) | (np.abs(d) > K_CAND * sig_d).any(axis=1)
    clusters = merge(runs(cand), t, MERGE_GAP)
    n = len(t)
    events = []
    for c, (cs, ce) in enumerate(clusters):
        lo_t = max(t[cs] - SEARCH, t[clusters[c - 1][1]] if c else -np.inf)
        hi_t = min(t[ce] + SEARCH, t[clusters[c + 1][0]] if c + 1 < len(clusters) else np.inf)
        w0 = int(np.searchsorted(t, lo_t, "left"))
        w1 = int(np.searchsorted(t, hi_t, "right")) - 1
        if c:
            w0 = max(w0, clusters[c - 1][1] + 1)
        if c + 1 < len(clusters):
            w1 = min(w1, clusters[c + 1][0] - 1)
        on, off, show = [], [], []
        for j in range(r.shape[1]):
            dj = np.abs(d[w0:w1 + 1, j])
            peak_rate = dj.max()
            span = np.ptp(s[w0:w1 + 1, j])
            if peak_rate <= K_RATE * sig_d[j] or span <= max(K_AMP * sig[j], MIN_AMP):
                continue
            act = merge(runs(dj > max(REL_RATE * peak_rate, K_LO * sig_d[j])),
                        t[w0:w1 + 1], ACT_GAP)
            act = [(w0 + a, w0 + b) for a, b in act if w0 + b >= cs and w0 + a <= ce]
            show.append(j)
            if act and peak_rate > K_CAND * sig_d[j]:   # timing from the strong joints
                on.append(act[0][0])
                off.append(act[-1][1])
        if not show:          # arm moved but no joint current reacted: not a push
            continue
        events.append((min(on + [cs]), max(off + [ce]), show))
    # merge events closer than MERGE_GAP
    merged = []
    for a, b, show in events:
        if merged and t[a] - t[merged[-1][1]] < MERGE_GAP:
            pa, pb, ps = merged[-1]
            merged[-1] = (pa, max(pb, b), sorted(set(ps) | set(show)))
        else:
            merged.append((a, b, list(show)))
    out = []
    for k, (a, b, show) in enumerate(merged):
        base0 = int(np.searchsorted(t, t[a] - BASE_WIN))
        base = np.median(s[base0:a + 1], axis=0)
        dev = np.abs(s[a:b + 1] - base).max(axis=0)
        joints = [j for j in show if dev[j] > max(K_AMP * sig[j], MIN_AMP)]
        if not joints:
            joints = [max(show, key=lambda j: dev[j])]
        # end of the slow relaxation tail (information only)
        nxt = merged[k + 1][0] if k + 1 < len(merged) else n - 1
        quiet = (np.abs(d[:, joints]) < K_LO * sig_d[joints]).all(axis=1)
        hold = int(round(TAIL_HOLD * fs))
        tail = nxt
        for i in range(b, nxt):
            if quiet[i:i + hold].all() and i + hold <= nxt:
                tail = i
                break
        out.append({
            "start_s": round(float(t[a]), 3),
            "stop_s": round(float(t[b]), 3),
            "joints": [j + 1 for j in joints],
            "peak_A": round(float(dev[joints].max()), 3),
            "peak_A_per_joint": {str(j + 1): round(float(dev[j]), 3) for j in joints},
            "tail_stop_s": round(float(t[tail]), 3),
        })
    diag = {"sigma_A": sig, "sigma_rate_A_per_s": sig_d}
    return out, float(t[-1]), (t, r, s, np.asarray(rec.qd)), diag


# -- moving-robot files -----------------------------------------------------
def features(rec, t):
    q, qd = np.asarray(rec.q), np.asarray(rec.qd)
    fs = _fs(t)
    qdd = lowpass(np.gradient(lowpass(qd, QDD_FC, fs), t, axis=0), QDD_FC, fs)
    return np.hstack([q, np.sin(q), np.cos(q), qd, np.tanh(qd / 0.02),
                      np.tanh(qd / 0.1), qdd])


def _model():
    from sklearn.linear_model import Ridge
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    return make_pipeline(StandardScaler(), Ridge(alpha=RIDGE_ALPHA))


def _hysteresis(t, z, k_hi, k_lo, joints):
    """Per-joint hysteresis runs (``|z| > k_lo`` containing ``|z| > k_hi``)
    of ``joints``, union over joints, merged when closer than MERGE_GAP.

    A run needs a core sample (``|z| > k_hi``) outside the first/last
    ``EDGE`` s, where the zero-phase filters' edge transients live."""
    mask = np.zeros(len(t), bool)
    inner = (t >= t[0] + EDGE) & (t <= t[-1] - EDGE)
    for j in joints:
        a = np.abs(z[:, j])
        for i0, i1 in runs(a > k_lo):
            if (inner[i0:i1 + 1] & (a[i0:i1 + 1] > k_hi)).any():
                mask[i0:i1 + 1] = True
    return merge(runs(mask), t, MERGE_GAP)


def _coll_events(t, z_slow, z_fast):
    """Events: slow band on all joints, or impact band on joints 1-3."""
    ev = _hysteresis(t, z_slow, K_COLL, K_LO_COLL, range(6))
    ev += _hysteresis(t, z_fast, K_IMP, K_LO_COLL, IMP_JOINTS)
    return merge(ev, t, MERGE_GAP)


def label_collisions(root):
    data = {}
    for name in [FREE_FILE] + COLL_FILES:
        rec, t = _load(root / name)
        data[name] = (t, features(rec, t), np.asarray(rec.current))
    tf, Xf, Yf = data[FREE_FILE]
    half = len(tf) // 2
    folds = [(np.arange(half), np.arange(half, len(tf))),
             (np.arange(half, len(tf)), np.arange(half))]

    def residuals(extra_X, extra_Y):
        res = {}
        # collision_free: cross-fitted
        R = np.zeros_like(Yf)
        for tr, te in folds:
            m = _model().fit(np.vstack([Xf[tr]] + extra_X), np.vstack([Yf[tr]] + extra_Y))
            R[te] = Yf[te] - m.predict(Xf[te])
        res[FREE_FILE] = R
        m = _model().fit(np.vstack([Xf] + extra_X), np.vstack([Yf] + extra_Y))
        for name in COLL_FILES:
            _, X, Y = data[name]
            res[name] = Y - m.predict(X)
        return res

    def bands(res):
        out = {}
        for k, v in res.items():
            fs = _fs(data[k][0])
            out[k] = (lowpass(v, COLL_FC, fs), lowpass(v, IMP_FC, fs))
        return out

    def score(band, sig):
        z, ev = {}, {}
        for name, (slow, fast) in band.items():
            z[name] = tuple((e - np.median(e, axis=0)) / s for e, s in zip((slow, fast), sig))
            ev[name] = _coll_events(data[name][0], *z[name])
        return z, ev

    band1 = bands(residuals([], []))
    sig = tuple(mad_sigma(b) for b in band1[FREE_FILE])
    z1, ev1 = score(band1, sig)
    # pass 2: add the collision files' samples away from pass-1 events
    ex_X, ex_Y = [], []
    for name in COLL_FILES:
        t, X, Y = data[name]
        keep = np.ones(len(t), bool)
        for a, b in ev1[name]:
            keep &= ~((t >= t[a] - GUARD) & (t <= t[b] + GUARD))
        ex_X.append(X[keep])
        ex_Y.append(Y[keep])
    band2 = bands(residuals(ex_X, ex_Y))
    z2, ev2 = score(band2, sig)
    labels, plots = {}, {}
    for name in [FREE_FILE] + COLL_FILES:
        t = data[name][0]
        zs, zf = z2[name]
        e = band2[name][0] - np.median(band2[name][0], axis=0)
        ef = band2[name][1] - np.median(band2[name][1], axis=0)
        out = []
        for a, b in ev2[name]:
            ms, mf = np.abs(zs[a:b + 1]).max(axis=0), np.abs(zf[a:b + 1]).max(axis=0)
            joints = [j for j in range(6) if ms[j] > K_COLL
                      or (j in IMP_JOINTS and mf[j] > K_IMP)]
            by = (["slow"] if (ms > K_COLL).any() else []) + \
                (["impact"] if (mf[list(IMP_JOINTS)] > K_IMP).any() else [])
            amp = e if "slow" in by else ef
            out.append({
                "start_s": round(float(t[a]), 3),
                "stop_s": round(float(t[b]), 3),
                "joints": [j + 1 for j in joints],
                "peak_A": round(float(np.abs(amp[a:b + 1, joints]).max()), 3),
                "peak_A_per_joint": {str(j + 1): round(float(np.abs(amp[a:b + 1, j]).max()), 3)
                                     for j in joints},
                "peak_sigma": round(float(ms.max()), 1),
                "peak_sigma_impact_band": round(float(mf[list(IMP_JOINTS)].max()), 1),
                "detected_by": by,
            })
        # ambiguous: slow band, joints 1-3, K_UNSURE < |z| (no event there)
        unsure = []
        for a, b in _hysteresis(t, zs, K_UNSURE, K_LO_COLL, IMP_JOINTS):
            if any(a <= eb and b >= ea for ea, eb in ev2[name]):
                continue
            ms = np.abs(zs[a:b + 1]).max(axis=0)
            unsure.append({"start_s": round(float(t[a]), 3), "stop_s": round(float(t[b]), 3),
                           "joints": [j + 1 for j in IMP_JOINTS if ms[j] > K_UNSURE],
                           "peak_sigma": round(float(ms.max()), 1)})
        labels[name] = (out, float(t[-1]), unsure)
        plots[name] = (t, zs, zf)
    tfree = data[FREE_FILE][0]
    inner = (tfree >= EDGE) & (tfree <= tfree[-1] - EDGE)
    zfs, zff = (np.abs(z) for z in z2[FREE_FILE])
    diag = {
        "sigma_A_slow_band": sig[0],
        "sigma_A_impact_band": sig[1],
        "free_max_abs_z_per_joint": zfs[inner].max(axis=0),
        "free_max_abs_z_per_joint_impact_band": zff[inner].max(axis=0),
        "free_max_abs_z_per_joint_incl_edges": zfs.max(axis=0),
        "pass1_event_counts": {k: len(v) for k, v in ev1.items()},
        "max_abs_z_outside_events": {},
    }
    for name in [FREE_FILE] + COLL_FILES:
        t = data[name][0]
        inside = np.zeros(len(t), bool)
        for a, b in ev2[name]:
            inside[max(a - 10, 0):b + 11] = True
        inside |= (t < EDGE) | (t > t[-1] - EDGE)
        diag["max_abs_z_outside_events"][name] = {
            "slow_band": np.abs(z2[name][0][~inside]).max(axis=0),
            "impact_band": np.abs(z2[name][1][~inside]).max(axis=0)}
    return labels, plots, diag


# -- plots ------------------------------------------------------------------
def _shade(ax, events, key="stop_s"):
    for ev in events:
        ax.axvspan(ev["start_s"], ev[key], color="tab:orange", alpha=0.25, lw=0)
        if "tail_stop_s" in ev and key == "stop_s":
            ax.axvspan(ev["stop_s"], ev["tail_stop_s"], color="tab:gray", alpha=0.12, lw=0)


def plot_push(name, events, arrays, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, r, s, qd = arrays
    fig, axes = plt.subplots(7, 1, figsize=(16, 17), sharex=True)
    for j in range(6):
        ax = axes[j]
        ax.plot(t, r[:, j], lw=0.4, color="0.6")
        ax.plot(t, s[:, j], lw=0.9, color="tab:blue")
        ax.set_ylabel(f"i-i_des j{j + 1} [A]")
        _shade(ax, events)
        for ev in events:
            if j + 1 in ev["joints"]:
                ax.text(ev["start_s"], ax.get_ylim()[1], "*", color="red", va="top")
        ax.grid(alpha=0.3)
    ax = axes[6]
    ax.plot(t, np.abs(qd).max(axis=1), lw=0.6)
    ax.axhline(QD_THR, color="r", lw=0.6)
    ax.set_yscale("symlog", linthresh=1e-4)
    ax.set_ylabel("max |qd| [rad/s]")
    _shade(ax, events)
    ax.set_xticks(np.arange(0, t[-1] + 0.5, 0.5), minor=True)
    ax.set_xticks(np.arange(0, t[-1] + 1, 1))
    ax.grid(alpha=0.3, which="both")
    ax.set_xlabel("t - t0 [s]")
    fig.suptitle(f"{name}: {len(events)} events (orange: event, grey: relaxation tail)")
    fig.tight_layout()
    fig.savefig(out, dpi=70)
    plt.close(fig)


def plot_coll(name, events, arrays, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, zs, zf = arrays
    events, unsure = events
    fig, axes = plt.subplots(6, 1, figsize=(max(16, t[-1] / 2.5), 15), sharex=True)
    for j in range(6):
        ax = axes[j]
        ax.plot(t, zf[:, j], lw=0.5, color="0.6", label=f"{IMP_FC:g} Hz (impact band)")
        ax.plot(t, zs[:, j], lw=0.8, color="tab:blue", label=f"{COLL_FC:g} Hz")
        for ev in unsure:
            ax.axvspan(ev["start_s"], ev["stop_s"], color="tab:purple", alpha=0.2, lw=0)
        for k in (K_COLL, -K_COLL):
            ax.axhline(k, color="r", lw=0.6)
        for k in (K_LO_COLL, -K_LO_COLL):
            ax.axhline(k, color="r", lw=0.4, ls=":")
        ax.set_ylabel(f"z j{j + 1} [sigma]")
        _shade(ax, events)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[-1].set_xticks(np.arange(0, t[-1] + 1, 1))
    axes[-1].set_xlabel("t - t0 [s]")
    fig.suptitle(f"{name}: {len(events)} events (orange), {len(unsure)} ambiguous (purple)")
    fig.tight_layout()
    fig.savefig(out, dpi=60)
    plt.close(fig)


# -- main -------------------------------------------------------------------
def _plain(obj):
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_plain(v) for v in obj.tolist()]
    if isinstance(obj, (float, np.floating)):
        return round(float(obj), 4)
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None,
                        help="UR10e data folder (default: $GPCD_REAL_DATA/ur10e_mamedov or "
                             "../shared/data/real/ur10e_mamedov next to the repository)")
    parser.add_argument("--plot", default=None, help="folder for the PNG figures (optional)")
    parser.add_argument("--output", default=str(Path(__file__).resolve().parent / "labels"
                                                 / "ur10e_events.json"))
    args = parser.parse_args(argv)
    root = real_data_path(DATASET, args.data)
    require_data(root, "UR10e recordings (Mamedov et al.)", PUSH_FILES + [FREE_FILE] + COLL_FILES)
    plot_dir = Path(args.plot) if args.plot else None
    if plot_dir:
        plot_dir.mkdir(parents=True, exist_ok=True)

    files, diagnostics = {}, {}
    for name in PUSH_FILES:
        events, duration, arrays, diag = label_push(root / name)
        files[name] = {"events": events, "duration_s": round(duration, 3)}
        diagnostics[name] = diag
        print(f"{name}: {len(events)} events")
        for ev in events:
            print(f"  {ev['start_s']:7.2f} - {ev['stop_s']:7.2f} s  joints {ev['joints']}  "
                  f"peak {ev['peak_A']:.2f} A  (tail to {ev['tail_stop_s']:.2f} s)")
        if plot_dir:
            plot_push(name, events, arrays, plot_dir / (Path(name).stem + ".png"))
    labels, plots, diag = label_collisions(root)
    diagnostics["collision_detection_data_2020"] = diag
    for name in [FREE_FILE] + COLL_FILES:
        events, duration, unsure = labels[name]
        files[name] = {"events": events, "duration_s": round(duration, 3),
                       "ambiguous": unsure}
        print(f"{name}: {len(events)} events")
        for ev in events:
            print(f"  {ev['start_s']:7.2f} - {ev['stop_s']:7.2f} s  joints {ev['joints']}  "
                  f"peak {ev['peak_A']:.2f} A  ({ev['peak_sigma']:.0f} / "
                  f"{ev['peak_sigma_impact_band']:.0f} sigma, {'+'.join(ev['detected_by'])})")
        for ev in unsure:
            print(f"  ambiguous {ev['start_s']:7.2f} - {ev['stop_s']:7.2f} s  joints "
                  f"{ev['joints']}  {ev['peak_sigma']:.1f} sigma")
        if plot_dir:
            plot_coll(name, (events, unsure), plots[name],
                      plot_dir / (Path(name).stem + ".png"))
    print("collision_free max |z| per joint:",
          np.round(diag["free_max_abs_z_per_joint"], 1), "impact band:",
          np.round(diag["free_max_abs_z_per_joint_impact_band"], 1),
          f"(first/last {EDGE} s excluded; with them:",
          np.round(diag["free_max_abs_z_per_joint_incl_edges"], 1), ")")

    result = {
        "method": __doc__,
        "created_by": "benchmarks/label_ur10e_events.py",
        "data": f"{DATASET} (github.com/shamilmamedov/dynamic_calibration), read in place",
        "time_origin": "seconds after the first sample of each file; joints 1-based",
        "parameters": {k: globals()[k] for k in (
            "PUSH_FC", "PUSH_ORDER", "QD_THR", "K_CAND", "K_RATE", "K_LO", "REL_RATE", "K_AMP",
            "MIN_AMP", "SEARCH", "MERGE_GAP", "BASE_WIN", "TAIL_HOLD", "ACT_GAP", "QDD_FC", "COLL_FC",
            "RIDGE_ALPHA", "K_COLL", "K_LO_COLL", "GUARD", "EDGE", "IMP_FC", "K_IMP",
            "IMP_JOINTS", "K_UNSURE")},
        "files": files,
        "diagnostics": diagnostics,
    }
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w") as fh:
        json.dump(_plain(result), fh, indent=1)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
