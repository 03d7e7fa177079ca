"""Measured vs predicted current, velocity and monitoring signal (paper Fig. 3)."""

import numpy as np

from ..metrics import contact_events


def _pyplot():
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "plot_monitoring needs matplotlib; install it with "
            "`pip install sklearn-gpcd[plot]` or `pip install matplotlib`"
        ) from exc
    return plt


def _joint_column(name, values, joint, n_samples):
    values = np.asarray(values, dtype=float)
    if values.ndim == 2:
        if not 0 <= joint < values.shape[1]:
            raise ValueError(
                f"joint={joint} is out of range for {name} with {values.shape[1]} joints"
            )
        values = values[:, joint]
    if values.shape != (n_samples,):
        raise ValueError(
            f"{name} must have shape ({n_samples},) or ({n_samples}, n_joints), "
            f"got {np.shape(values)}"
        )
    return values


def _band(thresholds, joint, n_samples):
    """Threshold of one joint as a per-sample array."""
    thresholds = np.asarray(thresholds, dtype=float)
    if thresholds.ndim == 0:
        return np.full(n_samples, float(thresholds))
    if thresholds.ndim == 1 and thresholds.shape[0] != n_samples:
        if not 0 <= joint < thresholds.shape[0]:
            raise ValueError(
                f"joint={joint} is out of range for thresholds with "
                f"{thresholds.shape[0]} joints"
            )
        return np.full(n_samples, thresholds[joint])
    return _joint_column("thresholds", thresholds, joint, n_samples)


def plot_monitoring(
    time, current, predicted, qd, s, thresholds, labels=None, joint=0, ax=None, alarms=None
):
    """Plot one joint's current, prediction, velocity and monitoring signal.

    The layout of the paper's Fig. 3: measured current ``i_l`` against the
    prediction ``i_hat_l``, the joint velocity ``qd_l``, and the monitoring
    signal ``s_l`` inside its threshold band ``+/- sigma_CD,l``, with the
    labelled contact intervals shaded grey on every panel and, when given,
    the alarms marked (a purple strip along the top of the signal panel and
    a dotted line at each alarm onset). The legends name the shading and
    the alarm marks.

    Parameters
    ----------
    time : array-like of shape (n_samples,)
        Time stamps in seconds.
    current, predicted, qd, s : array-like of shape (n_samples,) or \
            (n_samples, n_joints)
        Measured current, predicted current, joint velocity and monitoring
        signal (e.g. from ``CollisionDetector.monitoring_signal``).
    thresholds : float or array-like
        The band: a scalar, one value per joint (``thresholds_``), or one
        per sample, ``(n_samples,)`` or ``(n_samples, n_joints)``, for a
        variance-aware band.
    labels : array-like of shape (n_samples,), default=None
        Contact labels (0 free, ``k > 0`` in contact ``k``); contacts are
        shaded.
    joint : int, default=0
        Joint to plot (0-based index; the labels number joints from 1 as the
        paper does, so ``joint=0`` is labelled ``i_1``).
    ax : sequence of 3 matplotlib Axes, default=None
        Axes to draw on; None creates a figure with three stacked panels.
    alarms : array-like of bool of shape (n_samples,), default=None
        Detector decision per sample (True: alarm), e.g.
        ``detector.predict(...) == -1``; None marks nothing.

    Returns
    -------
    axes : ndarray of 3 Axes

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> t = np.arange(100) * 0.008
    >>> i = np.sin(t); i_hat = i + 0.01
    >>> labels = np.where((t > 0.3) & (t < 0.4), 1, 0)
    >>> axes = plot_monitoring(t, i, i_hat, np.cos(t), i - i_hat, 0.05,
    ...                        labels=labels)
    >>> [a.get_ylabel() for a in axes]
    ['current [A]', 'velocity [rad/s]', 'monitoring signal']
    >>> axes = plot_monitoring(t, i, i_hat, np.cos(t), i - i_hat, 0.05,
    ...                        labels=labels, alarms=(t > 0.32) & (t < 0.45))
    >>> [x.get_text() for x in axes[2].get_legend().get_texts()][-2:]
    ['labelled contact', 'alarm']
    """
    time = np.asarray(time, dtype=float)
    if time.ndim != 1:
        raise ValueError(f"time must be 1-D, got shape {time.shape}")
    n = time.shape[0]
    current = _joint_column("current", current, joint, n)
    predicted = _joint_column("predicted", predicted, joint, n)
    qd = _joint_column("qd", qd, joint, n)
    s = _joint_column("s", s, joint, n)
    band = _band(thresholds, joint, n)
    if ax is None:
        plt = _pyplot()
        _, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 6))
    else:
        axes = np.asarray(ax, dtype=object).ravel()
        if axes.shape != (3,):
            raise ValueError(f"ax must hold 3 Axes, got {axes.shape[0]}")
    axes = np.asarray(axes, dtype=object)
    top, middle, bottom = axes
    number = joint + 1  # the paper numbers joints from 1 (i_1, s_1)
    if labels is not None:
        labels = np.asarray(labels)
        if labels.shape != (n,):
            raise ValueError(f"labels must have shape ({n},), got {labels.shape}")
    if alarms is not None:
        alarms = np.asarray(alarms, dtype=bool)
        if alarms.shape != (n,):
            raise ValueError(f"alarms must have shape ({n},), got {alarms.shape}")
    top.plot(time, current, label=f"$i_{{{number}}}$ measured")
    top.plot(time, predicted, "--", label=f"$\\hat{{i}}_{{{number}}}$ predicted")
    top.set_ylabel("current [A]")
    middle.plot(time, qd, color="tab:green")
    middle.set_ylabel("velocity [rad/s]")
    bottom.plot(time, s, color="tab:red", label=f"$s_{{{number}}}$")
    bottom.fill_between(time, -band, band, color="tab:blue", alpha=0.15,
                        label=r"$\pm\sigma_{CD}$")
    bottom.set_ylabel("monitoring signal")
    bottom.set_xlabel("time [s]")
    if labels is not None:
        starts, stops = contact_events(labels)
        for k, (start, stop) in enumerate(zip(starts, stops)):
            end = time[stop] if stop < n else time[-1]
            for a in axes:
                a.axvspan(time[start], end, color="grey", alpha=0.3, lw=0,
                          label="labelled contact" if k == 0 else None)
    if alarms is not None:
        starts, stops = contact_events(alarms.astype(int))
        for k, (start, stop) in enumerate(zip(starts, stops)):
            end = time[stop] if stop < n else time[-1]
            bottom.axvspan(time[start], end, ymin=0.94, ymax=1.0, color="tab:purple",
                           lw=0, label="alarm" if k == 0 else None)
            for a in axes:
                a.axvline(time[start], color="tab:purple", ls=":", lw=1.0)
        if not starts.size:  # say so rather than leave the reader guessing
            bottom.plot([], [], color="tab:purple", lw=4, label="alarm (none)")
    for a in (top, bottom):  # outside the panels: a legend never hides the signals
        a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
                 borderaxespad=0.0)
    return axes
