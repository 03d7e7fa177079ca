"""Choice of the support set D_SDP on which the GP posterior is computed.

The paper (Sec. V-A) fits on 80,000 samples but conditions the GP on a
subset of 5,000 of them; this module chooses that subset.
"""

import numpy as np

SUPPORT_SELECTIONS = ("random", "greedy")
#: Support rows of ``n_support="auto"``: the GP is conditioned on at most this
#: many rows, so the posterior factor stays ~32 MB per output (2,000^2 floats)
#: and the hyperparameters go to minibatch Adam for the paper's SP_P
#: (``resolve_optimizer``), whatever the number of training rows.
AUTO_SUPPORT = 2000


def resolve_n_support(n_support, n_samples):
    """The number of support rows ``n_support`` stands for.

    Parameters
    ----------
    n_support : int, "auto" or None
        None keeps every row (an exact GP); "auto" keeps
        ``min(n_samples, AUTO_SUPPORT)`` rows; an int keeps
        ``min(n_samples, n_support)``.
    n_samples : int
        Number of training rows.

    Returns
    -------
    n_support : int

    Examples
    --------
    >>> resolve_n_support("auto", 500), resolve_n_support("auto", 41707)
    (500, 2000)
    >>> resolve_n_support(None, 41707), resolve_n_support(5000, 3000)
    (41707, 3000)
    """
    if n_support is None:
        return n_samples
    if isinstance(n_support, str) and n_support == "auto":
        return min(n_samples, AUTO_SUPPORT)
    return min(n_samples, n_support)


def select_support(kernel, X, n_support, method, rng):
    """Indices of the ``n_support`` training rows the GP is conditioned on.

    Parameters
    ----------
    kernel : Kernel
        Kernel defining the metric of the ``"greedy"`` rule.
    X : ndarray of shape (n_samples, n_features)
        Training inputs.
    n_support : int or None
        Size of the support set; None, or a value >= n_samples, keeps all rows.
    method : {"random", "greedy"}
        ``"random"``: uniform sample without replacement.
        ``"greedy"``: farthest-point traversal in the kernel metric

        .. math::

            d(x, x')^2 = k(x, x) + k(x', x') - 2 k(x, x'),

        starting from a row drawn with ``rng`` and repeatedly adding the row
        farthest from the rows already chosen. It spreads the support over
        the input space as the kernel sees it (in particular over moving and
        resting samples when the kernel is gated) and costs
        ``n_support`` kernel evaluations of shape ``(n_samples, 1)`` and
        O(n_samples) memory.
    rng : numpy.random.RandomState
        Random generator.

    Returns
    -------
    support : ndarray of shape (n_support,)
        Sorted row indices.
    """
    n = X.shape[0]
    if n_support is None or n_support >= n:
        return np.arange(n)
    if method == "random":
        return np.sort(rng.choice(n, size=n_support, replace=False))
    return np.sort(_farthest_points(kernel, X, n_support, rng.randint(n)))


def _farthest_points(kernel, X, n_support, first):
    """Greedy farthest-point traversal in the metric induced by ``kernel``."""
    diag = kernel.diag(X)
    chosen = [first]
    dist2 = np.full(X.shape[0], np.inf)
    for _ in range(n_support - 1):
        i = chosen[-1]
        k_i = kernel(X, X[i : i + 1])[:, 0]
        np.minimum(dist2, diag + diag[i] - 2.0 * k_i, out=dist2)
        dist2[i] = -np.inf  # stays -inf: chosen rows are never re-picked
        chosen.append(int(np.argmax(dist2)))
    return np.asarray(chosen)
