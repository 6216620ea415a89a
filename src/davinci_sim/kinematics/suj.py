"""The setup-joint (SUJ) frame chain of the patient cart (dvrk.md 1.6).

Frames: ``cart`` (SUJ world origin), each arm's RCM (its chain base), the camera = ECM tip.

* ``T_cart_rcm = world_origin_to_SUJ · DH_SUJ(q_suj) · SUJ_tip_to_tool_origin`` per arm.
* The reference arm (ECM by default) gets ``T_cart_rcm`` as its base frame, so
  ``ECM/measured_cp`` is the camera tip in the cart frame.
* Every other arm gets ``inv(T_cart_refrcm · T_refrcm_reftip) · T_cart_rcm``: its RCM in the
  camera frame, so ``PSMx/measured_cp`` is the PSM tip seen from the camera.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from davinci_sim.geometry.se3 import invert_transform
from davinci_sim.kinematics.arms import SUJArmKinematics, load_arm, load_suj
from davinci_sim.kinematics.fk import forward_kinematics


def T_cart_rcm(suj_arm: SUJArmKinematics, q_suj) -> np.ndarray:
    """RCM (arm base) of the arm carried by ``suj_arm`` in the cart frame, (4, 4), m.

    ``q_suj``: SUJ joints J0…J5 (m for J0, rad for J1-J5), shape (6,) or (..., 6).
    """
    T_sujbase_sujtip = forward_kinematics(suj_arm.chain, q_suj)
    return suj_arm.T_cart_sujbase @ T_sujbase_sujtip @ suj_arm.T_sujtip_rcm


def _frozen(T: np.ndarray) -> np.ndarray:
    T = np.array(T, dtype=float)
    T.setflags(write=False)
    return T


@dataclass(frozen=True, eq=False)
class CartFrames:
    """All frames the SUJ chain produces for one set of joint values (m, read-only arrays)."""

    reference_arm: str
    """The arm whose tip is the camera (``ECM`` unless changed)."""
    T_cart_rcm: Mapping[str, np.ndarray]
    """RCM of every arm in the cart frame (the SUJ ``local/measured_cp``)."""
    T_cart_camera: np.ndarray
    """Tip of the reference arm (camera) in the cart frame."""
    base_frames: Mapping[str, np.ndarray]
    """Base frame pushed to every arm: ``T_cart_rcm`` for the reference arm, the RCM in the
    camera frame (``T_camera_rcm``) for the others."""


def cart_frames(
    q_suj: Mapping[str, np.ndarray] | None = None,
    q_reference=None,
    *,
    reference_arm: str = "ECM",
    suj: Mapping[str, SUJArmKinematics] | None = None,
) -> CartFrames:
    """Compute :class:`CartFrames` (dvrk.md 1.6).

    Args:
        q_suj: SUJ joints per arm name (``ECM``, ``PSM1``…); missing arms use their
            ``simulated_position``. None = all simulated positions.
        q_reference: joints of the reference arm (rad / m); None = its home pose
            (ECM: (0, 0, 0.12, 0), dvrk.md 1.7).
        reference_arm: the arm whose tip is the camera frame (dVRK ``reference_arm``).
        suj: the SUJ arms; None = :func:`~davinci_sim.kinematics.arms.load_suj`.

    Raises:
        KeyError: unknown arm names.
    """
    suj = load_suj() if suj is None else suj
    q_suj = {} if q_suj is None else q_suj
    unknown = set(q_suj) - set(suj)
    if unknown or reference_arm not in suj:
        bad = sorted(unknown) if unknown else [reference_arm]
        raise KeyError(f"unknown SUJ arm(s) {bad}; known: {sorted(suj)}")
    rcm = {
        name: _frozen(T_cart_rcm(arm, q_suj.get(name, arm.simulated_position)))
        for name, arm in suj.items()
    }
    ref_kin = load_arm(reference_arm)
    q_ref = ref_kin.home if q_reference is None else q_reference
    T_cart_camera = _frozen(rcm[reference_arm] @ forward_kinematics(ref_kin.chain, q_ref))
    T_camera_cart = invert_transform(T_cart_camera)
    base = {
        name: T if name == reference_arm else _frozen(T_camera_cart @ T) for name, T in rcm.items()
    }
    return CartFrames(
        reference_arm=reference_arm,
        T_cart_rcm=MappingProxyType(rcm),
        T_cart_camera=T_cart_camera,
        base_frames=MappingProxyType(base),
    )
