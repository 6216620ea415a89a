"""The setup-joint (SUJ) frame chain of the patient cart (dvrk.md 1.6).

Frames: ``cart`` (SUJ world origin), each arm's RCM (its chain base), the camera = ECM tip.

* ``T_cart_rcm = world_origin_to_SUJ · DH_SUJ(q_suj) · SUJ_tip_to_tool_origin`` per arm.
* The reference arm (ECM by default) gets ``T_cart_rcm`` as its base frame, so
  ``ECM/measured_cp`` is the camera tip in the cart frame.
* Every other arm gets ``inv(T_cart_refrcm · T_refrcm_reftip) · T_cart_rcm``: its RCM in the
  camera frame, so ``PSMx/measured_cp`` is the PSM tip seen from the camera.

One implementation: :func:`frames_into` (a compiled kernel, :mod:`~davinci_sim.kinematics.jit`,
around the FK row of :mod:`~davinci_sim.kinematics.fk_compiled`) computes all of these for one
set of joints in ~2 µs; the live simulation calls it whenever a setup or ECM joint changes at
all, :func:`T_cart_rcm` and :func:`cart_frames` call it too.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from davinci_sim.kinematics.arms import SUJArmKinematics, load_arm, load_suj
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import _consts
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.kinematics.jit import helper, jit, kernel_array, warm


# --- the kernel ----------------------------------------------------------------------------
@helper
def _compose_rigid(A, B, out):
    """``out = A · B`` for rigid 4x4 transforms (``out`` is neither ``A`` nor ``B``)."""
    for i in range(3):
        a0, a1, a2, a3 = A[i, 0], A[i, 1], A[i, 2], A[i, 3]
        for j in range(3):
            out[i, j] = a0 * B[0, j] + a1 * B[1, j] + a2 * B[2, j]
        out[i, 3] = a0 * B[0, 3] + a1 * B[1, 3] + a2 * B[2, 3] + a3
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@helper
def invert_rigid_row(T, out):
    """``out = T⁻¹ = (Rᵀ, −Rᵀp)`` for a rigid 4x4 ``T`` (``out`` is not ``T``)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = T[j, i]
        out[i, 3] = -(T[0, i] * T[0, 3] + T[1, i] * T[1, 3] + T[2, i] * T[2, 3])
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@helper
def _rcm_row(links, modified, tool, tool_is_identity, T_cart_sujbase, q, out, T1, J, F):
    """``out = T_cart_sujbase · DH(q) · tool`` (``tool``: ``SUJ_tip_to_tool_origin``)."""
    tip_pose_row(links, modified, tool, tool_is_identity, q, T1, J, False, F)
    _compose_rigid(T_cart_sujbase, T1, out)


@jit
def _rcm_rows(links, modified, tool, tool_is_identity, T_cart_sujbase, Q, out, T1, J, F):
    for r in range(Q.shape[0]):
        _rcm_row(links, modified, tool, tool_is_identity, T_cart_sujbase, Q[r], out[r], T1, J, F)


invert_rigid = jit(invert_rigid_row)
""":func:`invert_rigid_row` compiled, for Python callers: the inverse of an arm's base frame
(``Arm._T_base_reference``) with the arithmetic of the compiled control period."""


@helper
def frames_row(
    links, modified, tools, tools_identity, T_cart_sujbase, Q_suj, reference,
    ref_links, ref_modified, ref_tool, ref_tool_identity, q_ref, out, T1, J, F,
):  # fmt: skip
    """:func:`frames_into`'s arithmetic (``plan.args``, the SUJ joints ``Q_suj`` (k, n),
    ``plan.reference``, ``plan.ref_args``, the reference arm's joints ``q_ref``), callable
    from kernels (:mod:`davinci_sim.sim.live_kernel`); ``T1``, ``J``, ``F`` scratch."""
    k = Q_suj.shape[0]
    for i in range(k):
        _rcm_row(links[i], modified[i], tools[i], tools_identity[i], T_cart_sujbase[i],
                 Q_suj[i], out[i], T1, J, F)  # fmt: skip
    tip_pose_row(ref_links, ref_modified, ref_tool, ref_tool_identity, q_ref, T1, J, False, F)
    _compose_rigid(out[reference], T1, out[k])
    invert_rigid_row(out[k], out[k + 1])
    for i in range(k):
        if i == reference:
            for r in range(4):
                for c in range(4):
                    out[k + 2 + i, r, c] = out[i, r, c]
        else:
            _compose_rigid(out[k + 1], out[i], out[k + 2 + i])


_frames_rows = jit(frames_row)


def _packed_rcm_chain(suj_arm: SUJArmKinematics) -> tuple:
    """The kernel's constants of ``DH · SUJ_tip_to_tool_origin`` (fk's packing)."""
    chain = suj_arm.chain
    tool = chain.T_last_tip @ suj_arm.T_sujtip_rcm
    return _consts(DHChain(chain.name, chain.convention, chain.joints, tool)).packed


@dataclass(frozen=True, eq=False)
class FramePlan:
    """The constants of :func:`frames_into` for a set of SUJ arms and a reference arm."""

    arms: tuple[str, ...]
    """The SUJ arms (carried arm names), in the rows' order."""
    reference: int
    """Index in ``arms`` of the reference arm (whose tip is the camera)."""
    dof: int
    """Joints of the reference arm."""
    args: tuple
    ref_args: tuple


def frame_plan(
    suj: Mapping[str, SUJArmKinematics], reference_chain: DHChain, reference_arm: str = "ECM"
) -> FramePlan:
    """The plan for the SUJ arms ``suj`` (by carried arm) with ``reference_arm``'s
    ``reference_chain`` giving the camera (dvrk.md 1.6)."""
    arms = tuple(suj)
    packed = [_packed_rcm_chain(suj[a]) for a in arms]
    n = {p[0].shape[1] for p in packed}
    if len(n) != 1:
        raise ValueError(f"SUJ arms with different joint counts: {sorted(n)}")
    args = (
        np.ascontiguousarray(np.stack([p[0] for p in packed])),
        np.array([p[1] for p in packed], dtype=bool),
        np.ascontiguousarray(np.stack([p[2] for p in packed])),
        np.array([p[3] for p in packed], dtype=bool),
        np.ascontiguousarray(np.stack([suj[a].T_cart_sujbase for a in arms]).astype(float)),
    )
    ref = _consts(reference_chain).packed
    return FramePlan(arms, arms.index(reference_arm), reference_chain.dof, args, ref)


def frames_into(plan: FramePlan, q_suj: np.ndarray, q_reference: np.ndarray, out=None):
    """All SUJ frames for joints ``q_suj`` (k, 6: a row per ``plan.arms``, m and rad) and the
    reference arm's joints ``q_reference``: ``out`` (2k + 2, 4, 4), m, holds ``T_cart_rcm``
    per arm (rows 0..k-1), ``T_cart_camera`` (row k), ``T_camera_cart`` (row k + 1) and the
    base frame of every arm (rows k + 2..: the reference arm's RCM in the cart, the others'
    RCM in the camera frame). Returns ``out`` (a new array if None)."""
    k = len(plan.arms)
    if out is None:
        out = np.empty((2 * k + 2, 4, 4))
    # New writable C arrays: the kernel's one compiled signature (its warm-up's), whether
    # the joints come read-only or not.
    Q = np.array(q_suj, dtype=float, order="C").reshape(k, -1)
    q_ref = np.array(q_reference, dtype=float, order="C").reshape(plan.dof)
    _frames_rows(*plan.args, Q, plan.reference, *plan.ref_args, q_ref, out, *_scratch(Q.shape[1]))
    return out


def _scratch(n: int) -> tuple:
    return np.empty((4, 4)), np.empty((6, 0)), np.empty((max(n, 8), 12))


def T_cart_rcm(suj_arm: SUJArmKinematics, q_suj) -> np.ndarray:
    """RCM (arm base) of the arm carried by ``suj_arm`` in the cart frame, (4, 4), m:
    ``world_origin_to_SUJ · DH(q) · SUJ_tip_to_tool_origin`` (dvrk.md 1.6).

    ``q_suj``: SUJ joints J0…J5 (m for J0, rad for J1-J5), shape (6,) or (..., 6).
    """
    q = np.asarray(q_suj, dtype=float)
    n = suj_arm.chain.dof
    if q.ndim == 0 or q.shape[-1] != n:
        raise ValueError(f"{suj_arm.chain.name}: expected joints (..., {n}), got {q.shape}")
    batch = q.shape[:-1]
    Q = kernel_array(q).reshape(-1, n)
    out = np.empty((Q.shape[0], 4, 4))
    T_sujbase = np.ascontiguousarray(suj_arm.T_cart_sujbase, dtype=float)
    _rcm_rows(*_packed_rcm_chain(suj_arm), T_sujbase, Q, out, *_scratch(n))
    return out.reshape(*batch, 4, 4) if batch else out[0]


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
    ref_kin = load_arm(reference_arm)
    q_ref = ref_kin.home if q_reference is None else q_reference
    plan = frame_plan(suj, ref_kin.chain, reference_arm)
    Q = np.array([q_suj.get(name, arm.simulated_position) for name, arm in suj.items()])
    out = frames_into(plan, Q, q_ref)
    k = len(plan.arms)
    rcm = {name: _frozen(out[i]) for i, name in enumerate(plan.arms)}
    base = {
        name: rcm[name] if name == reference_arm else _frozen(out[k + 2 + i])
        for i, name in enumerate(plan.arms)
    }
    return CartFrames(
        reference_arm=reference_arm,
        T_cart_rcm=MappingProxyType(rcm),
        T_cart_camera=_frozen(out[k]),
        base_frames=MappingProxyType(base),
    )


def _warm_up() -> None:
    """Compile (or load from the cache) at import, not in the middle of a 1 kHz loop."""
    suj = load_suj()
    cart_frames(suj=suj)
    T_cart_rcm(suj["ECM"], suj["ECM"].simulated_position)
    T = np.eye(4)
    invert_rigid(T, np.empty((4, 4)))
    T.setflags(write=False)  # (the simulation's base frames are read-only)
    invert_rigid(T, np.empty((4, 4)))


warm(_warm_up)
