"""The web console's rate input on a hand, one tick, compiled: :func:`hand_rate_row`.

:meth:`HandInput.pre_step <davinci_sim.devices.hand_input.HandInput.pre_step>` while a key
holds a velocity: the hand's target moves ``v·dt`` within its lead of the handle and its
workspace, and, while a turn key holds an angular velocity, the wrist's target orientation
turns by ``w·dt`` unless it already leads the handle by ``max_turn_lead``. The console's
compiled ticks (:mod:`davinci_sim.console.chunk_kernel`) call it; the Python method stays the
oracle, and the two give the same bits (``tests/console/test_chunk.py``): numpy's norm of a
3-vector is ``sqrt`` of BLAS's dot, as ``np.dot`` is here; numpy's and numba's ``@`` call the
same BLAS; the angle between two rotations is :func:`~davinci_sim.geometry.so3.angle_between`'s
own plain sum.

The hand's part of its device's row (``console/chunk_rows.hand_part``) is ``(on, state,
params)``: ``state`` = target (3, m), origin (3, m), velocity (3, m/s), angular velocity
(3, rad/s), the wrist's target orientation (9, row-major; HRSV), the target's velocity
over the tick (6: m/s, rad/s; ``SimulatedMTM.move_hand``'s, which the device's read uses
up); ``params`` = max lead (m), workspace (m), the time the velocities hold until (s), max
turn lead (rad), and 1.0 when the wrist's target orientation is held (0.0: none yet, the
first turn is Python's: it grasps).
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.geometry.so3 import angle_between_entries, rotation_from_array
from davinci_sim.kinematics.jit import helper
from davinci_sim.kinematics.scratch import local

__all__ = ["STATE_SIZE", "PARAMS_SIZE", "hand_rate_row"]

STATE_SIZE = 27
PARAMS_SIZE = 5

_angle = helper(angle_between_entries)
_rotation = helper(rotation_from_array)

#: Rotations the device takes as a target without a message: ``as_transform``'s check is
#: 1e-6 on the Gram matrix; a turned target further than this from orthonormal is left to
#: Python (never in practice: a turn's product drifts ~1e-16 a tick).
_ORTHONORMAL = 1e-9


@numba.njit(cache=True, nogil=True)
def hand_rate_row(hand, T_hrsv, target, dt) -> bool:
    """One tick of the rate input on its hand (see the module docstring): the hand's target
    ``hand[1][:3]`` moves, within ``max_lead`` of the handle (the device's last read,
    ``T_hrsv``, 4x4 HRSV) and ``workspace`` of where the hand took it; a turn turns
    ``hand[1][12:21]``; the device's target pose ``target`` (4x4) follows. False (nothing
    written) where the tick is Python's: a turn whose result is not a proper rotation to the
    device's check. ``hand[1][21:27]``: the target's velocity over the tick, for the hand's
    damping: the key's where the hand moved freely (not held back by its lead or its
    workspace), the turn's where the wrist turned, else 0."""
    state, params = hand[1], hand[2]
    tgt, handle, lead = local(3), local(3), local(3)  # (in the frame: every tick)
    for i in range(3):
        tgt[i] = state[i] + state[6 + i] * dt
        handle[i] = T_hrsv[i, 3]
    for i in range(3):
        lead[i] = tgt[i] - handle[i]
    d = np.sqrt(np.dot(lead, lead))
    free = True  # (the hand moves at the key's velocity)
    if d > params[0]:  # the handle is held back: the hand waits for it
        s = params[0] / d
        for i in range(3):
            tgt[i] = handle[i] + lead[i] * s
        free = False
    reach = local(3)
    for i in range(3):
        reach[i] = tgt[i] - state[3 + i]
    r = np.sqrt(np.dot(reach, reach))
    if r > params[1]:
        s = params[1] / r
        for i in range(3):
            tgt[i] = state[3 + i] + reach[i] * s
        free = False
    turning = state[9] != 0.0 or state[10] != 0.0 or state[11] != 0.0
    turned = False
    R_target = local(3, 3)
    for k in range(9):
        R_target[k // 3, k % 3] = state[12 + k]
    if turning:  # (HandInput._turn)
        R = _rotation(state[9:12] * dt) @ R_target
        R_handle = T_hrsv[:3, :3].copy()
        lead_now = _angle(R.ravel(), R_handle.ravel())
        if lead_now <= max(params[3], _angle(R_target.ravel(), R_handle.ravel())):
            for i in range(3):  # (the device's check of the pose it is given, stricter)
                for j in range(3):
                    g = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j]
                    if abs(g - (1.0 if i == j else 0.0)) > _ORTHONORMAL:
                        return False
            R_target = R
            turned = True
    for i in range(3):
        state[21 + i] = state[6 + i] if free else 0.0
        state[24 + i] = state[9 + i] if turned else 0.0
        state[i] = tgt[i]
        target[i, 3] = tgt[i]
    if params[4] != 0.0:  # (the wrist's target held: the device's target takes it)
        for i in range(3):
            for j in range(3):
                state[12 + 3 * i + j] = R_target[i, j]
                target[i, j] = R_target[i, j]
    return True
