"""Column layout of the model inputs, shared by every layer.

The paper's inputs for an ``n``-joint robot are stacked joint-major blocks

    x   = [q, qd, qdd]                          (Sec. IV-A, 3 n columns)
    x^a = [q, qd, qdd, e_q, de_q, i_c]          (Eq. 13, 6 n columns)

so that column ``block * n + joint`` holds signal ``block`` of joint ``joint``
(0-based). Names follow the same scheme: ``"q_0"``, ``"qd_3"``, ``"i_c_5"``.
Every layer reads its columns through this module (it imports nothing of the
package).

Examples
--------
>>> from sklearn_gpcd.layout import column_index, column_names
>>> column_names(1)
['q_0', 'qd_0', 'qdd_0', 'e_q_0', 'de_q_0', 'i_c_0']
>>> column_index("i_c", 0, n_joints=1)
5
"""

__all__ = [
    "STATE_BLOCKS",
    "AUGMENTED_BLOCKS",
    "column_names",
    "column_index",
    "block_columns",
    "state_columns",
]

#: Blocks of the state inputs ``x = [q, qd, qdd]`` (Sec. IV-A).
STATE_BLOCKS = ("q", "qd", "qdd")
#: Blocks of the augmented inputs ``x^a`` (Eq. 13).
AUGMENTED_BLOCKS = STATE_BLOCKS + ("e_q", "de_q", "i_c")


def column_names(n_joints, augmented=True):
    """Names of the input columns, joint-major within each block.

    Parameters
    ----------
    n_joints : int
        Number of robot joints.
    augmented : bool, default=True
        Include the augmented blocks ``e_q``, ``de_q``, ``i_c`` (Eq. 13).

    Returns
    -------
    names : list of str

    Examples
    --------
    >>> column_names(2, augmented=False)
    ['q_0', 'q_1', 'qd_0', 'qd_1', 'qdd_0', 'qdd_1']
    """
    blocks = AUGMENTED_BLOCKS if augmented else STATE_BLOCKS
    return [f"{b}_{j}" for b in blocks for j in range(n_joints)]


def column_index(block, joint, n_joints):
    """Index of signal ``block`` of joint ``joint`` in the layout.

    Parameters
    ----------
    block : str
        One of :data:`AUGMENTED_BLOCKS`, e.g. ``"qd"``.
    joint : int
        Joint (0-based).
    n_joints : int
        Number of robot joints.

    Returns
    -------
    index : int
        ``block_position * n_joints + joint``.

    Examples
    --------
    >>> column_index("qd", 1, 6)
    7
    """
    return AUGMENTED_BLOCKS.index(block) * n_joints + joint


def block_columns(block, n_joints):
    """Indices of all joints' columns of one block.

    Parameters
    ----------
    block : str
        One of :data:`AUGMENTED_BLOCKS`.
    n_joints : int
        Number of robot joints.

    Returns
    -------
    indices : list of int

    Examples
    --------
    >>> block_columns("qdd", 2)
    [4, 5]
    """
    start = AUGMENTED_BLOCKS.index(block) * n_joints
    return list(range(start, start + n_joints))


def state_columns(n_joints):
    """Indices of ``x = [q, qd, qdd]`` inside either layout.

    Parameters
    ----------
    n_joints : int
        Number of robot joints.

    Returns
    -------
    indices : list of int
        The first ``3 * n_joints`` columns.

    Examples
    --------
    >>> state_columns(1)
    [0, 1, 2]
    """
    return list(range(3 * n_joints))
