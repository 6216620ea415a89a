"""The dVRK arm types shipped with davinci-sim, loaded from ``kinematics/data/*.json``.

Each file carries the dVRK numbers for one arm type (DH chain, tool, jaw/gripper, limits,
home pose, trajectory limits); the section of ``dvrk.md`` each number comes from is named in
the file's ``source`` and ``notes`` fields.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Literal

import numpy as np

from davinci_sim.kinematics.chain import DHChain, chain_from_json, load_data

ArmType = Literal["PSM", "ECM", "MTM"]

#: Arm name -> data file. PSM1-3 share one type, as do the two MTMs' DH (limits differ).
ARM_FILES: dict[str, str] = {
    "PSM1": "psm_classic_large_needle_driver_400006.json",
    "PSM2": "psm_classic_large_needle_driver_400006.json",
    "PSM3": "psm_classic_large_needle_driver_400006.json",
    "ECM": "ecm_classic_straight.json",
    "MTML": "mtml.json",
    "MTMR": "mtmr.json",
}
SUJ_FILE = "suj_classic.json"


def _frozen(a) -> np.ndarray:
    arr = np.array(a, dtype=float)
    arr.setflags(write=False)
    return arr


def _transform(rotation, translation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.array(rotation, dtype=float)
    T[:3, 3] = np.array(translation, dtype=float)
    T.setflags(write=False)
    return T


@dataclass(frozen=True, eq=False)
class GripperSpec:
    """A 1-DOF jaw (PSM) or gripper (MTM): name, range in rad, max effort."""

    name: str
    qmin: float
    qmax: float
    ftmax: float = np.inf


@dataclass(frozen=True, eq=False)
class ArmKinematics:
    """Everything kinematic about one arm type, in dVRK units (m, rad, s)."""

    arm_type: ArmType
    chain: DHChain
    home: np.ndarray
    """Simulated homing goal (dvrk.md 1.7)."""
    v_max: np.ndarray
    """Trajectory velocity limits per joint (dvrk.md 1.9)."""
    a_max: np.ndarray
    """Trajectory acceleration limits per joint (dvrk.md 1.9)."""
    goal_tolerance: np.ndarray
    jaw: GripperSpec | None = None
    """PSM jaw (dvrk.md 1.2)."""
    gripper: GripperSpec | None = None
    """MTM gripper (dvrk.md 1.5)."""
    jaw_v_max: float = np.inf
    jaw_a_max: float = np.inf
    T_reference_base: np.ndarray | None = None
    """Configured base frame (MTMs: base in HRSV, dvrk.md 1.5); None = identity."""
    reference_frame: str | None = None
    mounting_pitch: float | None = None
    """ECM mounting pitch, rad (dvrk.md 1.4)."""

    @property
    def dof(self) -> int:
        return self.chain.dof


@cache
def load_arm(arm: str) -> ArmKinematics:
    """Kinematics of ``arm`` (``PSM1``, ``PSM2``, ``PSM3``, ``ECM``, ``MTML`` or ``MTMR``)."""
    if arm not in ARM_FILES:
        raise KeyError(f"unknown arm {arm!r}; known arms: {sorted(ARM_FILES)}")
    data = load_data(ARM_FILES[arm])
    chain = chain_from_json(data, name=arm)
    n = chain.dof
    tol = np.broadcast_to(np.asarray(data["goal_tolerance"], dtype=float), (n,))
    jaw = data.get("jaw")
    grip = data.get("gripper")
    base = data.get("base_frame")
    return ArmKinematics(
        arm_type=data["arm_type"],
        chain=chain,
        home=_frozen(data["home"]),
        v_max=_frozen(data["v_max"]),
        a_max=_frozen(data["a_max"]),
        goal_tolerance=_frozen(tol),
        jaw=GripperSpec(**jaw) if jaw else None,
        gripper=GripperSpec(**grip) if grip else None,
        jaw_v_max=float(data.get("jaw_v_max", np.inf)),
        jaw_a_max=float(data.get("jaw_a_max", np.inf)),
        T_reference_base=_transform(base["rotation"], base["translation"]) if base else None,
        reference_frame=base["reference_frame"] if base else None,
        mounting_pitch=data.get("mounting_pitch"),
    )


@dataclass(frozen=True, eq=False)
class SUJArmKinematics:
    """One setup-joint arm (dvrk.md 1.6): ``T_cart_rcm = T_cart_sujbase · DH(q) · T_sujtip_rcm``."""

    name: str
    """The arm it carries: ``ECM``, ``PSM1``, ``PSM2`` or ``PSM3``."""
    plug_number: int
    chain: DHChain
    T_cart_sujbase: np.ndarray
    """``world_origin_to_SUJ``."""
    T_sujtip_rcm: np.ndarray
    """``SUJ_tip_to_tool_origin``."""
    simulated_position: np.ndarray
    """Joint values J0…J5 of the simulated SUJ (m, rad)."""


def suj_joint_names(arm: str) -> list[str]:
    """The dVRK's names of the setup joints carrying ``arm`` (``ECM``, ``PSM1``…):
    ``SUJ_<arm>_J0`` … ``SUJ_<arm>_J5`` (dvrk.md 1.6, section 6)."""
    return [f"SUJ_{arm}_J{i}" for i in range(6)]


@cache
def load_suj() -> dict[str, SUJArmKinematics]:
    """The four SUJ arms of the simulated Classic patient cart, keyed by carried arm."""
    data = load_data(SUJ_FILE)
    out = {}
    for name, a in data["arms"].items():
        chain = chain_from_json(
            {"convention": data["convention"], "joints": a["links"]}, f"SUJ/{name}"
        )
        # The dVRK names the setup joints SUJ_<arm>_J0…J5 on every interface (6 per arm,
        # the ECM's too: MUX_ARRAY_SIZE; dvrk.md 1.6 and section 6): measured_js, topics,
        # and here the model's joints (``SUJ/<arm>/SUJ_<arm>_J0``).
        expected = tuple(suj_joint_names(name))
        if chain.joint_names != expected:
            raise ValueError(f"{SUJ_FILE}: SUJ/{name} joints {chain.joint_names} != {expected}")
        out[name] = SUJArmKinematics(
            name=name,
            plug_number=int(a["plug_number"]),
            chain=chain,
            T_cart_sujbase=_transform(**a["world_origin_to_SUJ"]),
            T_sujtip_rcm=_transform(**a["SUJ_tip_to_tool_origin"]),
            simulated_position=_frozen(a["simulated_position"]),
        )
    return out
