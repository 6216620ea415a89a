"""The skill exercises beyond the seed's path (issue 12's curriculum), registered as task
kinds when imported (:func:`davinci_sim.tasks.base.task_kinds` imports this module):

* ``camera_targeting`` — :class:`~davinci_sim.tasks.camera_targeting.CameraTargetingTask`;
* ``ring_walk`` — :class:`~davinci_sim.tasks.ring_walk.RingWalkTask`;
* ``needle_targeting`` — :class:`~davinci_sim.tasks.needle_targeting.NeedleTargetingTask`;
* ``needle_pickup`` — :class:`~davinci_sim.tasks.needle_pickup.NeedlePickupTask`;
* ``needle_drive`` — :class:`~davinci_sim.tasks.needle_drive.NeedleDriveTask` (needle
  driving and the running suture).
"""

from davinci_sim.tasks.camera_targeting import CameraTargetingTask
from davinci_sim.tasks.needle_drive import NeedleDriveTask
from davinci_sim.tasks.needle_pickup import NeedlePickupTask
from davinci_sim.tasks.needle_targeting import NeedleTargetingTask
from davinci_sim.tasks.ring_walk import RingWalkTask

__all__ = [
    "CameraTargetingTask",
    "NeedleDriveTask",
    "NeedlePickupTask",
    "NeedleTargetingTask",
    "RingWalkTask",
]
