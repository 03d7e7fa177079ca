"""Causal GP inputs, one raw robot sample at a time.

:class:`InverseDynamicsFeatures` differentiates whole recordings with
zero-phase filters (Savitzky-Golay, ``filtfilt``): every row then depends on
samples that come *after* it, which no robot controller has. Detection
figures that claim online behaviour must come from inputs that can be
computed on the robot, sample by sample, with bounded state. This module
builds the same column layout (:mod:`sklearn_gpcd.layout`)

.. math:: x^a_k = [q_k,\\ \\dot q_k,\\ \\hat{\\ddot q}_k,\\ e_{q,k},\\
          \\dot e_{q,k},\\ i_{c,k}]

causally. The only derived signal is the acceleration, estimated from the
measured velocity by a backward difference and a first-order low-pass filter
discretised exactly for each (possibly irregular) time step
:math:`\\Delta t_k = t_k - t_{k-1}`:

.. math::

    d_k = \\frac{\\dot q_k - \\dot q_{k-1}}{\\Delta t_k},\\qquad
    \\hat{\\ddot q}_k = \\hat{\\ddot q}_{k-1}
        + \\beta_k\\,(d_k - \\hat{\\ddot q}_{k-1}),\\qquad
    \\beta_k = 1 - e^{-2\\pi f_c \\Delta t_k},

with :math:`\\hat{\\ddot q}_0 = 0`. Its state is two vectors (the last
velocity and the last estimate). ``e_q``, ``de_q`` and ``i_c`` are the
controller's logged signals (the same definitions as
:class:`InverseDynamicsFeatures`); when ``target_qd`` is not logged but
``target_q`` is, its derivative is the same causal estimate.

:class:`CausalFeatures` is the scikit-learn transformer (whole recordings,
for training and batch evaluation); :meth:`CausalFeatures.online` returns an
:class:`OnlineFeatures` state that turns one raw sample into one input row.
``transform`` runs exactly that state over every sample, so batch and
streaming rows are identical by construction.
"""

import warnings
from numbers import Real

import numpy as np
from sklearn.base import _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from .inputs import (
    _AUGMENTED_SIGNALS,
    MissingSignalWarning,
    _check_finite,
    _check_joint_counts,
    _label,
    _RecordingFeatures,
    as_recordings,
)


class OnlineFeatures:
    """Bounded state that turns one raw sample into one GP input row.

    Made by :meth:`CausalFeatures.online`; see the module docstring for the
    maths. :meth:`step` writes into, and returns, one preallocated row: copy
    it if you keep it past the next call.

    Parameters
    ----------
    n_joints : int
        Number of joints.
    augmented : bool
        Build :math:`x^a` (``6 n`` columns) rather than :math:`x`.
    acceleration_cutoff : float
        Cut-off frequency :math:`f_c` [Hz] of the acceleration estimate.
    signals : tuple of str
        Augmented signals the model was trained with (``"target_q"``,
        ``"target_qd"``, ``"target_current"``); the others are zero.
    sign : float
        +1 for ``e_q = target_q - q``, -1 for the opposite convention.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.features import CausalFeatures
    >>> state = CausalFeatures(augmented=False).online(n_joints=1)
    >>> state.step(0.00, q=[0.0], qd=[0.0]).tolist()
    [0.0, 0.0, 0.0]
    >>> state.step(0.01, q=[0.0], qd=[0.1]).round(3).tolist()  # qd jumps by 0.1
    [0.0, 0.1, 2.696]
    """

    def __init__(self, n_joints, augmented, acceleration_cutoff, signals, sign=1.0):
        self.n_joints = n_joints
        self.augmented = augmented
        self.acceleration_cutoff = float(acceleration_cutoff)
        self.signals = tuple(signals)
        self.sign = sign
        n = n_joints
        self.row = np.zeros((6 if augmented else 3) * n)
        self._qdd = self.row[2 * n : 3 * n]
        self._dtarget = np.zeros(n)  # causal derivative of target_q
        self._last_qd = np.zeros(n)
        self._last_target_q = np.zeros(n)
        self._scratch = np.zeros(n)
        self.reset()

    def reset(self):
        """Forget the history (a new recording starts)."""
        self.last_time = None
        self._qdd[:] = 0.0
        self._dtarget[:] = 0.0

    def _lowpass_derivative(self, value, last, estimate, dt):
        """``estimate += beta (d - estimate)`` with ``d = (value - last) / dt``."""
        beta = 1.0 - np.exp(-2.0 * np.pi * self.acceleration_cutoff * dt)
        d = self._scratch
        np.subtract(value, last, out=d)
        d /= dt
        d -= estimate
        d *= beta
        estimate += d

    def step(self, time, q, qd, target_q=None, target_qd=None, target_current=None):
        """The input row of one sample.

        Parameters
        ----------
        time : float
            Time stamp [s], strictly after the previous sample's.
        q, qd : array-like of shape (n_joints,)
            Measured positions [rad] and velocities [rad/s].
        target_q, target_qd, target_current : array-like of shape (n_joints,), \
default=None
            Controller signals; needed when the features were fitted with
            them (see ``CausalFeatures.signals_``), ignored otherwise.

        Returns
        -------
        row : ndarray of shape (3 * n_joints,) or (6 * n_joints,)
            The preallocated row, overwritten by the next call.

        Raises
        ------
        ValueError
            When ``time`` does not advance or a needed signal is None.
        """
        n = self.n_joints
        row = self.row
        row[:n] = q
        row[n : 2 * n] = qd
        if self.last_time is None:
            self._qdd[:] = 0.0
        else:
            dt = time - self.last_time
            if not dt > 0.0:
                raise ValueError(
                    f"time must increase: got {time!r} after {self.last_time!r}"
                )
            self._lowpass_derivative(row[n : 2 * n], self._last_qd, self._qdd, dt)
        if self.augmented:
            self._augmented(time, row, target_q, target_qd, target_current)
        self._last_qd[:] = row[n : 2 * n]
        self.last_time = time
        return row

    def _augmented(self, time, row, target_q, target_qd, target_current):
        n = self.n_joints
        e_q, de_q, i_c = row[3 * n : 4 * n], row[4 * n : 5 * n], row[5 * n :]
        if "target_q" in self.signals:
            _require(target_q, "target_q")
            np.subtract(target_q, row[:n], out=e_q)
            e_q *= self.sign
            if "target_qd" not in self.signals:  # derivative of target_q, causally
                if self.last_time is not None:
                    self._lowpass_derivative(
                        target_q, self._last_target_q, self._dtarget, time - self.last_time
                    )
                np.subtract(self._dtarget, row[n : 2 * n], out=de_q)
                de_q *= self.sign
            self._last_target_q[:] = target_q
        if "target_qd" in self.signals:
            _require(target_qd, "target_qd")
            np.subtract(target_qd, row[n : 2 * n], out=de_q)
            de_q *= self.sign
        if "target_current" in self.signals:
            _require(target_current, "target_current")
            i_c[:] = target_current


def _require(value, name):
    if value is None:
        raise ValueError(
            f"{name} is missing, but the features were fitted on recordings that "
            f"log it (the model uses it); pass {name}, or train the model without "
            "it: gpcd train ... --signals none"
        )


class CausalFeatures(_RecordingFeatures):
    """The paper's GP inputs, computed causally (what can run on the robot).

    Same column layout as :class:`InverseDynamicsFeatures` (Eq. 13), but
    every row depends only on the current and past samples: the acceleration
    is a causal low-pass derivative of the measured velocity (see
    :mod:`sklearn_gpcd.features.online`), never a zero-phase filter. Use it
    for every figure that claims online behaviour, and wherever a detector is
    calibrated (thresholds must be set on the signal the robot will see).
    :meth:`online` gives the per-sample state used by
    :class:`~sklearn_gpcd.detection.StreamingMonitor`; ``transform`` runs that
    same state over each recording, so batch == streaming, row for row.

    **Missing signals.** ``fit`` records which controller signals
    (``target_q``, ``target_qd``, ``target_current``) the inputs use
    (``signals_``): with ``signals="auto"`` every one that all training
    recordings log. ``transform`` then requires them: a recording without
    one raises ``ValueError`` (a model trained with the controller current
    and silently fed zeros misses collisions), unless ``allow_missing=True``,
    which fills zeros and warns (:class:`MissingSignalWarning`). The signals
    not used are zero everywhere (``missing_signals_``). A model that reads
    none of their columns (P_f and SP_S read only :math:`[q, \\dot q,
    \\ddot q]`) should not require them: ``signals=()`` keeps their columns
    zero and accepts recordings that do not log them.

    Parameters
    ----------
    augmented : bool, default=True
        Return :math:`x^a` (``6 n`` columns, Eq. 13) rather than :math:`x`.
    acceleration_cutoff : float, default=5.0
        Cut-off [Hz] of the causal acceleration estimate: lower is smoother
        and later (group delay about :math:`1 / (2 \\pi f_c)`, 32 ms at 5 Hz).
    sign : {"target-minus-actual", "actual-minus-target"}, \
default="target-minus-actual"
        Sign convention of :math:`e_q` and :math:`\\dot e_q`.
    allow_missing : bool, default=False
        Fill controller signals missing at transform time with zeros (with a
        warning) instead of raising.
    signals : "auto" or tuple of str, default="auto"
        Controller signals the inputs use: "auto", every one logged by all
        training recordings; or some of ``"target_q"``, ``"target_qd"``,
        ``"target_current"`` (each must be logged by every training
        recording; ``()`` uses none).

    Attributes
    ----------
    n_joints_ : int
        Number of joints seen in ``fit``.
    signals_ : tuple of str
        Controller signals used (and then required by ``transform``).
    missing_signals_ : tuple of str
        Controller signals not used, absent from some training recording or
        left out by ``signals`` (their columns are zero).

    See Also
    --------
    InverseDynamicsFeatures : Zero-phase (offline) inputs, for training.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.features import CausalFeatures
    >>> t = np.arange(100) * 0.01
    >>> q = np.sin(t)[:, None]
    >>> rec = Recording(time=t, q=q, qd=np.cos(t)[:, None], current=q,
    ...                 target_current=q)
    >>> features = CausalFeatures().fit(rec)
    >>> features.signals_
    ('target_current',)
    >>> X = features.transform(rec)
    >>> X.shape
    (100, 6)
    >>> state = features.online()
    >>> rows = np.array([state.step(t[k], q[k], np.cos(t[k:k + 1]),
    ...                             target_current=q[k]).copy() for k in range(100)])
    >>> bool(np.array_equal(rows, X))              # batch == streaming
    True
    >>> CausalFeatures(signals=()).fit(rec).missing_signals_   # e.g. for P_f
    ('target_q', 'target_qd', 'target_current')
    """

    _parameter_constraints = {
        **_RecordingFeatures._parameter_constraints,
        "acceleration_cutoff": [Interval(Real, 0, np.inf, closed="neither")],
        "allow_missing": ["boolean"],
        "signals": [StrOptions({"auto"}), tuple, list],
    }

    def __init__(self, augmented=True, acceleration_cutoff=5.0,
                 sign="target-minus-actual", allow_missing=False, signals="auto"):
        self.augmented = augmented
        self.acceleration_cutoff = acceleration_cutoff
        self.sign = sign
        self.allow_missing = allow_missing
        self.signals = signals

    def _requested_signals(self):
        """``signals`` checked: "auto", or a tuple of known names without repeats."""
        signals = self.signals
        if isinstance(signals, str):
            return signals
        names = tuple(signals)
        if not set(names) <= set(_AUGMENTED_SIGNALS) or len(set(names)) < len(names):
            raise ValueError(
                f"signals must be 'auto' or a tuple of distinct names among "
                f"{_AUGMENTED_SIGNALS}, got {signals!r}"
            )
        if names and not self.augmented:
            raise ValueError(f"signals={signals!r} needs augmented=True (the inputs x have "
                             "no controller columns)")
        return names

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, recordings, y=None):
        """Check the parameters; record the joint count and the signals logged.

        Parameters
        ----------
        recordings : Recording or list of Recording
            Training recordings.
        y : None
            Ignored.

        Returns
        -------
        self : CausalFeatures
        """
        requested = self._requested_signals()
        recordings = as_recordings(recordings)
        self.n_joints_ = _check_joint_counts(recordings)
        present = [
            s for s in _AUGMENTED_SIGNALS
            if self.augmented and all(getattr(r, s) is not None for r in recordings)
        ]
        if requested != "auto":
            if (name := next((s for s in requested if s not in present), None)):
                lacking = next(i for i, r in enumerate(recordings) if getattr(r, name) is None)
                raise ValueError(
                    f"signals asks for {name}, but training recording "
                    f"{_label(recordings[lacking], lacking)} does not log it"
                )
            present = [s for s in present if s in requested]
        self.signals_ = tuple(present)
        self.missing_signals_ = tuple(
            s for s in _AUGMENTED_SIGNALS if self.augmented and s not in present
        )
        return self

    def online(self, n_joints=None):
        """A fresh :class:`OnlineFeatures` state for one stream of samples.

        Parameters
        ----------
        n_joints : int, default=None
            Only for an unfitted transformer (then no controller signal is
            used); a fitted one uses ``n_joints_`` and ``signals_``.

        Returns
        -------
        state : OnlineFeatures
        """
        if n_joints is None:
            check_is_fitted(self)
            n_joints, signals = self.n_joints_, self.signals_
        else:
            self._validate_params()
            signals = ()
        sign = 1.0 if self.sign == "target-minus-actual" else -1.0
        return OnlineFeatures(n_joints, self.augmented, self.acceleration_cutoff, signals, sign)

    def _signals_for(self, rec, index):
        """The fitted signals ``rec`` can give; error or warning for the others."""
        absent = [s for s in self.signals_ if getattr(rec, s) is None]
        if absent and not self.allow_missing:
            raise ValueError(
                f"recording {_label(rec, index)} does not log {', '.join(absent)}, which "
                "the model was trained with; use recordings that log it, or train the "
                "model without it: gpcd train ... --signals none (or --signals with the "
                "ones these recordings log)"
            )
        return tuple(s for s in self.signals_ if s not in absent), absent

    def transform(self, recordings):
        """Causal input rows of the recordings, stacked in order.

        Parameters
        ----------
        recordings : Recording or list of Recording
            Recordings with the joint count seen in ``fit``; each starts a
            fresh state.

        Returns
        -------
        X : ndarray of shape (n_samples_total, 3 * n_joints or 6 * n_joints)
        """
        recordings = self._fitted_recordings(recordings)
        blocks, filled = [], []
        for i, rec in enumerate(recordings):
            signals, absent = self._signals_for(rec, i)
            if absent:
                filled.append(f"{rec.name or f'#{i}'} ({', '.join(absent)})")
            blocks.append(self._recording_rows(rec, i, signals))
        if filled:
            warnings.warn(
                "controller signals missing, filled with zeros: " + "; ".join(filled),
                MissingSignalWarning, stacklevel=2,
            )
        return np.concatenate(blocks)

    def _recording_rows(self, rec, index, signals):
        for key in ("q", "qd", *signals):
            _check_finite(rec, index, key, getattr(rec, key))
        sign = 1.0 if self.sign == "target-minus-actual" else -1.0
        state = OnlineFeatures(self.n_joints_, self.augmented, self.acceleration_cutoff,
                               signals, sign)
        columns = {s: getattr(rec, s) for s in signals}
        out = np.empty((rec.n_samples, state.row.shape[0]))
        for k in range(rec.n_samples):
            out[k] = state.step(
                rec.time[k], rec.q[k], rec.qd[k],
                **{s: v[k] for s, v in columns.items()},
            )
        return out
