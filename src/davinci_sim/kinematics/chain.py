"""DH chains as the dVRK (cisst ``robManipulator``) defines them.

Reference: ``dvrk.md`` section 1.1. A chain is a tuple of :class:`DHJoint` in one
convention plus a constant tool transform (the dVRK ``tooltip_offset``). Joint values
are in rad (revolute) or m (prismatic); lengths in m.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from typing import Literal

import numpy as np

Convention = Literal["modified", "standard"]
JointType = Literal["revolute", "prismatic"]


@dataclass(frozen=True)
class DHJoint:
    """One joint/link of a DH chain (dVRK JSON fields, dvrk.md section 1.1)."""

    name: str
    joint_type: JointType
    alpha: float
    a: float
    theta: float
    d: float
    offset: float
    qmin: float
    qmax: float
    ftmax: float = np.inf
    """Maximum joint effort, N·m (revolute) or N (prismatic)."""

    @property
    def is_revolute(self) -> bool:
        return self.joint_type == "revolute"


@dataclass(frozen=True, eq=False)
class DHChain:
    """A serial chain: ``T_base_tip = link_1 · … · link_n · T_last_tip``.

    ``T_last_tip`` is the dVRK ``tooltip_offset`` (identity for MTMs and SUJ arms).
    """

    name: str
    convention: Convention
    joints: tuple[DHJoint, ...]
    T_last_tip: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if self.convention not in ("modified", "standard"):
            raise ValueError(f"unknown DH convention {self.convention!r}")
        T = np.array(self.T_last_tip, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"T_last_tip must be 4x4, got shape {T.shape}")
        T.setflags(write=False)
        object.__setattr__(self, "T_last_tip", T)
        # Per-joint parameter arrays used by the vectorised FK.
        params = {
            "alpha": np.array([j.alpha for j in self.joints]),
            "a": np.array([j.a for j in self.joints]),
            "theta": np.array([j.theta for j in self.joints]),
            "d": np.array([j.d for j in self.joints]),
            "offset": np.array([j.offset for j in self.joints]),
            "revolute": np.array([j.is_revolute for j in self.joints]),
        }
        for v in params.values():
            v.setflags(write=False)
        object.__setattr__(self, "_params", params)

    @property
    def dof(self) -> int:
        return len(self.joints)

    @cached_property
    def joint_names(self) -> tuple[str, ...]:
        # Cached: every joint state the simulator publishes carries it (snapshots at 1 kHz).
        return tuple(j.name for j in self.joints)

    @property
    def qmin(self) -> np.ndarray:
        return np.array([j.qmin for j in self.joints])

    @property
    def qmax(self) -> np.ndarray:
        return np.array([j.qmax for j in self.joints])

    @property
    def ftmax(self) -> np.ndarray:
        return np.array([j.ftmax for j in self.joints])

    @property
    def revolute(self) -> np.ndarray:
        return self._params["revolute"]  # type: ignore[attr-defined]

    def truncated(self, n_links: int, *, with_tool: bool = False) -> DHChain:
        """The first ``n_links`` links (tool transform kept only if asked and n_links = dof)."""
        if not 0 <= n_links <= self.dof:
            raise ValueError(f"n_links must be in [0, {self.dof}], got {n_links}")
        T = self.T_last_tip if (with_tool and n_links == self.dof) else np.eye(4)
        return DHChain(f"{self.name}[:{n_links}]", self.convention, self.joints[:n_links], T)


def _joint_from_json(j: dict) -> DHJoint:
    return DHJoint(
        name=j["name"],
        joint_type=j["type"],
        alpha=float(j["alpha"]),
        a=float(j["a"]),
        theta=float(j.get("theta", 0.0)),
        d=float(j["d"]),
        offset=float(j.get("offset", 0.0)),
        qmin=float(j["qmin"]),
        qmax=float(j["qmax"]),
        ftmax=float(j.get("ftmax", np.inf)),
    )


def chain_from_json(data: dict, name: str | None = None) -> DHChain:
    """Build a chain from a dVRK-style JSON object.

    Keys: ``convention``, ``joints`` (or ``links``), optional ``tooltip_offset``.
    """
    return DHChain(
        name=name or data.get("name", "chain"),
        convention=data["convention"],
        joints=tuple(_joint_from_json(j) for j in data.get("joints", data.get("links", []))),
        T_last_tip=np.array(data.get("tooltip_offset", np.eye(4)), dtype=float),
    )


def load_data(filename: str) -> dict:
    """Read one of the JSON data files shipped in ``davinci_sim/kinematics/data``."""
    text = resources.files("davinci_sim.kinematics").joinpath("data").joinpath(filename).read_text()
    return json.loads(text)
