"""crtk_python's ``crtk.msg_conversions``: PyKDL and numpy values to and from ROS messages
(here the rosbridge JSON objects); see :mod:`davinci_sim.compat.crtk_utils`."""

from davinci_sim.compat.crtk_utils import (
    ArrayFromTwistMsg,
    ArrayFromWrenchMsg,
    ArrayToTwistMsg,
    ArrayToWrenchMsg,
    FrameFromPoseMsg,
    FrameToPoseMsg,
)

__all__ = [
    "ArrayFromTwistMsg",
    "ArrayFromWrenchMsg",
    "ArrayToTwistMsg",
    "ArrayToWrenchMsg",
    "FrameFromPoseMsg",
    "FrameToPoseMsg",
]
