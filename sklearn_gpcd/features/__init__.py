"""From recordings to GP inputs: derivatives, input matrices, quasi-static masks.

* :mod:`~sklearn_gpcd.features.differentiation` -- filtered derivatives of
  irregularly sampled signals (:func:`differentiate`, :func:`lowpass`).
* :mod:`~sklearn_gpcd.features.inputs` -- the inputs :math:`x` and
  :math:`x^a` (Eq. 13) as a transformer (:class:`InverseDynamicsFeatures`),
  the currents :func:`targets`, and :func:`make_inputs`.
* :mod:`~sklearn_gpcd.features.online` -- the same inputs computed causally,
  one raw sample at a time (:class:`CausalFeatures`, :class:`OnlineFeatures`):
  what runs on the robot.
* :mod:`~sklearn_gpcd.features.masks` -- the quasi-static gate of Eq. 15
  (:func:`quasi_static_mask`), motion :func:`regimes` and
  :func:`contiguous_segments`.
"""

from .differentiation import METHODS, differentiate, lowpass
from .inputs import (
    ACCELERATION_SOURCES,
    SIGN_CONVENTIONS,
    InverseDynamicsFeatures,
    MissingSignalWarning,
    make_inputs,
    targets,
)
from .online import CausalFeatures, OnlineFeatures
from .masks import REGIMES, contiguous_segments, quasi_static_mask, regimes

__all__ = [
    "ACCELERATION_SOURCES",
    "CausalFeatures",
    "InverseDynamicsFeatures",
    "METHODS",
    "MissingSignalWarning",
    "OnlineFeatures",
    "REGIMES",
    "SIGN_CONVENTIONS",
    "contiguous_segments",
    "differentiate",
    "lowpass",
    "make_inputs",
    "quasi_static_mask",
    "regimes",
    "targets",
]
