"""Isolation on the 2020 UR10e collision files: which significance measure, and its limit.

Question (issue 36, acceptance: 90 % of the detected labelled collisions of
``collision_detection_data_2020`` attributed to the right link group: link 2,
link 3, wrist 4-6). The package rule (``isolate_contact``) measures each
joint against its *alarm threshold*; on the wrist joints 4-6 stay at
0.1-0.35 of theirs. Here: other significance measures, and the measurement
of what the residuals carry.

**Split, declared before any per-event figure of this study was looked at.**
The labelled events of each file are taken in time order
(``benchmarks/labels/ur10e_events.json``); the first ``ceil(n / 2)`` of each
file are the *development* events (2link 1-4, 3link 1-6, wrist 1-4: 14
events), the others the *score* events (2link 5-7, 3link 7-11, wrist 5-7:
11 events). Every choice of this study (statistic, noise estimate, cut,
candidate set) is made on the development events only; the score events
are reported with the choice frozen, and the overall figure beside. (The
previous session's per-event table showed |m| / threshold of all events:
the project has seen them, this study's choices have not.)

Data: the real benchmark's training runs (observer identified there, as
``benchmarks/real_ur10e.py`` does), the collision files and
``collision_free.csv`` read in place; calibration pool of each file as the
benchmark's (``family_calibration``: ``collision_free.csv`` plus the
event-free segments of the two other files).

Run::

    python studies/isolation_2020.py [--data DIR]
"""

import math

#: Events of each file used for development: the first ceil(n / 2) in time order.
def development_count(n_events):
    """How many of a file's events (time order) are development events.

    >>> [development_count(n) for n in (7, 11, 7)]
    [4, 6, 4]
    """
    return math.ceil(n_events / 2)
