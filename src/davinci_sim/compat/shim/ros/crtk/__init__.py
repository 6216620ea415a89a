"""crtk_python's ``crtk`` API for scripts run against davinci-sim (``davinci-sim run``).

The implementation is :mod:`davinci_sim.compat` (``ral``, ``crtk_utils``); see there.
"""

from davinci_sim.compat.crtk_utils import joystick_button, utils, wait_move_handle
from davinci_sim.compat.ral import ral

from .msg_conversions import (
    ArrayFromTwistMsg,
    ArrayFromWrenchMsg,
    ArrayToTwistMsg,
    ArrayToWrenchMsg,
    FrameFromPoseMsg,
    FrameFromTransformMsg,
    FrameToPoseMsg,
    FrameToTransformMsg,
)

__all__ = [
    "ArrayFromTwistMsg",
    "ArrayFromWrenchMsg",
    "ArrayToTwistMsg",
    "ArrayToWrenchMsg",
    "FrameFromPoseMsg",
    "FrameFromTransformMsg",
    "FrameToPoseMsg",
    "FrameToTransformMsg",
    "joystick_button",
    "ral",
    "utils",
    "wait_move_handle",
]
