"""Sensors: endoscope images, named monitoring cameras, instrument contact forces."""

import os
import subprocess
import sys

import numpy as np
import pytest
from sim_helpers import home

from davinci_sim.model import CameraConfig, ExternalCamera
from davinci_sim.sim.simulation import Simulation


def test_named_monitoring_cameras_render_offscreen():
    cams = (
        ExternalCamera("side", (1.2, 1.2, 1.3), (0.05, 1.2, 0.85)),
        ExternalCamera("top", (0.05, 1.2, 2.2), (0.05, 1.2, 0.8), fovy_deg=60.0),
    )
    sim = Simulation("psm1", cameras=cams)
    assert {"side", "top", "overview", "ECM/left", "ECM/right"} <= set(sim.camera_names())
    side = sim.render("side", 320, 240)
    top = sim.render("top", 320, 240)
    assert side.shape == (240, 320, 3) and side.dtype == np.uint8
    assert side.std() > 5 and top.std() > 5  # not a blank image
    assert not np.array_equal(side, top)
    with pytest.raises(KeyError, match="cameras"):
        sim.render("nope")
    sim.close()


def test_stereo_pair_sees_the_instruments_from_two_viewpoints():
    sim = Simulation("psm1", keyframe="surgical", endoscope=CameraConfig(width=320, height=240))
    left, right = sim.render_stereo()
    assert left.shape == right.shape == (240, 320, 3)
    assert left.std() > 5
    # A 5 mm baseline: close but not identical images.
    diff = np.abs(left.astype(int) - right.astype(int)).mean()
    assert 0.5 < diff < 60
    sim.close()


def test_contact_force_on_an_instrument_pressed_into_tissue():
    sim = Simulation("psm1")
    home(sim, ["PSM1"])
    psm = sim.arms["PSM1"]
    assert np.allclose(sim.contact_force("PSM1"), 0.0)
    # Drive the tip 5 cm down in the cart frame: into the tissue pad below it.
    goal = psm.setpoint_jp()
    for _ in range(1500):
        goal[2] = min(goal[2] + 0.0001, 0.24)
        psm.servo_jp(goal)
        sim.tick()
        if np.linalg.norm(sim.contact_force("PSM1")) > 0.5:
            break
    f = sim.contact_force("PSM1")
    assert np.linalg.norm(f) > 0.5
    assert f[2] > 0  # the tissue pushes the instrument up
    np.testing.assert_allclose(f, _contact_force_reference(sim, "PSM1"), rtol=1e-12, atol=1e-12)
    with pytest.raises(KeyError, match="instrument"):
        sim.contact_force("MTMR")


def _contact_force_reference(sim, arm: str) -> np.ndarray:
    """The contact force on ``arm``'s instrument contact by contact, from the bodies' names:
    MuJoCo's force on geom2 from geom1, turned into the world, signed by which side the
    instrument is on, pairs inside the instrument skipped."""
    import mujoco

    from davinci_sim.sim.sensors import INSTRUMENT_BODIES

    model, data = sim.model, sim.data
    names = {f"{arm}/{b}" for b in INSTRUMENT_BODIES["PSM"]}
    total = np.zeros(3)
    for i in range(data.ncon):
        c = data.contact[i]
        on = [model.body(model.geom_bodyid[g]).name in names for g in (c.geom1, c.geom2)]
        if on[0] == on[1]:
            continue
        f6 = np.zeros(6)
        mujoco.mj_contactForce(model, data, i, f6)
        f_world = c.frame.reshape(3, 3).T @ f6[:3]
        total += f_world if on[1] else -f_world
    return total


def test_a_task_draws_its_path_into_the_scene_before_compiling():
    from davinci_sim.tasks import add_path_visual, load_task

    task = load_task("seed_path")
    plain = Simulation("psm1", keyframe="surgical")
    drawn = Simulation(
        "psm1", keyframe="surgical", edit_spec=lambda spec: add_path_visual(spec, task)
    )
    assert drawn.model.ngeom > plain.model.ngeom
    assert drawn.model.nq == plain.model.nq and drawn.model.nu == plain.model.nu
    left_plain, _ = plain.render_stereo()
    left_drawn, _ = drawn.render_stereo()
    assert np.abs(left_plain.astype(int) - left_drawn.astype(int)).sum() > 0


def test_closing_a_renderer_survives_another_being_collected_meanwhile():
    """An unclosed simulation's renderer, freed by the garbage collector while another
    simulation closes its own, must not make that close fail: MuJoCo's close restores the
    context current before it, which was the collected one's (EGL_BAD_CONTEXT in a CI run)."""
    import gc

    from davinci_sim.sim.simulation import Simulation

    closing, left = Simulation("psm1"), Simulation("psm1")
    camera = closing.camera_names()[0]
    closing.render(camera, 64, 48)
    left.render(camera, 64, 48)  # (its context is now the current one)
    holder = [left]
    del left

    class CollectOnFree:  # the collector runs in the middle of the close
        def __init__(self, context):
            self.context = context

        def free(self):
            self.context.free()
            holder.clear()
            gc.collect()

    (renderer,) = closing._cameras._renderers.values()
    renderer._mjr_context = CollectOnFree(renderer._mjr_context)
    closing.close()  # (raised EGLError before CameraRenderer.close made its context current)
    assert closing._cameras is None and not holder


def test_rendering_without_an_opengl_context_says_how_to_get_one():
    """A program that imports mujoco before davinci_sim, headless, with MUJOCO_GL unset:
    MuJoCo took GLFW, which cannot start without a display; rendering says to set MUJOCO_GL
    (or to import davinci_sim first) instead of MuJoCo's bare FatalError."""
    script = (
        "import mujoco\n"
        "from davinci_sim.sim.sensors import CameraRenderer\n"
        "m = mujoco.MjModel.from_xml_string("
        "'<mujoco><worldbody><camera name=\"c\"/></worldbody></mujoco>')\n"
        "try:\n"
        "    CameraRenderer(m).render(mujoco.MjData(m), 'c', 32, 24)\n"
        "except RuntimeError as e:\n"
        "    print('refused:', e)\n"
    )
    unset = ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY", "PYOPENGL_PLATFORM")
    env = {k: v for k, v in os.environ.items() if k not in unset}
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "refused: MuJoCo has no OpenGL context" in out.stdout
    assert "MUJOCO_GL=egl" in out.stdout and "mujoco.glfw" in out.stdout
