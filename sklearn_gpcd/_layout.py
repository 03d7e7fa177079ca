"""Column layout of the model inputs, shared by every layer.

The paper's inputs for an ``n``-joint robot are stacked joint-major blocks

    x   = [q, qd, qdd]                          (Sec. IV-A, 3 n columns)
    x^a = [q, qd, qdd, e_q, de_q, i_c]          (Eq. 13, 6 n columns)

so that column ``block * n + joint`` holds signal ``block`` of joint ``joint``
(0-based). Names follow the same scheme: ``"q_0"``, ``"qd_3"``, ``"i_c_5"``.
"""

STATE_BLOCKS = ("q", "qd", "qdd")
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

    Examples
    --------
    >>> column_index("qd", 1, 6)
    7
    """
    return AUGMENTED_BLOCKS.index(block) * n_joints + joint


def block_columns(block, n_joints):
    """Indices of all joints' columns of one block.

    Examples
    --------
    >>> block_columns("qdd", 2)
    [4, 5]
    """
    start = AUGMENTED_BLOCKS.index(block) * n_joints
    return list(range(start, start + n_joints))


def state_columns(n_joints):
    """Indices of ``x = [q, qd, qdd]`` inside either layout.

    Examples
    --------
    >>> state_columns(1)
    [0, 1, 2]
    """
    return list(range(3 * n_joints))
