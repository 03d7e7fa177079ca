"""Causal post-processing of the monitoring signal: low-pass filter, debounce.

Both are causal, so batch and tick-by-tick processing give the same
numbers. Rows of a batch are one time series per *segment*; the state
restarts at every segment start (a new recording, or a gap left by dropped
rows).
"""

import numpy as np
from scipy.signal import butter, lfilter, lfilter_zi


def lowpass_coefficients(cutoff, sample_time, order=1):
    """Coefficients ``(b, a)`` of a causal low-pass filter.

    The moving-phase residual is high-frequency and "might be easily
    canceled with a low pass filter" (paper Sec. IV-C, Fig. 2):

    - ``order=1``: the exact discretisation of a first-order lag with time
      constant ``tau = 1 / (2 pi f_c)``,

      .. math:: y_k = y_{k-1} + \\beta (u_k - y_{k-1}),
                \\quad \\beta = 1 - e^{-2 \\pi f_c T};

    - ``order=2``: a second-order Butterworth filter (bilinear transform).

    ``cutoff`` [Hz] must lie in ``(0, 1 / (2 T))``, ``T = sample_time`` [s];
    ``a[0] == 1``, both of length ``order + 1``.
    """
    nyquist = 0.5 / sample_time
    if not 0.0 < cutoff < nyquist:
        raise ValueError(
            f"filter_cutoff must lie in (0, {nyquist:g}) Hz, the Nyquist band for "
            f"sample_time={sample_time:g} s; got {cutoff!r}"
        )
    if order == 1:
        beta = 1.0 - np.exp(-2.0 * np.pi * cutoff * sample_time)
        return np.array([beta, 0.0]), np.array([1.0, beta - 1.0])
    if order == 2:
        b, a = butter(2, cutoff, btype="low", fs=1.0 / sample_time)
        return b / a[0], a / a[0]
    raise ValueError(f"filter_order must be 1 or 2, got {order!r}")


def recording_index(groups, labels=None):
    """Recording index ``0 .. n - 1`` of each collision-free row (None without ``groups``).

    Rows with a non-zero label are dropped, as the detector drops them.
    """
    if groups is None:
        return None
    groups = np.asarray(groups)
    if labels is not None:
        groups = groups[np.asarray(labels) == 0]
    return np.unique(groups, return_inverse=True)[1].reshape(-1)


def segment_starts(n_samples, groups=None, keep=None):
    """Row indices where the signal state restarts, beginning with 0 (empty: no rows).

    A segment starts where ``groups`` changes and, with ``keep`` (bool mask of
    the rows kept), after a gap of dropped rows; indices refer to the kept rows.
    """
    new = np.zeros(n_samples, dtype=bool)
    if n_samples:
        new[0] = True
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (n_samples,):
            raise ValueError(f"groups must have shape ({n_samples},), got {groups.shape}")
        new[1:] |= groups[1:] != groups[:-1]
    if keep is not None:
        gap = np.zeros(n_samples, dtype=bool)
        gap[1:] = ~keep[:-1]
        new = (new | gap)[keep]
    return np.flatnonzero(new)


def filter_segments(u, b, a, starts):
    """Apply the IIR filter ``(b, a)`` along axis 0, restarting per segment.

    Each segment starts in the steady state of its first sample
    (``scipy.signal.lfilter_zi``): a constant offset passes unchanged, with
    no start-up transient.
    """
    y = np.empty_like(u)
    zi = lfilter_zi(b, a)
    bounds = np.append(starts, u.shape[0])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        seg = u[lo:hi]
        y[lo:hi], _ = lfilter(b, a, seg, axis=0, zi=zi[:, None] * seg[0])
    return y


def window_segments(x, window, starts, reduce, pad=None):
    """``reduce`` (``np.min``, ``np.max``) over the last ``window`` rows, per segment.

    Causal; before its first row a segment sees ``pad``, or (None) its first
    row repeated; ``window <= 1`` returns ``x`` itself. The debounce is the
    running minimum of ``|m|`` with ``pad=0`` (a joint above the threshold
    for ``min_duration`` samples in a row is one whose minimum over them is;
    the first ``min_duration - 1`` samples of a segment cannot fire).
    """
    if window <= 1:
        return x
    out = np.empty_like(x)
    bounds = np.append(starts, x.shape[0])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        head = (np.repeat(x[lo:lo + 1], window - 1, axis=0) if pad is None
                else np.full((window - 1, x.shape[1]), pad))
        windows = np.lib.stride_tricks.sliding_window_view(
            np.concatenate([head, x[lo:hi]]), window, axis=0)
        out[lo:hi] = reduce(windows, axis=-1)
    return out
