"""After the alarm: which link was hit, and how hard.

* :func:`isolate_contact` -- the link most likely hit during an alarm event,
  from the joint residuals and their thresholds (the most distal joint whose
  residual is significant), with a confidence; :func:`link_group` and
  :data:`LINK_GROUPS` name the groups (link 1, link 2, link 3, wrist);
* :func:`estimate_force` -- the external force at a contact point on that
  link from the joint residual torques through the Jacobian, with its
  uncertainty from the residual's standard deviation and a conditioning
  measure; :func:`contact_point` -- the default point (the link's frame);
* :func:`describe_alarms` -- one row per alarm event of a monitor's output:
  start, stop, link, confidence and force (the table a monitor prints).

This layer reads robots and dynamics only; the residuals come from any
monitor (a GP detector, ``i - i_des`` or the
:class:`~sklearn_gpcd.dynamics.MomentumObserver`).

>>> from sklearn_gpcd.contact import link_group
>>> link_group(4)
'wrist'
"""

from .events import describe_alarms
from .force import contact_point, estimate_force, protected_force
from .isolation import LINK_GROUPS, isolate_contact, link_group

__all__ = ["LINK_GROUPS", "contact_point", "describe_alarms", "estimate_force", "isolate_contact",
           "link_group", "protected_force"]
