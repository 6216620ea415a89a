"""ROS 1 and ROS 2 dialects of rosbridge JSON (rosbridge.md §3).

A server speaks one dialect, chosen at start:

* ROS 1: type names ``pkg/Type``, time ``{"secs", "nsecs"}``, ``Header`` with ``seq``;
* ROS 2: type names ``pkg/msg/Type`` (``pkg/srv/Type``, ``pkg/action/Type``), time
  ``{"sec", "nanosec"}``, no ``seq``.

On input both spellings are accepted (roslibpy writes ``secs``/``nsecs`` even against ROS 2,
rosbridge.md §3), and both type-name forms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from davinci_sim.bridge.rosbridge.msgdefs import ROS2_PACKAGE_ALIASES

Kind = Literal["msg", "srv", "action"]
_KINDS = ("msg", "srv", "action")


class TypeNameError(ValueError):
    """A type name that is not ``pkg/Type`` or ``pkg/{msg,srv,action}/Type``."""


def split_type(name: str) -> tuple[str, Kind | None]:
    """``("pkg/Type", kind)`` from any spelling; ``kind`` is None for the short form.

    Raises:
        TypeNameError: for anything else (empty parts, too many slashes, not a string).
    """
    if not isinstance(name, str):
        raise TypeNameError(f"a type name must be a string, got {name!r}")
    parts = name.strip("/").split("/")
    if len(parts) == 2 and all(parts):
        pkg, typ = parts
        kind = None
    elif len(parts) == 3 and all(parts) and parts[1] in _KINDS:
        pkg, kind, typ = parts
    else:
        raise TypeNameError(
            f"bad type name {name!r}: expected 'pkg/Type' or 'pkg/msg/Type' (or srv, action)"
        )
    pkg = ROS2_PACKAGE_ALIASES.get(pkg, pkg)
    return f"{pkg}/{typ}", kind  # type: ignore[return-value]


@dataclass(frozen=True)
class Dialect:
    """One ROS dialect of the rosbridge JSON."""

    ros_version: Literal[1, 2]

    def __post_init__(self) -> None:
        if self.ros_version not in (1, 2):
            raise ValueError(f"ros_version must be 1 or 2, got {self.ros_version!r}")

    @property
    def sec_key(self) -> str:
        return "secs" if self.ros_version == 1 else "sec"

    @property
    def nsec_key(self) -> str:
        return "nsecs" if self.ros_version == 1 else "nanosec"

    def type_name(self, canonical: str, kind: Kind = "msg") -> str:
        """The wire name of a canonical ``pkg/Type``."""
        if self.ros_version == 1:
            return canonical
        pkg, typ = canonical.split("/")
        if pkg == "rosapi":
            pkg = "rosapi_msgs"
        return f"{pkg}/{kind}/{typ}"

    def stamp(self, t: float) -> dict[str, int]:
        """A ROS time from seconds (negative or non-finite times become 0)."""
        if not (t > 0.0) or not math.isfinite(t):
            return {self.sec_key: 0, self.nsec_key: 0}
        sec = int(t)
        nsec = int(round((t - sec) * 1e9))
        if nsec >= 1_000_000_000:
            sec, nsec = sec + 1, nsec - 1_000_000_000
        return {self.sec_key: sec, self.nsec_key: nsec}

    def header(self, t: float, frame_id: str = "", seq: int = 0) -> dict:
        """A ``std_msgs/Header``."""
        if self.ros_version == 1:
            return {"seq": seq, "stamp": self.stamp(t), "frame_id": frame_id}
        return {"stamp": self.stamp(t), "frame_id": frame_id}

    @staticmethod
    def time_to_sec(stamp: dict) -> float:
        """Seconds from a time in either spelling (already validated)."""
        sec = stamp.get("sec", stamp.get("secs", 0))
        nsec = stamp.get("nanosec", stamp.get("nsecs", 0))
        return float(sec) + 1e-9 * float(nsec)


ROS1 = Dialect(1)
ROS2 = Dialect(2)


def dialect(ros_version: int) -> Dialect:
    """The dialect of ``ros_version`` (1 or 2)."""
    if ros_version == 1:
        return ROS1
    if ros_version == 2:
        return ROS2
    raise ValueError(f"ros_version must be 1 or 2, got {ros_version!r}")
