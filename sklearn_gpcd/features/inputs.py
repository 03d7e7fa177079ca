"""GP input matrices built from :class:`~sklearn_gpcd.io.Recording` objects.

The paper models each motor current as a function of the standard
inverse-dynamics inputs (Sec. IV-A)

.. math:: x_k = [q(t_k), \\dot q(t_k), \\ddot q(t_k)]

or, for the quasi-static component, of the augmented inputs (Eq. 13)

.. math:: x^a_k = [q, \\dot q, \\ddot q, e_q, \\dot e_q, i_c](t_k),

with the column layout fixed by :mod:`sklearn_gpcd.layout`.
"""

import warnings

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils._param_validation import StrOptions
from sklearn.utils.validation import check_is_fitted

from ..layout import column_names
from .._persistence import VersionedStateMixin
from ..io import Recording
from .differentiation import METHODS, _check_options, check_finite, differentiate

#: Values accepted by ``InverseDynamicsFeatures(acceleration=...)``.
ACCELERATION_SOURCES = ("auto", "measured", "target", "differentiate")
#: Values accepted by ``InverseDynamicsFeatures(sign=...)``.
SIGN_CONVENTIONS = ("target-minus-actual", "actual-minus-target")


class MissingSignalWarning(UserWarning):
    """A signal needed by the augmented inputs is absent and was replaced.

    Emitted once per :meth:`InverseDynamicsFeatures.transform` call that fills
    a missing ``target_q``, ``target_qd`` or ``target_current`` block; the
    message names the signals, the recordings and the substitute.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.features import MissingSignalWarning, make_inputs
    >>> t = np.arange(30) * 0.01
    >>> rec = Recording(time=t, q=np.zeros((30, 1)), qd=np.zeros((30, 1)),
    ...                 current=np.ones((30, 1)))          # no target signals
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     X, y = make_inputs(rec)
    >>> [w.category.__name__ for w in caught]
    ['MissingSignalWarning']
    >>> bool(X[:, 3:].any())            # e_q, de_q and i_c filled with zeros
    False
    """


def as_recordings(recordings):
    """A non-empty list of :class:`Recording`, from one or an iterable of them.

    Package-internal (not in ``__all__``): shared with the streaming monitor's
    ``replay_recording``.
    """
    if isinstance(recordings, Recording):
        return [recordings]
    if isinstance(recordings, (str, bytes, np.ndarray)) or not hasattr(
        recordings, "__iter__"
    ):
        raise TypeError(
            "expected a Recording or a list of Recording objects, got "
            f"{type(recordings).__name__}"
        )
    recordings = list(recordings)
    if not recordings:
        raise ValueError("expected at least one Recording, got an empty list")
    for i, rec in enumerate(recordings):
        if not isinstance(rec, Recording):
            raise TypeError(
                f"item {i} is a {type(rec).__name__}, expected a Recording"
            )
    return recordings


def _label(rec, index):
    return f"{rec.name!r} (index {index})" if rec.name else f"index {index}"


def _check_joint_counts(recordings):
    """The common joint count; ValueError naming recordings that differ."""
    counts = [rec.n_joints for rec in recordings]
    if len(set(counts)) > 1:
        listing = ", ".join(
            f"{_label(rec, i)}: {n}" for i, (rec, n) in enumerate(zip(recordings, counts))
        )
        raise ValueError(f"recordings have different numbers of joints: {listing}")
    return counts[0]


def _check_finite(rec, index, key, value):
    check_finite(value, f"recording {_label(rec, index)}: {key}", column="joint")


def targets(recordings):
    """Motor currents ``y`` aligned with the rows of the input matrices.

    Parameters
    ----------
    recordings : Recording or list of Recording
        Recordings with the same number of joints.

    Returns
    -------
    y : ndarray of shape (n_samples_total, n_joints)
        ``recording.current`` of every recording, stacked in order (the
        same row order as :meth:`InverseDynamicsFeatures.transform`).

    Raises
    ------
    ValueError
        If the joint counts differ or a current is NaN/inf.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.features import targets
    >>> rec = Recording(time=np.arange(3.0), q=np.zeros((3, 2)),
    ...                 qd=np.zeros((3, 2)), current=np.ones((3, 2)))
    >>> targets([rec, rec]).shape
    (6, 2)
    """
    recordings = as_recordings(recordings)
    _check_joint_counts(recordings)
    for i, rec in enumerate(recordings):
        _check_finite(rec, i, "current", rec.current)
    return np.concatenate([rec.current for rec in recordings])


class _RecordingFeatures(VersionedStateMixin, TransformerMixin, BaseEstimator):
    """What the recording-to-inputs transformers share: constraints, names, tags."""

    _parameter_constraints = {
        "augmented": ["boolean"],
        "sign": [StrOptions(set(SIGN_CONVENTIONS))],
    }

    def _fitted_recordings(self, recordings):
        """``recordings`` as a list with the fitted joint count (ValueError otherwise)."""
        check_is_fitted(self)
        recordings = as_recordings(recordings)
        n_joints = _check_joint_counts(recordings)
        if n_joints != self.n_joints_:
            raise ValueError(
                f"recordings have {n_joints} joints, the transformer was fitted "
                f"on {self.n_joints_}"
            )
        return recordings

    def get_feature_names_out(self, input_features=None):
        """Names of the output columns, e.g. ``q_0``, ``qd_3``, ``i_c_5``.

        Parameters
        ----------
        input_features : None
            Ignored (the inputs are recordings, not named columns).

        Returns
        -------
        feature_names_out : ndarray of str objects
            :func:`sklearn_gpcd.layout.column_names` of the fitted layout.
        """
        check_is_fitted(self)
        return np.asarray(column_names(self.n_joints_, self.augmented), dtype=object)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False
        tags.requires_fit = True
        return tags


class InverseDynamicsFeatures(_RecordingFeatures):
    """Build the paper's GP inputs from recordings.

    ``transform`` returns, row per sample, either the standard inputs
    :math:`x = [q, \\dot q, \\ddot q]` (``3 n`` columns) or the augmented
    inputs of Eq. 13 (``6 n`` columns)

    .. math:: x^a = [q, \\dot q, \\ddot q, e_q, \\dot e_q, i_c],

    in the joint-major layout of :func:`sklearn_gpcd.layout.column_names`.
    Like a text vectorizer accepts strings, it accepts one
    :class:`~sklearn_gpcd.io.Recording` or a list of them; recordings are
    processed one by one (numerical differentiation never crosses a recording
    boundary) and their rows stacked in order. Pair it with :func:`targets`.

    Signals (per recording):

    * :math:`\\ddot q`, by ``acceleration``: ``"auto"`` takes ``recording.qdd``
      when logged, otherwise differentiates ``qd`` numerically with
      :func:`~sklearn_gpcd.features.differentiate`; ``"measured"`` requires
      ``recording.qdd``; ``"differentiate"`` always differentiates ``qd``;
      ``"target"`` uses the controller's ``target_qdd``. ``"auto"`` never
      falls back to ``target_qdd``: it is a command, not a measurement, and
      differs from the true acceleration exactly when something (a
      collision) disturbs the motion.
    * :math:`e_q = q_{target} - q` and :math:`\\dot e_q = \\dot q_{target} -
      \\dot q` with the default ``sign="target-minus-actual"`` (the usual
      controller error, positive when the joint lags its set-point);
      ``"actual-minus-target"`` flips both.
    * :math:`i_c` = ``target_current``, the current requested by the joint
      controller, used as is.

    Missing augmented signals (the UR10e logs have ``target_current`` but no
    ``target_q`` / ``target_qd``) do not change the layout: ``target_qd`` is
    taken as the derivative of ``target_q`` when only the latter exists, and
    otherwise the block is filled with zeros. Each ``transform`` call that
    does this emits ONE :class:`MissingSignalWarning` naming the missing
    signals, the recordings and the substitute.

    Parameters
    ----------
    augmented : bool, default=True
        Return :math:`x^a` (Eq. 13) rather than :math:`x`.
    acceleration : {"auto", "measured", "target", "differentiate"}, \
default="auto"
        Where :math:`\\ddot q` comes from (see above).
    differentiation : {"savgol", "butter", "gradient"}, default="savgol"
        Method of :func:`~sklearn_gpcd.features.differentiate` used for
        numerical derivatives.
    differentiation_options : dict, default=None
        Options of that method (e.g. ``{"window_length": 11,
        "polyorder": 3}`` or ``{"order": 5, "cutoff": 7.5}``).
    sign : {"target-minus-actual", "actual-minus-target"}, \
default="target-minus-actual"
        Sign convention of :math:`e_q` and :math:`\\dot e_q`.

    Attributes
    ----------
    n_joints_ : int
        Number of joints seen in ``fit``.
    missing_signals_ : tuple of str
        Augmented-input signals (``"target_q"``, ``"target_qd"``,
        ``"target_current"``) absent from at least one recording seen in
        ``fit``; empty when ``augmented=False``.
    acceleration_sources_ : tuple of str
        For each recording seen in ``fit``, where :math:`\\ddot q` comes from:
        ``"qdd"``, ``"target_qdd"`` or ``"differentiated qd"``.

    See Also
    --------
    make_inputs : ``(X, y)`` in one call.
    sklearn_gpcd.features.quasi_static_mask : the gate :math:`a_\\ell` of Eq. 15.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.features import InverseDynamicsFeatures
    >>> t = np.arange(50) * 0.01
    >>> q = np.column_stack([np.sin(t), np.cos(t)])
    >>> rec = Recording(time=t, q=q, qd=np.gradient(q, t, axis=0),
    ...                 current=np.ones((50, 2)), target_q=q + 0.1,
    ...                 target_qd=np.gradient(q, t, axis=0),
    ...                 target_current=np.ones((50, 2)))
    >>> features = InverseDynamicsFeatures().fit(rec)
    >>> X = features.transform(rec)
    >>> X.shape
    (50, 12)
    >>> features.get_feature_names_out()[6:8].tolist()
    ['e_q_0', 'e_q_1']
    >>> float(X[0, 6])
    0.1
    """

    _parameter_constraints = {
        **_RecordingFeatures._parameter_constraints,
        "acceleration": [StrOptions(set(ACCELERATION_SOURCES))],
        "differentiation": [StrOptions(set(METHODS))],
        "differentiation_options": [None, dict],
    }

    def __init__(
        self,
        augmented=True,
        acceleration="auto",
        differentiation="savgol",
        differentiation_options=None,
        sign="target-minus-actual",
    ):
        self.augmented = augmented
        self.acceleration = acceleration
        self.differentiation = differentiation
        self.differentiation_options = differentiation_options
        self.sign = sign

    def _acceleration_source(self, rec, index):
        """Which signal gives qdd for ``rec`` (ValueError if unavailable)."""
        if self.acceleration == "measured" and rec.qdd is None:
            raise ValueError(
                f"recording {_label(rec, index)} has no qdd but acceleration='measured'"
            )
        if self.acceleration == "target":
            if rec.target_qdd is None:
                raise ValueError(
                    f"recording {_label(rec, index)} has no target_qdd but "
                    "acceleration='target'"
                )
            return "target_qdd"
        if self.acceleration in ("auto", "measured") and rec.qdd is not None:
            return "qdd"
        return "differentiated qd"

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, recordings, y=None):
        """Check the parameters and the recordings; record what is missing.

        Parameters
        ----------
        recordings : Recording or list of Recording
            Recordings with the same number of joints.
        y : None
            Ignored.

        Returns
        -------
        self : InverseDynamicsFeatures
            Fitted transformer.
        """
        _check_options(self.differentiation, self.differentiation_options or {})
        recordings = as_recordings(recordings)
        self.n_joints_ = _check_joint_counts(recordings)
        self.acceleration_sources_ = tuple(
            self._acceleration_source(rec, i) for i, rec in enumerate(recordings)
        )
        missing = set()
        if self.augmented:
            for rec in recordings:
                missing.update(_missing_augmented(rec))
        self.missing_signals_ = tuple(s for s in _AUGMENTED_SIGNALS if s in missing)
        return self

    def _differentiate(self, rec, index, key, signal):
        try:
            return differentiate(
                rec.time, signal, self.differentiation,
                **(self.differentiation_options or {}),
            )
        except ValueError as err:
            raise ValueError(
                f"recording {_label(rec, index)}: cannot differentiate {key}: {err}"
            ) from err

    def _recording_inputs(self, rec, index):
        """Input rows of one recording and its substitutions ``{signal: note}``."""
        for key in ("q", "qd", "qdd", "target_q", "target_qd", "target_qdd",
                    "target_current"):
            value = getattr(rec, key)
            if value is not None:
                _check_finite(rec, index, key, value)
        source = self._acceleration_source(rec, index)
        if source == "qdd":
            qdd = rec.qdd
        elif source == "target_qdd":
            qdd = rec.target_qdd
        else:
            qdd = self._differentiate(rec, index, "qd", rec.qd)
        blocks = [rec.q, rec.qd, qdd]
        notes = {}
        if self.augmented:
            sign = 1.0 if self.sign == "target-minus-actual" else -1.0
            zeros = np.zeros_like(rec.q)
            if rec.target_q is None:
                e_q = zeros
                notes["target_q"] = "e_q set to 0"
            else:
                e_q = sign * (rec.target_q - rec.q)
            if rec.target_qd is not None:
                de_q = sign * (rec.target_qd - rec.qd)
            elif rec.target_q is not None:
                target_qd = self._differentiate(rec, index, "target_q", rec.target_q)
                de_q = sign * (target_qd - rec.qd)
                notes["target_qd"] = "de_q from the derivative of target_q"
            else:
                de_q = zeros
                notes["target_qd"] = "de_q set to 0"
            if rec.target_current is None:
                i_c = zeros
                notes["target_current"] = "i_c set to 0"
            else:
                i_c = rec.target_current
            blocks += [e_q, de_q, i_c]
        return np.hstack(blocks), notes

    def transform(self, recordings):
        """Input matrix of the recordings, rows stacked in order.

        Parameters
        ----------
        recordings : Recording or list of Recording
            Recordings with the joint count seen in ``fit``.

        Returns
        -------
        X : ndarray of shape (n_samples_total, 3 * n_joints) or \
(n_samples_total, 6 * n_joints)
            :math:`x` or :math:`x^a` (Eq. 13), columns named by
            :meth:`get_feature_names_out`.

        Warns
        -----
        MissingSignalWarning
            Once per call, when augmented signals had to be substituted.
        """
        recordings = self._fitted_recordings(recordings)
        rows, substitutions = [], {}
        for i, rec in enumerate(recordings):
            X, notes = self._recording_inputs(rec, i)
            rows.append(X)
            for key, note in notes.items():
                substitutions.setdefault((key, note), []).append(rec.name or f"#{i}")
        if substitutions:
            warnings.warn(_substitution_message(substitutions), MissingSignalWarning,
                          stacklevel=2)
        return np.concatenate(rows)


_AUGMENTED_SIGNALS = ("target_q", "target_qd", "target_current")


def _missing_augmented(rec):
    return [key for key in _AUGMENTED_SIGNALS if getattr(rec, key) is None]


def _substitution_message(substitutions, max_names=3):
    parts = []
    for (key, note), names in substitutions.items():
        shown = ", ".join(repr(n) for n in names[:max_names])
        if len(names) > max_names:
            shown += f" and {len(names) - max_names} more"
        parts.append(f"{key} missing in {len(names)} recording(s) ({shown}): {note}")
    return (
        "augmented inputs built from incomplete recordings; "
        + "; ".join(parts)
        + ". The column layout [q, qd, qdd, e_q, de_q, i_c] is unchanged."
    )


def make_inputs(
    recordings,
    augmented=True,
    acceleration="auto",
    differentiation="savgol",
    differentiation_options=None,
    sign="target-minus-actual",
):
    """Input matrix ``X`` and currents ``y`` of recordings in one call.

    Shorthand for ``InverseDynamicsFeatures(...).fit_transform(recordings)``
    and :func:`targets`. Keep the transformer (fit it yourself) when the same
    settings must be applied to new data.

    Parameters
    ----------
    recordings : Recording or list of Recording
        Recordings with the same number of joints.
    augmented, acceleration, differentiation, differentiation_options, sign
        See :class:`InverseDynamicsFeatures`.

    Returns
    -------
    X : ndarray of shape (n_samples_total, 3 * n_joints or 6 * n_joints)
        GP inputs, columns as :func:`sklearn_gpcd.layout.column_names`.
    y : ndarray of shape (n_samples_total, n_joints)
        Motor currents, row-aligned with ``X``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.features import make_inputs
    >>> t = np.arange(30) * 0.01
    >>> rec = Recording(time=t, q=np.zeros((30, 6)), qd=np.zeros((30, 6)),
    ...                 current=np.ones((30, 6)))
    >>> X, y = make_inputs([rec, rec], augmented=False)
    >>> X.shape, y.shape
    ((60, 18), (60, 6))
    """
    features = InverseDynamicsFeatures(
        augmented=augmented,
        acceleration=acceleration,
        differentiation=differentiation,
        differentiation_options=differentiation_options,
        sign=sign,
    )
    recordings = as_recordings(recordings)
    return features.fit_transform(recordings), targets(recordings)
