"""The :class:`Robot` type: a pinocchio model plus the drive-train data the
collision detector needs (torque constants, gear ratios, rotor inertias)."""

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

#: Longest pinocchio model text a saved robot may hold [characters] (a UR's
#: is about 15,000; a 7-link arm with meshes' inertias well below 1 MB).
MAX_MODEL_TEXT = 4 << 20

def _per_joint(values, n_joints, name, positive=False):
    """Validate an optional per-joint vector."""
    if values is None:
        return None
    arr = np.asarray(values, dtype=float).reshape(-1)
    if arr.shape != (n_joints,):
        raise ValueError(
            f"{name} needs one value per joint ({n_joints}), got shape {np.shape(values)}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf: {arr.tolist()}")
    if positive and np.any(arr <= 0):
        raise ValueError(f"{name} must be strictly positive, got {arr.tolist()}")
    if not positive and np.any(arr < 0):
        raise ValueError(f"{name} must be non-negative, got {arr.tolist()}")
    return arr


def as_joint_batch(values, n_joints, name):
    """Return ``values`` as a float array of shape (n_samples, n_joints).

    Parameters
    ----------
    values : array-like of shape (n_joints,) or (n_samples, n_joints)
    n_joints : int
    name : str
        Used in error messages.

    Returns
    -------
    batch : ndarray of shape (n_samples, n_joints)
    single : bool
        True when ``values`` was one-dimensional.

    Examples
    --------
    >>> batch, single = as_joint_batch([0.0, 1.0], 2, "q")
    >>> batch.shape, single
    ((1, 2), True)
    """
    arr = np.asarray(values, dtype=float)
    single = arr.ndim == 1
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != n_joints:
        raise ValueError(
            f"{name} must have shape (n_joints,) or (n_samples, n_joints) with "
            f"n_joints={n_joints}, got {np.shape(values)}"
        )
    bad = ~np.isfinite(arr)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise ValueError(f"{name} contains NaN or inf (first at row {row}, joint {col})")
    return arr, single


def _model_limits(field, doc):
    """A read-only property: the pinocchio model's ``field`` as a float array."""
    return property(lambda self: np.array(getattr(self.model, field), dtype=float), doc=doc)


@dataclass(eq=False)
class Robot:
    """A serial robot arm: kinematic/dynamic model and drive-train data.

    Build one with :func:`sklearn_gpcd.robots.load_robot`.

    Parameters
    ----------
    name : str
        Lowercase robot name (``"ur10e"``) or the URDF file stem.
    model : pinocchio.Model
        Kinematic tree of ``n_joints`` one-dof joints. Its ``armature`` is the
        reflected rotor inertia used by :meth:`rnea`.
    flange_frame : str
        Name of the pinocchio frame at the tool flange.
    torque_constants : ndarray of shape (n_joints,), default=None
        Motor current [A] -> joint torque [Nm], i.e. ``K_tau K_r`` of the
        paper (Eq. 4), so that ``tau = torque_constants * current``.
        ``None`` when unknown.
    gear_ratios : ndarray of shape (n_joints,), default=None
        Gear reduction ratios ``K_r`` (Eq. 4), ``None`` when unknown.
    rotor_inertias : ndarray of shape (n_joints,), default=None
        Reflected rotor inertias on the joint side, ``K_r^2 J_m`` [kg m^2]
        (Eq. 4). When given they are copied into ``model.armature``;
        ``None`` keeps the model's armature (zero for built-in robots).
    dh : ndarray of shape (n_joints, 3), default=None
        Standard DH table ``(d, a, alpha)`` for DH-built robots.
    citation : str, default=""
        Where the parameters come from.

    Attributes
    ----------
    n_joints : int
    joint_names : list of str
    lower, upper : ndarray of shape (n_joints,)
        Position limits [rad].
    velocity_limits : ndarray of shape (n_joints,)
        [rad/s].
    effort_limits : ndarray of shape (n_joints,)
        [Nm].
    flange_frame_id : int
        Index of ``flange_frame`` in ``model.frames``.

    Examples
    --------
    >>> from sklearn_gpcd.robots import load_robot
    >>> robot = load_robot("ur10e")
    >>> robot.n_joints, robot.joint_names[1]
    (6, 'shoulder_lift_joint')
    >>> robot.gravity([0.0, -1.57, 0.0, -1.57, 0.0, 0.0]).shape
    (6,)
    """

    name: str
    model: pin.Model = field(repr=False)
    flange_frame: str
    torque_constants: np.ndarray = None
    gear_ratios: np.ndarray = None
    rotor_inertias: np.ndarray = None
    dh: np.ndarray = field(default=None, repr=False)
    citation: str = field(default="", repr=False)

    def __post_init__(self):
        if self.model.nq != self.model.nv:
            raise ValueError(
                f"robot {self.name!r}: only one-dof revolute/prismatic joints are "
                f"supported (model has nq={self.model.nq}, nv={self.model.nv}; "
                "continuous URDF joints use cos/sin and are not supported)"
            )
        n = self.model.nv
        self.torque_constants = _per_joint(self.torque_constants, n, "torque_constants", True)
        self.gear_ratios = _per_joint(self.gear_ratios, n, "gear_ratios", True)
        self.rotor_inertias = _per_joint(self.rotor_inertias, n, "rotor_inertias")
        if self.rotor_inertias is not None:
            self.model.armature = self.rotor_inertias.copy()
        if not self.model.existFrame(self.flange_frame):
            names = [f.name for f in self.model.frames]
            raise ValueError(
                f"flange frame {self.flange_frame!r} not in the model; frames: {names}"
            )
        if self.dh is not None:
            self.dh = np.asarray(self.dh, dtype=float)

    # ----------------------------------------------------------- pickling
    def __getstate__(self):
        """State for pickle / joblib / skops, with the model as text.

        A ``pinocchio.Model`` cannot be rebuilt the way skops rebuilds
        objects (``cls.__new__`` then ``__setstate__``), so the model is
        stored as pinocchio's text archive (``model.saveToString()``), which
        writes every double with 17 significant digits: the reloaded model,
        and so :meth:`rnea` and the regressors, are bit-identical.

        Returns
        -------
        state : dict
            The dataclass fields, ``model`` replaced by a str.

        Examples
        --------
        >>> from sklearn_gpcd.robots import load_robot
        >>> state = load_robot("ur10").__getstate__()
        >>> type(state["model"]).__name__
        'str'
        """
        state = self.__dict__.copy()
        state["model"] = self.model.saveToString()
        return state

    def __setstate__(self, state):
        """Restore from :meth:`__getstate__` (a ``pinocchio.Model`` is accepted too).

        Parameters
        ----------
        state : dict
            As returned by :meth:`__getstate__`; older pickles hold the
            ``pinocchio.Model`` itself under ``"model"``.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.robots import Robot, load_robot
        >>> robot = load_robot("ur10")
        >>> copy = Robot.__new__(Robot)
        >>> copy.__setstate__(robot.__getstate__())
        >>> q = np.linspace(-1.0, 1.0, 6)
        >>> bool(np.array_equal(copy.gravity(q), robot.gravity(q)))
        True
        """
        state = dict(state)
        model = state.get("model")
        if isinstance(model, str):
            if len(model) > MAX_MODEL_TEXT:
                raise ValueError(f"Robot state: the pinocchio model text has {len(model):,} "
                                 f"characters, more than the {MAX_MODEL_TEXT:,} a robot's has")
            state["model"] = pin.Model()
            try:
                state["model"].loadFromString(model)
            except RuntimeError as exc:  # pinocchio's archive reader: truncated or edited
                raise ValueError(f"Robot state: the pinocchio model text does not load "
                                 f"({exc})") from None
        elif not isinstance(model, pin.Model):
            raise TypeError(
                "Robot state needs 'model' as a pinocchio.Model or the str of "
                f"model.saveToString(), got {type(model).__name__}"
            )
        self.__dict__.update(state)

    # ------------------------------------------------------------------ info
    @property
    def n_joints(self):
        return int(self.model.nv)

    @property
    def joint_names(self):
        return list(self.model.names)[1:]

    lower = _model_limits("lowerPositionLimit", "Lower joint position limits [rad].")
    upper = _model_limits("upperPositionLimit", "Upper joint position limits [rad].")
    velocity_limits = _model_limits("velocityLimit", "Joint velocity limits [rad/s].")
    effort_limits = _model_limits("effortLimit", "Joint torque limits [Nm].")

    @property
    def flange_frame_id(self):
        return int(self.model.getFrameId(self.flange_frame))

    # ------------------------------------------------------------- dynamics
    def forward_kinematics(self, q, frame=None):
        """Pose of the flange (or another frame) in the model's world frame.

        The world frame is the DH base frame for built-in robots and the URDF
        root link otherwise.

        Parameters
        ----------
        q : array-like of shape (n_joints,) or (n_samples, n_joints)
            Joint positions [rad].
        frame : str, default=None
            Frame name; ``None`` means :attr:`flange_frame`.

        Returns
        -------
        T : ndarray of shape (4, 4) or (n_samples, 4, 4)
            Homogeneous transforms.

        Examples
        --------
        >>> from sklearn_gpcd.robots import load_robot
        >>> T = load_robot("ur5").forward_kinematics([0, 0, 0, 0, 0, 0])
        >>> T.shape
        (4, 4)
        """
        q, single = as_joint_batch(q, self.n_joints, "q")
        frame = self.flange_frame if frame is None else frame
        if not self.model.existFrame(frame):
            raise ValueError(f"frame {frame!r} not in robot {self.name!r}")
        fid = self.model.getFrameId(frame)
        data = self.model.createData()
        out = np.empty((len(q), 4, 4))
        for k, qk in enumerate(q):
            pin.framesForwardKinematics(self.model, data, qk)
            out[k] = data.oMf[fid].homogeneous
        return out[0] if single else out

    def gravity(self, q):
        """Gravity torques :math:`\\tau_g(q)` [Nm] (Eq. 1).

        Parameters
        ----------
        q : array-like of shape (n_joints,) or (n_samples, n_joints)

        Returns
        -------
        tau_g : ndarray of shape (n_joints,) or (n_samples, n_joints)

        Examples
        --------
        >>> from sklearn_gpcd.robots import load_robot
        >>> tau = load_robot("ur5").gravity([0, 0, 0, 0, 0, 0])  # arm horizontal
        >>> tau[1:3].round(1).tolist()
        [-53.8, -15.6]
        """
        q, single = as_joint_batch(q, self.n_joints, "q")
        data = self.model.createData()
        out = np.empty_like(q)
        for k, qk in enumerate(q):
            out[k] = pin.computeGeneralizedGravity(self.model, data, qk)
        return out[0] if single else out

    def rnea(self, q, qd, qdd):
        """Inverse dynamics :math:`M(q)\\ddot q + C(q,\\dot q)\\dot q + \\tau_g(q)`.

        ``M`` includes the reflected rotor inertias (``model.armature``,
        Eq. 4: :math:`M_{eq} = M + K_r^2 J_m`); no friction.

        Parameters
        ----------
        q, qd, qdd : array-like of shape (n_joints,) or (n_samples, n_joints)
            Joint positions, velocities and accelerations.

        Returns
        -------
        tau : ndarray of shape (n_joints,) or (n_samples, n_joints)
            Joint torques [Nm].

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.robots import load_robot
        >>> robot = load_robot("ur10")
        >>> q = np.zeros(6)
        >>> bool(np.allclose(robot.rnea(q, q, q), robot.gravity(q)))
        True
        """
        q, single = as_joint_batch(q, self.n_joints, "q")
        qd, _ = as_joint_batch(qd, self.n_joints, "qd")
        qdd, _ = as_joint_batch(qdd, self.n_joints, "qdd")
        if not (len(q) == len(qd) == len(qdd)):
            raise ValueError(
                f"q, qd, qdd must have the same number of samples, got "
                f"{len(q)}, {len(qd)}, {len(qdd)}"
            )
        data = self.model.createData()
        out = np.empty_like(q)
        for k in range(len(q)):
            out[k] = pin.rnea(self.model, data, q[k], qd[k], qdd[k])
        return out[0] if single else out
