"""External contacts (collisions, pushes) applied to the simulated robot."""

from dataclasses import dataclass

import numpy as np
import pinocchio as pin


@dataclass(frozen=True)
class Contact:
    """A force (and moment) on one link over a time interval, smooth in time.

    The wrench ``s(t) [F; M]`` acts at ``point`` on link ``link`` and enters
    the dynamics as the joint torque

    .. math::

        \\tau_{ext}(t) = s(t)\\, J_k(q)^T
            \\begin{bmatrix} F \\\\ p \\times F + M \\end{bmatrix},

    with ``J_k`` the Jacobian of joint ``k``'s frame in that frame (pinocchio
    ``LOCAL``), ``F, M`` expressed in it and ``p`` the point. The profile
    ``s(t)`` rises from 0 to 1 in ``rise_time`` with a half cosine, holds,
    and falls back symmetrically; with the default ``rise_time`` (half the
    duration) it is the bell ``sin^2(pi (t - start) / duration)``.

    Parameters
    ----------
    link : int
        Link touched, 1-based as in the paper: link ``k`` is the body moved
        by joint ``k`` (pinocchio joint id ``k``), so a force on link 1 only
        loads joint 1.
    start : float
        Contact onset [s] from the beginning of the simulation.
    duration : float
        Contact length [s].
    force : array-like of shape (3,)
        Peak force [N].
    point : array-like of shape (3,), default=(0, 0, 0)
        Application point in the link (joint) frame [m].
    moment : array-like of shape (3,), default=(0, 0, 0)
        Peak pure moment [Nm].
    frame : {"world", "local"}, default="world"
        Frame of ``force`` and ``moment``: the base frame, or the link frame
        (the force then turns with the link).
    rise_time : float, default=None
        Ramp time [s]; None means ``duration / 2``.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import Contact
    >>> push = Contact(link=1, start=2.0, duration=1.0, force=[0.0, 100.0, 0.0],
    ...                point=[0.2, 0.0, 0.0], frame="local")
    >>> push.profile([1.9, 2.25, 2.5, 3.0]).round(3).tolist()
    [0.0, 0.5, 1.0, 0.0]
    >>> push.stop
    3.0
    """

    link: int
    start: float
    duration: float
    force: np.ndarray
    point: np.ndarray = (0.0, 0.0, 0.0)
    moment: np.ndarray = (0.0, 0.0, 0.0)
    frame: str = "world"
    rise_time: float = None

    def __post_init__(self):
        if int(self.link) != self.link or self.link < 1:
            raise ValueError(f"Contact.link must be a 1-based link index, got {self.link!r}")
        object.__setattr__(self, "link", int(self.link))
        for key in ("force", "point", "moment"):
            value = np.asarray(getattr(self, key), dtype=float)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(
                    f"Contact.{key} must be 3 finite numbers, got {getattr(self, key)!r}"
                )
            value.setflags(write=False)
            object.__setattr__(self, key, value)
        if not (np.isfinite(self.start) and self.start >= 0):
            raise ValueError(f"Contact.start must be >= 0 seconds, got {self.start}")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"Contact.duration must be > 0 seconds, got {self.duration}")
        if self.frame not in ("world", "local"):
            raise ValueError(f"Contact.frame must be 'world' or 'local', got {self.frame!r}")
        if self.rise_time is not None and not 0 < self.rise_time <= self.duration / 2:
            raise ValueError(
                f"Contact.rise_time must be in (0, duration/2] = (0, {self.duration / 2}], "
                f"got {self.rise_time}"
            )

    @property
    def stop(self):
        """End of the contact [s]."""
        return self.start + self.duration

    def profile(self, t):
        """Time profile ``s(t)`` in ``[0, 1]``, zero outside ``[start, stop)``.

        Parameters
        ----------
        t : array-like
            Times [s].

        Returns
        -------
        s : ndarray, same shape as ``t``
        """
        t = np.asarray(t, dtype=float)
        rise = self.duration / 2 if self.rise_time is None else self.rise_time
        tau = np.minimum(t - self.start, self.stop - t)  # distance to the nearer edge
        s = 0.5 * (1.0 - np.cos(np.pi * np.clip(tau, 0.0, rise) / rise))
        return np.where((t >= self.start) & (t < self.stop), s, 0.0)

    def joint_torque(self, model, data, q, scale=1.0):
        """Joint torque ``scale * J^T w`` of the peak wrench at configuration ``q``.

        Parameters
        ----------
        model, data : pinocchio.Model, pinocchio.Data
        q : ndarray of shape (model.nq,)
        scale : float, default=1.0
            Profile value ``s(t)``.

        Returns
        -------
        tau_ext : ndarray of shape (model.nv,)
        """
        pin.forwardKinematics(model, data, q)  # data.oMi for the world frame
        jac = pin.computeJointJacobian(model, data, q, self.link)  # LOCAL frame
        force, moment = self.force, self.moment
        if self.frame == "world":
            rotation = data.oMi[self.link].rotation
            force, moment = rotation.T @ force, rotation.T @ moment
        p = self.point
        moment = moment + (  # p x F, spelled out (np.cross is slow on 3-vectors)
            p[1] * force[2] - p[2] * force[1],
            p[2] * force[0] - p[0] * force[2],
            p[0] * force[1] - p[1] * force[0],
        )
        return scale * (jac[:3].T @ force + jac[3:].T @ moment)


def contact_labels(time, contacts):
    """Ground-truth labels: 0 in free motion, ``k`` inside the k-th contact.

    Contacts are numbered 1, 2, ... in the order given; where two overlap the
    later one wins.

    Parameters
    ----------
    time : array-like of shape (n_samples,)
        Sample times [s].
    contacts : sequence of Contact

    Returns
    -------
    labels : ndarray of shape (n_samples,), dtype int

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.datasets import Contact
    >>> from sklearn_gpcd.datasets.contacts import contact_labels
    >>> c = Contact(link=1, start=1.0, duration=1.0, force=[1.0, 0.0, 0.0])
    >>> contact_labels(np.arange(4.0), [c]).tolist()
    [0, 1, 0, 0]
    """
    time = np.asarray(time, dtype=float)
    labels = np.zeros(time.shape, dtype=int)
    for k, contact in enumerate(contacts, start=1):
        labels[(time >= contact.start) & (time < contact.stop)] = k
    return labels
