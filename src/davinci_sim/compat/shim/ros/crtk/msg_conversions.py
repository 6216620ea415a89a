"""crtk_python's ``crtk.msg_conversions``: PyKDL and numpy values to and from ROS messages.

The ``…From…Msg`` functions take a message object (``geometry_msgs.msg.Pose`` …), a dict or
a :class:`~davinci_sim.compat.ral.Message`; the ``…To…Msg`` ones return message objects of
:mod:`davinci_sim.compat.msgs`, as crtk_python returns ``geometry_msgs`` messages.
"""

from davinci_sim.compat import crtk_utils as _utils
from davinci_sim.compat import msgs as _msgs
from davinci_sim.compat.crtk_utils import ArrayFromTwistMsg, ArrayFromWrenchMsg, FrameFromPoseMsg
from davinci_sim.compat.ral import to_dict as _to_dict

__all__ = [
    "ArrayFromTwistMsg",
    "ArrayFromWrenchMsg",
    "ArrayToTwistMsg",
    "ArrayToWrenchMsg",
    "FrameFromPoseMsg",
    "FrameFromTransformMsg",
    "FrameToPoseMsg",
    "FrameToTransformMsg",
]


def FrameToPoseMsg(frame):
    """A ``geometry_msgs.msg.Pose`` of a ``PyKDL.Frame``."""
    return _msgs.from_wire("geometry_msgs/Pose", _utils.FrameToPoseMsg(frame))


def FrameFromTransformMsg(transform):
    """A ``PyKDL.Frame`` of a ``geometry_msgs/Transform`` (object or dict)."""
    d = _to_dict(transform)
    return FrameFromPoseMsg({"position": d["translation"], "orientation": d["rotation"]})


def FrameToTransformMsg(frame):
    """A ``geometry_msgs.msg.Transform`` of a ``PyKDL.Frame``."""
    pose = _utils.FrameToPoseMsg(frame)
    fields = {"translation": pose["position"], "rotation": pose["orientation"]}
    return _msgs.from_wire("geometry_msgs/Transform", fields)


def ArrayToTwistMsg(values):
    """A ``geometry_msgs.msg.Twist`` of 6 values (linear, then angular)."""
    return _msgs.from_wire("geometry_msgs/Twist", _utils.ArrayToTwistMsg(values))


def ArrayToWrenchMsg(values):
    """A ``geometry_msgs.msg.Wrench`` of 6 values (force, then torque)."""
    return _msgs.from_wire("geometry_msgs/Wrench", _utils.ArrayToWrenchMsg(values))
