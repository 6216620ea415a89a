"""Stepping many simulations' rows in one compiled call gives the bits of MuJoCo's own
``mj_step`` called from Python on each simulation (the study batch relies on it)."""

import mujoco
import numpy as np
import pytest

from davinci_sim.sim import rows_step
from davinci_sim.sim.rows_step import RowStepper

XML = """<mujoco><option timestep="0.001"/><worldbody>
<body name="arm"><joint name="j0" type="hinge" axis="0 1 0" damping="0.01"/>
  <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02"/>
  <body name="hand" pos="0 0 -0.3"><joint name="j1" type="hinge" axis="1 0 0"/>
    <geom type="box" size=".05 .05 .05"/></body></body>
<body pos="0 0 -0.33"><geom type="plane" size="1 1 0.1"/></body></worldbody>
<actuator><motor joint="j0"/><motor joint="j1"/></actuator></mujoco>"""


def _rows(m, n):
    return (np.zeros((n, m.nq)), np.zeros((n, m.nv)), np.zeros((n, m.nv)),
            np.zeros((n, m.nv)), np.zeros((n, 3)))  # fmt: skip


@pytest.mark.parametrize("python", [False, True])
def test_rows_step_as_mujoco_steps_each_simulation(python, monkeypatch):
    if python:  # the fallback without numba: the same loop in Python
        monkeypatch.setattr(rows_step, "_KERNEL", None)
    m = mujoco.MjModel.from_xml_string(XML)
    heavy = mujoco.MjModel.from_xml_string(XML)  # a row with its own model (another mass)
    heavy.body_mass[2] *= 3.0
    n = 5
    models = [m, heavy, m, m, heavy]
    datas = [mujoco.MjData(x) for x in models]
    ref = [mujoco.MjData(x) for x in models]
    rng = np.random.default_rng(3)
    for d, e in zip(datas, ref, strict=True):
        d.qpos[:] = e.qpos[:] = rng.normal(size=m.nq)
    body = m.body("hand").id
    stepper = RowStepper(models, datas, body)
    Q, V, QB, QG, XI = _rows(m, n)
    touched = False
    for t in range(400):  # the box swings into the floor: contacts too
        ctrl = rng.normal(0, 0.5, (n, m.nu))
        xfrc = rng.normal(0, 0.5, (n, 6))
        rows = np.arange(n) if t % 3 else np.array([1, 3])  # some rows not stepped
        stepper.step(rows, ctrl, xfrc, Q, V, QB, QG, XI)
        for i in rows:
            e = ref[i]
            e.ctrl[:] = ctrl[i]
            e.xfrc_applied[body] = xfrc[i]
            mujoco.mj_step(models[i], e)
            np.testing.assert_array_equal(Q[i], e.qpos, strict=True)
            np.testing.assert_array_equal(V[i], e.qvel, strict=True)
            np.testing.assert_array_equal(QB[i], e.qfrc_bias, strict=True)
            np.testing.assert_array_equal(QG[i], e.qfrc_gravcomp, strict=True)
            np.testing.assert_array_equal(XI[i], e.xipos[body], strict=True)
            np.testing.assert_array_equal(datas[i].qpos, e.qpos, strict=True)
        touched |= any(d.ncon for d in datas)
    assert touched  # (the floor was reached: contacts were stepped)


def test_take_keeps_the_chosen_rows():
    m = mujoco.MjModel.from_xml_string(XML)
    datas = [mujoco.MjData(m) for _ in range(4)]
    for i, d in enumerate(datas):
        d.qpos[0] = 0.1 * i
    kept = RowStepper([m] * 4, datas, 2).take(np.array([1, 3]))
    Q, V, QB, QG, XI = _rows(m, 2)
    kept.step([0, 1], np.zeros((2, m.nu)), np.zeros((2, 6)), Q, V, QB, QG, XI)
    assert kept.datas == [datas[1], datas[3]]
    np.testing.assert_array_equal(Q[:, 0], [datas[1].qpos[0], datas[3].qpos[0]])
    assert datas[0].time == 0.0 and datas[1].time > 0.0


def test_mismatched_models_and_datas_are_refused():
    m = mujoco.MjModel.from_xml_string(XML)
    with pytest.raises(ValueError, match="2 models for 1 datas"):
        RowStepper([m, m], [mujoco.MjData(m)], 0)


def test_compiled_when_numba_is_on():
    from davinci_sim.kinematics import jit

    assert rows_step.COMPILED == jit.ENABLED
