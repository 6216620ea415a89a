"""Sensors: endoscope images, named monitoring cameras, instrument contact forces."""

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
    with pytest.raises(KeyError, match="instrument"):
        sim.contact_force("MTMR")


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
