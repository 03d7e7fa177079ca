"""Where the nominal model is wrong: the residual broken down.

The residual :math:`r_\\ell = i_\\ell - \\hat i_\\ell` (measured minus
reference current) is summarised per joint

* by **regime** (:func:`sklearn_gpcd.features.regimes`: ``rest``,
  ``creep``, ``moving``, ``braking``, ``reversal``),
* by **configuration region**: quantile bins of the joint's own position,
* by **time**: equal-length windows of each recording,

as the RMS residual and the share of the residual sum of squares in each
cell (compare with the share of samples: a regime holding 10 % of the
samples and 60 % of the squared error is where physics is missing).
"""

from dataclasses import dataclass

import numpy as np

from .._gate import DEFAULT_SIGMA_V
from ..features import REGIMES, regimes


@dataclass
class ResidualBreakdown:
    """Residual statistics by joint, regime, configuration region and time.

    Attributes
    ----------
    rms : ndarray of shape (n_joints,)
        RMS residual of each joint over all samples.
    rms_moving : ndarray of shape (n_joints,)
        RMS residual while the joint moves (``|qd| >= sigma_rest``).
    regimes : dict
        ``{regime: {"rms": (n_joints,), "share_of_error": (n_joints,),
        "share_of_samples": (n_joints,)}}``.
    regions : list of dict
        Per joint: ``{"edges": (n_regions + 1,), "rms": (n_regions,)}``
        over quantile bins of that joint's position [rad].
    time : list of dict
        Per recording: ``{"name", "centres": (n_bins,) [s], "rms":
        (n_bins, n_joints)}``.
    units : str
        Unit of the residual (``"A"`` or ``"Nm"``).

    Examples
    --------
    A residual only while joint 4 rests is found there by :meth:`worst`:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import NominalModel, Signals, residual_breakdown
    >>> rng = np.random.default_rng(0)
    >>> X = np.hstack([rng.normal(size=(200, 6)), rng.normal(size=(200, 6)),
    ...                np.zeros((200, 6))])
    >>> X[:50, 6 + 4] = 0.0  # joint 4 at rest for 50 samples
    >>> residual = np.zeros((200, 6))
    >>> residual[:50, 4] = 0.5
    >>> breakdown = residual_breakdown(Signals.from_states(NominalModel("ur10"), X), residual)
    >>> breakdown.n_joints, breakdown.worst()
    (6, (4, 'rest'))
    >>> round(float(breakdown.rms[4]), 3)
    0.25
    """

    rms: np.ndarray
    rms_moving: np.ndarray
    regimes: dict
    regions: list
    time: list
    units: str = "A"

    @property
    def n_joints(self):
        """Number of joints."""
        return self.rms.shape[0]

    def worst(self):
        """``(joint, regime)`` with the largest share of the squared error above its sample share.

        Returns
        -------
        joint : int
        regime : str
        """
        best, where = -np.inf, (int(np.argmax(self.rms)), "moving")
        for regime, cell in self.regimes.items():
            excess = cell["share_of_error"] - cell["share_of_samples"]
            j = int(np.nanargmax(np.where(np.isfinite(excess), excess, -np.inf)))
            if excess[j] > best:
                best, where = excess[j], (j, regime)
        return where

    def to_dict(self):
        """JSON-ready dictionary."""
        def lst(a):
            return [None if not np.isfinite(x) else float(x) for x in np.ravel(a)]

        return {
            "units": self.units,
            "rms": lst(self.rms),
            "rms_moving": lst(self.rms_moving),
            "regimes": {k: {kk: lst(vv) for kk, vv in v.items()} for k, v in self.regimes.items()},
            "regions": [{"edges": lst(r["edges"]), "rms": lst(r["rms"])} for r in self.regions],
            "time": [{"name": t["name"], "centres": lst(t["centres"]),
                      "rms": [lst(row) for row in t["rms"]]} for t in self.time],
        }


def _rms(values):
    return float(np.sqrt(np.mean(values ** 2))) if values.size else np.nan


def residual_breakdown(signals, residual, sigma_v=DEFAULT_SIGMA_V, sigma_rest=1e-3, n_regions=4,
                       n_time_bins=10, units="A"):
    """Break a residual down by joint, regime, configuration region and time.

    Parameters
    ----------
    signals : Signals
        States and time of the samples.
    residual : ndarray of shape (n_samples, n_joints)
        Measured minus predicted current.
    sigma_v : float, default=1e-2
        Quasi-static threshold of :func:`~sklearn_gpcd.features.regimes` [rad/s].
    sigma_rest : float, default=1e-3
        Rest threshold [rad/s].
    n_regions : int, default=4
        Quantile bins of each joint's position.
    n_time_bins : int, default=10
        Windows per recording.
    units : str, default="A"

    Returns
    -------
    breakdown : ResidualBreakdown

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import NominalModel, Signals, residual_breakdown
    >>> rng = np.random.default_rng(0)
    >>> X = np.hstack([rng.normal(size=(200, 6)), rng.normal(size=(200, 6)), np.zeros((200, 6))])
    >>> s = Signals.from_states(NominalModel("ur10"), X)
    >>> b = residual_breakdown(s, 0.1 * rng.normal(size=(200, 6)))
    >>> b.rms.shape, sorted(b.regimes) == sorted(["moving", "creep", "rest",
    ...                                            "braking", "reversal"])
    ((6,), True)
    """
    residual = np.asarray(residual, dtype=float)
    n, J = residual.shape
    labels = np.concatenate([
        regimes(signals.qd[signals.segment == s], signals.qdd[signals.segment == s],
                sigma_v=sigma_v, sigma_rest=sigma_rest)
        for s in np.unique(signals.segment)])
    order = np.concatenate([np.flatnonzero(signals.segment == s)
                            for s in np.unique(signals.segment)])
    lab = np.empty_like(labels)
    lab[order] = labels
    sq = residual ** 2
    total = sq.sum(axis=0)
    cells = {}
    for regime in REGIMES:
        inside = lab == regime
        cells[regime] = {
            "rms": np.array([_rms(residual[inside[:, j], j]) for j in range(J)]),
            "share_of_error": np.where(
                total > 0, (sq * inside).sum(0) / np.where(total > 0, total, 1), np.nan),
            "share_of_samples": inside.mean(axis=0),
        }
    regions = []
    for j in range(J):
        edges = np.unique(np.quantile(signals.q[:, j], np.linspace(0, 1, n_regions + 1)))
        if edges.size < 2:
            edges = np.array([signals.q[0, j] - 1e-9, signals.q[0, j] + 1e-9])
        idx = np.clip(np.searchsorted(edges, signals.q[:, j], side="right") - 1, 0, edges.size - 2)
        regions.append({"edges": edges,
                        "rms": np.array([_rms(residual[idx == b, j])
                                         for b in range(edges.size - 1)])})
    windows = []
    for s in np.unique(signals.segment):
        rows = np.flatnonzero(signals.segment == s)
        t = signals.time[rows] if signals.time is not None else np.arange(rows.size, dtype=float)
        edges = np.linspace(t[0], t[-1], n_time_bins + 1)
        idx = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, n_time_bins - 1)
        rms = np.array([[_rms(residual[rows[idx == b], j]) for j in range(J)]
                        for b in range(n_time_bins)])
        name = signals.names[s] if s < len(signals.names) else f"recording {s}"
        windows.append({"name": name, "centres": 0.5 * (edges[1:] + edges[:-1]), "rms": rms})
    moving = np.abs(signals.qd) >= sigma_rest
    return ResidualBreakdown(
        rms=np.array([_rms(residual[:, j]) for j in range(J)]),
        rms_moving=np.array([_rms(residual[moving[:, j], j]) for j in range(J)]),
        regimes=cells, regions=regions, time=windows, units=units)
