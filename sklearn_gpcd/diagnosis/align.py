"""Time alignment of a simulated and a real run of the same trajectory.

Both runs are resampled on a uniform grid (the real run's median period);
the lag :math:`\\tau` maximising the correlation coefficient of the joint
velocities over the overlap of the two runs (all joints pooled) is refined to a fraction of a
sample by a parabola through the peak and its neighbours. The simulated
current is then interpolated at the real time stamps shifted by
:math:`\\tau`, so it can serve as the reference current of the diagnosis.
"""

import numpy as np


def _uniform(time, values, step):
    grid = np.arange(time[0], time[-1], step)
    return grid, np.column_stack([np.interp(grid, time, v) for v in values.T])


def estimate_lag(simulated, real, max_lag=None):
    """Time offset ``tau`` [s] with ``real(t) ~ simulated(t - t0_real + t0_sim + tau)``.

    Parameters
    ----------
    simulated, real : Recording
        Runs of the same trajectory (same joints).
    max_lag : float, default=None
        Largest offset searched [s]; None means half the shorter run.

    Returns
    -------
    tau : float

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(0, 10, 0.01)
    >>> qd = np.sin(t)[:, None]
    >>> sim = Recording(time=t, q=qd, qd=qd, current=qd)
    >>> real = Recording(time=t[:800], q=qd[30:830], qd=qd[30:830], current=qd[30:830])
    >>> round(estimate_lag(sim, real), 3)
    0.3
    """
    if simulated.n_joints != real.n_joints:
        raise ValueError(
            f"simulated run has {simulated.n_joints} joints, real run {real.n_joints}"
        )
    step = float(np.median(np.diff(real.time)))
    _, a = _uniform(real.time - real.time[0], real.qd, step)
    _, b = _uniform(simulated.time - simulated.time[0], simulated.qd, step)
    a, b = a - a.mean(0), b - b.mean(0)
    limit = min(len(a), len(b)) // 2 if max_lag is None else int(round(max_lag / step))
    lags = np.arange(-limit, limit + 1)
    scores = np.empty(lags.size)
    for k, lag in enumerate(lags):  # real[i] ~ sim[i + lag]
        lo, hi = max(0, -lag), min(len(a), len(b) - lag)
        if hi - lo < 10:
            scores[k] = -np.inf
            continue
        x, y = a[lo:hi], b[lo + lag:hi + lag]
        x, y = x - x.mean(0), y - y.mean(0)
        denom = np.sqrt(np.sum(x * x) * np.sum(y * y))
        scores[k] = np.sum(x * y) / denom if denom > 0 else -np.inf
    best = int(np.argmax(scores))
    shift = 0.0
    if 0 < best < lags.size - 1 and np.all(np.isfinite(scores[best - 1:best + 2])):
        y0, y1, y2 = scores[best - 1:best + 2]
        denom = y0 - 2 * y1 + y2
        shift = 0.5 * (y0 - y2) / denom if denom != 0 else 0.0
    return float((lags[best] + shift) * step)


def align_recordings(simulated, real, max_lag=None):
    """Simulated current on the real run's time stamps.

    Parameters
    ----------
    simulated, real : Recording
        A simulated and a real run of the same trajectory.
    max_lag : float, default=None
        See :func:`estimate_lag`.

    Returns
    -------
    reference : ndarray of shape (real.n_samples, n_joints)
        Simulated current, time-aligned to ``real`` (held at the ends).
    tau : float
        Estimated offset [s].

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(0, 10, 0.01)
    >>> x = np.sin(t)[:, None]
    >>> sim = Recording(time=t, q=x, qd=x, current=2 * x)
    >>> real = Recording(time=t[:800] + 5.0, q=x[30:830], qd=x[30:830], current=2 * x[30:830])
    >>> ref, tau = align_recordings(sim, real)
    >>> bool(np.allclose(ref, real.current, atol=1e-3))
    True
    """
    if simulated.units != real.units:
        raise ValueError(
            f"simulated run logs {simulated.units!r}, real run {real.units!r}: units differ"
        )
    tau = estimate_lag(simulated, real, max_lag)
    t_sim = simulated.time - simulated.time[0]
    t_query = real.time - real.time[0] + tau
    ref = np.column_stack([np.interp(t_query, t_sim, simulated.current[:, j])
                           for j in range(real.n_joints)])
    return ref, tau
