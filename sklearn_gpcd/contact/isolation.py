r"""Which link was hit: isolation from the joint residuals of an alarm event.

A contact force on link :math:`k` enters the joint torques as
:math:`\tau_{ext} = J_k(q)^T F`, and the Jacobian of a point on link
:math:`k` has zero columns for the joints beyond :math:`k` (they do not move
the point). So joints :math:`k+1, \dots, n` carry no external torque, and the
most distal joint whose residual is significant is the contact link -- or,
strictly, a lower bound of it: a force through (or parallel to) the axes of
the joints up to :math:`k` loads only the proximal ones (Haddadin, De Luca
and Albu-Schäffer, IEEE T-RO 2017, Sec. V, "isolation").

Significance is measured against the detector's own scale: per joint, the
peak of the monitoring signal over the event divided by its threshold,
:math:`\rho_\ell = \max_t |m_\ell(t)| / \sigma_{CD,\ell}(t)` (a joint that
fired has :math:`\rho_\ell > 1`).
"""

import numpy as np
from sklearn.utils import Bunch

__all__ = ["LINK_GROUPS", "isolate_contact", "link_group"]

#: Link groups of a six-joint arm (1-based links): the groups the 2020 UR10e
#: collision files are named by (``2link``, ``3link``, ``wrist``) plus the base.
LINK_GROUPS = {"link 1": (1,), "link 2": (2,), "link 3": (3,), "wrist": (4, 5, 6)}


def link_group(link, n_joints=6):
    """Name of the group of a 1-based link: ``"link 1"`` .. ``"link 3"``, ``"wrist"``.

    Parameters
    ----------
    link : int
        1-based link (link ``k`` is moved by joint ``k``).
    n_joints : int, default=6
        Joints of the arm; the groups of :data:`LINK_GROUPS` apply to six
        joints, other arms get ``"link k"``.

    Returns
    -------
    group : str

    Examples
    --------
    >>> link_group(2), link_group(5), link_group(5, n_joints=7)
    ('link 2', 'wrist', 'link 5')
    """
    link = int(link)
    if not 1 <= link <= n_joints:
        raise ValueError(f"link must be in 1..{n_joints}, got {link}")
    if n_joints == 6:
        for name, links in LINK_GROUPS.items():
            if link in links:
                return name
    return f"link {link}"


def isolate_contact(signal, thresholds, *, sharpness=4.0):
    """The link most likely hit during an alarm event, with a confidence.

    Parameters
    ----------
    signal : array-like of shape (n_samples, n_joints)
        The joint monitoring signals (residuals, e.g. filtered) over the
        event, in the units of ``thresholds``.
    thresholds : array-like of shape (n_joints,) or (n_samples, n_joints)
        The detector's thresholds (or any per-joint scale of the
        collision-free signal), per sample when they change with the regime.
    sharpness : float > 0, default=4.0
        Slope :math:`s` of the certainty that a joint carries external
        torque, :math:`c(\\rho) = \\rho^s / (1 + \\rho^s)` (one half at the
        threshold, 0.94 at twice it for ``s = 4``).

    Returns
    -------
    result : Bunch
        ``link`` (int, 1-based): the most distal joint with
        :math:`\\rho_\\ell > 1`, or the joint of the largest :math:`\\rho`
        when none exceeds its threshold; ``group`` (:func:`link_group`);
        ``confidence`` (float in [0, 1]): the share of ``link`` in
        ``probabilities``; ``probabilities`` (ndarray of shape (n_joints,)):
        per link :math:`k`, :math:`c(\\rho_k) \\prod_{\\ell > k} (1 -
        c(\\rho_\\ell))` (joint :math:`k` loaded, none beyond it), normalised
        together with ``no_contact``, :math:`\\prod_\\ell (1 - c(\\rho_\\ell))`
        (no joint loaded), to sum 1; ``significance`` (:math:`\\rho`, shape
        (n_joints,)).

    Notes
    -----
    The confidence is a heuristic, not a calibrated probability: it is high
    when the chosen joint is well above its threshold and the joints beyond
    it well below theirs, and it falls towards 1/2 when either sits near its
    threshold. What it cannot see is a force whose torque on the more
    distal joints of the hit link vanishes (through or parallel to their
    axes): then ``link`` is proximal to the contact.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.contact import isolate_contact
    >>> signal = np.array([[0.5, 3.0, 2.0, 0.1, 0.05, 0.02]])   # one sample, A
    >>> out = isolate_contact(signal, thresholds=[1.0, 1.0, 1.0, 0.3, 0.3, 0.3])
    >>> out.link, out.group, round(out.confidence, 2)
    (3, 'link 3', 0.93)
    """
    signal = np.atleast_2d(np.asarray(signal, dtype=float))
    if signal.ndim != 2 or signal.shape[0] == 0:
        raise ValueError(f"signal must be (n_samples, n_joints), got shape {signal.shape}")
    thresholds = np.broadcast_to(np.asarray(thresholds, dtype=float), signal.shape)
    if not np.all(thresholds > 0):
        raise ValueError("thresholds must be > 0")
    if not (np.isfinite(sharpness) and sharpness > 0):
        raise ValueError(f"sharpness must be a finite number > 0, got {sharpness!r}")
    rho = np.nanmax(np.abs(signal) / thresholds, axis=0)
    rho = np.nan_to_num(rho, nan=0.0)
    n = rho.size
    above = np.flatnonzero(rho > 1.0)
    link = int(above[-1]) + 1 if above.size else int(np.argmax(rho)) + 1
    loaded = rho ** sharpness / (1.0 + rho ** sharpness)
    beyond = np.append(np.cumprod((1.0 - loaded)[::-1])[::-1][1:], 1.0)
    scores = loaded * beyond
    nothing = float(np.prod(1.0 - loaded))
    total = scores.sum() + nothing
    probabilities = scores / total
    return Bunch(link=link, group=link_group(link, n), confidence=float(probabilities[link - 1]),
                 probabilities=probabilities, no_contact=nothing / total, significance=rho)
