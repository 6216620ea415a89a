"""The path drawn in the scene: visual-only geoms, and visible in the endoscope image."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from davinci_sim.model import build_spec
from davinci_sim.sim.simulation import Simulation
from davinci_sim.tasks import add_path_visual, load_task
from davinci_sim.tasks.scene import digit_strokes


@pytest.fixture(scope="module")
def scene():
    task = load_task("seed_path")
    T_cart_camera = Simulation("psm1_ecm_mtmr", keyframe="surgical").T_cart_camera()
    spec = build_spec("psm1_ecm_mtmr")
    plain = spec.compile()
    add_path_visual(spec, task, T_world_camera=T_cart_camera)
    return task, plain, spec.compile()


def test_geoms_are_visual_only_and_keyframes_survive(scene):
    task, plain, model = scene
    names = [model.geom(i).name for i in range(model.ngeom)]
    ours = [i for i, n in enumerate(names) if n.startswith("task/")]
    n_tubes = len(task.path.vertices) - 1
    assert sum(names[i].startswith("task/tube") for i in ours) == n_tubes
    assert sum(names[i].startswith("task/marker") for i in ours) == 5
    assert sum(names[i].startswith("task/label") for i in ours) == sum(
        len(digit_strokes(str(k), 1.0)) for k in range(1, 6)
    )
    assert np.all(model.geom_contype[ours] == 0) and np.all(model.geom_conaffinity[ours] == 0)
    assert model.nq == plain.nq and model.nkey == plain.nkey
    np.testing.assert_array_equal(model.key("surgical").qpos, plain.key("surgical").qpos)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("surgical").id)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(
        data.geom_xpos[model.geom("task/marker1").id], task.markers[0], atol=1e-12
    )


def test_path_visible_in_the_endoscope(scene):
    """Rendered from the left endoscope camera at the surgical keyframe, the image differs
    from the scene without the path where the path projects, and the markers' yellow is
    there."""
    task, plain, model = scene
    images = []
    for m in (plain, model):
        data = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, data, m.key("surgical").id)
        mujoco.mj_forward(m, data)
        try:
            r = mujoco.Renderer(m, 240, 320)
        except Exception as e:  # no GL on this machine
            pytest.skip(f"offscreen rendering unavailable ({e}); set MUJOCO_GL=egl")
        with r:
            r.update_scene(data, camera="ECM/left")
            images.append(r.render().astype(int))
    diff = np.abs(images[1] - images[0]).sum(axis=2) > 60
    assert diff.sum() > 200
    rows, cols = np.nonzero(diff)
    # The changed pixels sit where the task test projects the path (columns 288-427 and
    # rows 167-251 of 640x480, halved here), give or take the markers, digits and shadows.
    assert 120 < np.median(cols) < 230 and 70 < np.median(rows) < 140
    yellow = (images[1][..., 0] > 200) & (images[1][..., 1] > 170) & (images[1][..., 2] < 90)
    assert yellow.sum() > 20


def test_digits():
    assert len(digit_strokes("8", 1.0)) == 7
    assert len(digit_strokes("10", 1.0)) == 2 + 6
    with pytest.raises(ValueError):
        digit_strokes("x", 1.0)
