"""Base (identifiable) parameters by QR decomposition with column pivoting.

Stacking the torque features over many random states gives
:math:`W \\in \\mathbb{R}^{N \\times p}` with :math:`W\\pi = \\tau`. Some
columns are zero or linear combinations of others for *every* state (e.g. a
link's inertia about an axis it never rotates about), so :math:`\\pi` is not
identifiable. With the pivoted QR :math:`W P = Q R`, the first ``r`` pivots
(``|R_ii| > tol``) are independent columns :math:`W_b` and the others satisfy
:math:`W_d = W_b B` with :math:`B = R_{11}^{-1} R_{12}`. Hence

.. math::

    W\\pi = W_b \\beta, \\qquad \\beta = \\pi_b + B\\,\\pi_d = K\\pi,

the base parameters (Gautier & Khalil's numerical method).
"""

import numpy as np
from scipy.linalg import qr, solve_triangular


def base_parameters(W, rank_tol=None):
    """Independent columns of stacked torque features and the map to base parameters.

    Parameters
    ----------
    W : ndarray of shape (n_rows, n_parameters)
        Regressor stacked over enough random states to reveal every
        structural dependency.
    rank_tol : float, default=None
        Relative tolerance: column pivot ``i`` counts as independent when
        :math:`|R_{ii}| > \\text{rank\\_tol} \\cdot |R_{00}|`. ``None`` means
        ``max(W.shape) * eps`` (as in ``numpy.linalg.matrix_rank``).

    Returns
    -------
    info : dict
        ``indices`` (ndarray of int, sorted): independent columns of ``W``;
        ``dependent`` (ndarray of int): the others;
        ``mapping`` (ndarray of shape (rank, n_parameters)): ``K`` with
        ``W[:, indices] @ (K @ pi) == W @ pi``;
        ``rank`` (int); ``tol`` (float): the absolute threshold on ``|R_ii|``.

    Examples
    --------
    >>> import numpy as np
    >>> W = np.array([[1.0, 2.0, 0.0], [3.0, 6.0, 1.0], [0.0, 0.0, 5.0]])
    >>> info = base_parameters(W)
    >>> info["indices"].tolist(), info["rank"]
    ([1, 2], 2)
    >>> info["mapping"].round(3).tolist()
    [[0.5, 1.0, 0.0], [0.0, 0.0, 1.0]]
    """
    W = np.asarray(W, dtype=float)
    if W.ndim != 2 or W.size == 0:
        raise ValueError(f"W must be a non-empty 2-D array, got shape {W.shape}")
    if not np.all(np.isfinite(W)):
        raise ValueError("W contains NaN or inf")
    _, R, perm = qr(W, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    rel = max(W.shape) * np.finfo(float).eps if rank_tol is None else float(rank_tol)
    tol = rel * diag[0] if diag.size else 0.0
    rank = int(np.sum(diag > tol))
    # B in pivot order: rows follow perm[:rank], columns perm[rank:]
    B = solve_triangular(R[:rank, :rank], R[:rank, rank:])
    p = W.shape[1]
    K = np.zeros((rank, p))
    K[np.arange(rank), perm[:rank]] = 1.0
    K[:, perm[rank:]] = B
    order = np.argsort(perm[:rank])
    return {
        "indices": perm[:rank][order],
        "dependent": np.sort(perm[rank:]),
        "mapping": K[order],
        "rank": rank,
        "tol": float(tol),
    }
