"""Robot recordings: one :class:`Recording` type, readers and writers."""

from .recording import JOINT_SIGNALS, Recording

__all__ = ["JOINT_SIGNALS", "Recording"]
