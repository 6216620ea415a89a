"""Physics: the PSM1 jaws, driven by their actuators, pick up the bead."""

import mujoco
import numpy as np

from davinci_sim.model import build_model, servo_gains


def test_psm1_lifts_the_bead():
    m = build_model("psm1")
    d = mujoco.MjData(m)
    gains = servo_gains(m)
    jid = m.actuator_trnid[:, 0]
    qadr, dof = m.jnt_qposadr[jid], m.jnt_dofadr[jid]
    ins, jaw1, jaw2 = (gains.names.index(f"PSM1/{n}") for n in ("insertion", "jaw_1", "jaw_2"))
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    target = d.qpos[qadr].copy()
    bead = m.body("object/bead").id
    tip = m.site("PSM1/tip").id
    # The bead sits on PSM1's instrument axis at home: insert until it is 7.5 mm past the
    # wrist-yaw axis (the jaw pivot), i.e. between the open jaws.
    axis = d.site_xmat[tip].reshape(3, 3)[:, 2]
    depth = float(np.dot(d.xpos[bead] - d.site_xpos[tip], axis))
    q_home, q_grasp = target[ins], target[ins] + depth - 0.0075
    z0 = d.xpos[bead][2]

    def run(seconds, update):
        n = int(round(seconds / m.opt.timestep))
        for k in range(n):
            update(min(1.0, 1.25 * k / n))
            d.ctrl[:] = target + d.qfrc_bias[dof] / gains.kp
            mujoco.mj_step(m, d)

    def set_jaws(angle):
        target[[jaw1, jaw2]] = angle  # each finger: half of the dVRK jaw angle

    run(0.15, lambda s: set_jaws(0.6))
    run(0.4, lambda s: target.__setitem__(ins, q_home + s * (q_grasp - q_home)))
    run(0.25, lambda s: set_jaws(-0.35))
    assert np.allclose(d.actuator_force[[jaw1, jaw2]], -0.16)  # squeezing at full jaw effort
    run(0.5, lambda s: target.__setitem__(ins, q_grasp + s * (0.10 - q_grasp)))
    run(0.2, lambda s: None)
    assert d.xpos[bead][2] - z0 > 0.06  # lifted with the instrument
    assert np.linalg.norm(d.xpos[bead] - d.site_xpos[tip]) < 0.012  # still between the jaws
