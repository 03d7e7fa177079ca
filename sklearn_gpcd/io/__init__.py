"""Robot recordings: one :class:`Recording` type, readers and writers.

================================  ==================================================
:func:`load_recording`            any format, detected from suffix and content
:func:`load_recordings`           many files, folders or glob patterns
:func:`iter_recording_chunks`     one long text recording, chunk by chunk
:func:`read_rtde_csv`             UR RTDE CSV (ur_rtde / UR ``record.py``)
:func:`write_rtde_csv`            the same format, exact float round trip
:func:`read_csv`                  any delimited text through a column map or preset
:func:`read_npz`                  ``.npz`` archives through a key map
:func:`read_value_files`          one value per line, one file per signal (the
                                  Franka Emika Panda logs, preset ``panda_gaz``)
:func:`read_rosbag`               ROS 1 / ROS 2 ``sensor_msgs/JointState`` (optional
                                  ``rosbags`` package)
:class:`RTDEClient`               live UR controller data (RTDE protocol 2);
                                  :class:`LoopbackRTDEServer` replays a recording
                                  (and injects link faults); what can end a
                                  stream: :class:`RTDEProtocolError`,
                                  :class:`MalformedPackage`, :class:`StreamPaused`
:func:`degrees_note`              unit sanity checks of a recording's signals,
:func:`units_note`                as sentences for warnings;
:func:`recording_problems`        all of them (and too short) for a loaded one;
:class:`SignalCheck`              signals against what a model knows, chunk by chunk
                                  (:func:`signal_ranges`, :class:`Finding`)
================================  ==================================================

All readers keep the logged (irregular) sampling, drop malformed rows,
exact duplicates, absurd values, out-of-order time stamps and kinematic
glitches with one :class:`RecordingWarning` per file (row numbers in
``metadata["dropped_rows"]``; the same warning reports gaps in time and
values that look like degrees or milliseconds), and raise ValueError naming
file, column and row for input that cannot be repaired. The user guide page
"Reading UR RTDE, CSV and ROS bag logs" lists every error and warning.
"""

from .plausibility import (
    Finding,
    SignalCheck,
    degrees_note,
    recording_problems,
    signal_ranges,
    units_note,
)
from ._rtde_live import (
    LoopbackRTDEServer,
    MalformedPackage,
    RTDEClient,
    RTDEProtocolError,
    StreamPaused,
)
from ._validation import RecordingWarning
from .chunks import iter_recording_chunks
from .columns import COLUMN_PRESETS, ColumnPreset
from .load import detect_format, load_recording, load_recordings
from .npz import read_npz
from .recording import JOINT_SIGNALS, Recording
from .rosbag import read_rosbag
from .rtde import read_rtde_csv, write_rtde_csv
from .table import read_csv
from .value_files import read_value_files

__all__ = [
    "COLUMN_PRESETS",
    "JOINT_SIGNALS",
    "ColumnPreset",
    "MalformedPackage",
    "RTDEClient",
    "RTDEProtocolError",
    "Recording",
    "RecordingWarning",
    "StreamPaused",
    "Finding",
    "SignalCheck",
    "degrees_note",
    "detect_format",
    "iter_recording_chunks",
    "load_recording",
    "load_recordings",
    "read_csv",
    "read_npz",
    "read_rosbag",
    "read_rtde_csv",
    "read_value_files",
    "recording_problems",
    "signal_ranges",
    "units_note",
    "write_rtde_csv",
]
