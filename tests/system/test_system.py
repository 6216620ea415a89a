"""One assembly: a running system built from a SystemDescription."""

import functools
import pickle
import time

import numpy as np
import pytest

from davinci_sim.devices.network import NetworkDevice
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.devices.udp import UDPJSONDevice
from davinci_sim.sim.simulation import Simulation
from davinci_sim.system import (
    ConsoleDescription,
    DeviceDescription,
    SystemDescription,
    TaskDescription,
    build_simulation,
    build_system,
    scene_model,
    task_condition,
)
from davinci_sim.tasks import load_task

TASK = SystemDescription(
    scene="psm1_ecm_mtmr",
    task=TaskDescription("seed_path", condition="40:5"),
    publish_qpos=True,
    snapshot_period=0.002,
)


def wait_for(predicate, timeout=30.0):
    end = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > end:
            return False
        time.sleep(0.01)
    return True


def test_a_task_description_builds_console_task_and_qpos_in_tick_order():
    sim = build_simulation(TASK)
    try:
        # devices read first, the console, the teleoperations, the haptic loop after the
        # step, the task session samples after the haptic loop, then the qpos publisher
        assert list(sim.components) == [
            "MTMR/device", "console", "MTMR_PSM1", "haptics", "task", "qpos",
        ]  # fmt: skip
        assert isinstance(sim.components["MTMR/device"], SimulatedMTM)
        session = sim.components["task"]
        assert session.snapshot().task == "seed_path"
        fields = sim.components["haptics"].snapshot().fields
        assert [mtm for _, mtm in fields] == ["MTMR"]  # the task's fixture, on its MTM
        # the path is drawn in the model: more geoms than the bare scene
        assert sim.model.ngeom > Simulation("psm1_ecm_mtmr").model.ngeom
        sim.tick()
        np.testing.assert_array_equal(sim.components["qpos"].snapshot(), sim.data.qpos)
    finally:
        sim.close()


def test_devices_teleop_scale_and_home_from_the_description():
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        console=ConsoleDescription(
            devices={"MTMR": DeviceDescription("network", watchdog=0.5)},
            scale=0.4,
            operator_present=True,
        ),
        home=True,
    )
    sim = build_simulation(description)
    try:
        device = sim.components["MTMR/device"]
        assert isinstance(device, NetworkDevice) and device.name == "MTMR/device"
        teleop = sim.components["MTMR_PSM1"]
        assert teleop.config.scale == 0.4
        assert sim.components["console"].snapshot().buttons["operator_present"]
        assert sim.arms["PSM1"].operating_state().state == "ENABLED"
        assert sim.arms["PSM1"].is_busy()  # homing
    finally:
        sim.close()
    udp = SystemDescription(
        scene="psm1_ecm_mtmr",
        console=ConsoleDescription(devices={"MTMR": DeviceDescription("udp", port=0)}),
    )
    sim = build_simulation(udp)
    device = sim.components["MTMR/device"]
    assert isinstance(device, UDPJSONDevice) and device.address[1] > 0
    device.close()
    sim.close()
    with pytest.raises(ValueError, match="unknown MTMs"):
        build_simulation(
            SystemDescription(scene="psm1", console=ConsoleDescription(devices={"MTMX": None}))
        )
    with pytest.raises(ValueError, match="kind"):
        DeviceDescription("bluetooth")
    with pytest.raises(ValueError, match="render_hz needs a runner"):
        SystemDescription(runner="none", render_hz=30)
    for runner, real_time in (("thread", False), ("process", True)):
        with pytest.raises(ValueError, match="stepped needs the process runner"):
            SystemDescription(runner=runner, real_time=real_time, stepped=True)


def test_task_conditions():
    task = load_task("seed_path")
    assert task_condition(task, "40:5") == {"type": "viscous", "B": 40.0, "G_max": 5.0}
    name = task.conditions[0]["name"]
    assert task_condition(task, name) == name and task_condition(task, None) is None
    with pytest.raises(ValueError, match="neither"):
        task_condition(task, "strong")
    with pytest.raises(ValueError, match="neither"):
        build_system(TASK.replace(task=TaskDescription("seed_path", condition="strong")))


def test_the_same_description_gives_the_same_run_in_both_runners():
    """The thread and the process runner run the same system: scripted inputs at given
    ticks give bit-identical states (the process factory is the description, pickled)."""
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        console=ConsoleDescription(teleop_enabled=True, operator_present=True),
        real_time=False,
        start_paused=True,
        snapshot_period=0.001,
    )
    pickle.dumps(functools.partial(build_simulation, description))
    snaps = []
    for runner in ("thread", "process"):
        with build_system(description.replace(runner=runner)) as system:
            handle = system.handle
            # (measured_jp is a copy; sim.measured_qpos would be the live array in a thread)
            done = handle.call_at(300, "MTMR", "measured_jp")
            psm = handle.call_at(300, "PSM1", "measured_jp")
            handle.call_at(100, "console", "emulate_clutch", [1])
            handle.resume()
            q = np.r_[done.result(60), psm.result(60)]
            assert wait_for(lambda h=handle: h.snapshot().tick >= 300)
        snaps.append(np.asarray(q))
        assert (system.sim is None) == (runner == "process")
    np.testing.assert_array_equal(snaps[0], snaps[1])
    # built, never started: stopping releases it and reports no ticks
    assert build_system(description.replace(runner="process")).stop() is None
    assert build_system(description).stop().ticks == 0


def test_the_renderer_draws_the_system_scene_with_the_task():
    """issue 11: the render process builds its model from the description, so the
    endoscope images show the task's path as the simulation has it."""
    model = scene_model(TASK)
    sim = build_simulation(TASK)
    other = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    try:
        assert model.ngeom == sim.model.ngeom and model.nq == sim.model.nq
        reference = sim.render_stereo()[0].astype(int)
        plain = other.render_stereo()[0].astype(int)
    finally:
        sim.close()
        other.close()
    # The arms move a little from tick 0 (no homing: they sag slowly), so compare where the
    # path is drawn: pixels that differ between the plain scene and the task's scene.
    drawn = np.any(np.abs(reference - plain) > 40, axis=2)
    assert drawn.sum() > 100

    def shows_the_task(frame):
        left = frame.left.astype(int)
        close_to_task = np.abs(left[drawn] - reference[drawn]).mean()
        close_to_plain = np.abs(left[drawn] - plain[drawn]).mean()
        assert close_to_task < 0.25 * close_to_plain, (close_to_task, close_to_plain)

    # the runner's renderer (render_hz), and a viewer's on-demand one fed from snapshots
    system = build_system(TASK.replace(render_hz=30.0, real_time=False), start=True)
    try:
        assert wait_for(lambda: (f := system.stereo_frame()) is not None and f.frame >= 1)
        frame = system.stereo_frame()
        assert frame.left.shape == (480, 640, 3)
        shows_the_task(frame)
    finally:
        system.stop()
    system = build_system(TASK.replace(real_time=False), start=True)
    frames = system.frames(30.0)
    try:
        assert not frames.from_handle
        assert wait_for(lambda: frames.latest() is not None)
        shows_the_task(frames.latest())
    finally:
        frames.stop()
        system.stop()


@pytest.mark.parametrize("keyframe", ["surgical", "home"])
def test_the_path_labels_read_left_to_right_and_upright_in_the_endoscope(keyframe):
    """The digits face the start keyframe's endoscope: in the left image, digit 2's upper
    right stroke (b) is right of and above its lower left stroke (e); mirrored labels (as
    drawn facing a fixed world direction) had b left of e."""
    import mujoco

    from davinci_sim.model.cameras import CameraConfig, project_left
    from davinci_sim.system import SystemDescription, TaskDescription
    from davinci_sim.system.build import scene_model

    description = SystemDescription(
        scene="psm1_ecm_mtmr", keyframe=keyframe, task=TaskDescription("seed_path")
    )
    model = scene_model(description)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(keyframe).id)
    mujoco.mj_forward(model, data)
    cam = model.camera("ECM/left").id
    R_left, p_left = data.cam_xmat[cam].reshape(3, 3), data.cam_xpos[cam]

    def pixel(geom: str):
        p = data.geom_xpos[model.geom(geom).id]
        # MuJoCo's camera looks along -z with y up; the dVRK tip frame: x left, y up, z in.
        x, y, z = R_left.T @ (p - p_left)
        return project_left([-x + CameraConfig().baseline_m / 2, y, -z], CameraConfig())

    # Digit "2" = segments a, b, g, e, d (tasks/scene.py): label2_1 is b, label2_3 is e.
    (u_b, v_b), (u_e, v_e) = pixel("task/label2_1"), pixel("task/label2_3")
    assert u_b > u_e and v_b < v_e
