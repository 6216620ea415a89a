"""``geometry_msgs.msg`` for davinci-sim scripts, used only when ROS's is not installed:
ROS 2-style classes made from the bridge's definitions (:mod:`davinci_sim.compat.msgs`)."""

from davinci_sim.compat.msgs import export

__all__ = export(globals(), "geometry_msgs")
