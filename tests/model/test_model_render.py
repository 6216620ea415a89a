"""The stereo endoscope renders the instruments; the overview shows the whole system."""

import mujoco
import numpy as np
import pytest

from davinci_sim.model import build_model


@pytest.fixture(scope="module")
def renderer_factory():
    renderers = []

    def make(model, height, width):
        try:
            r = mujoco.Renderer(model, height, width)
        except Exception as e:  # no OpenGL: nothing to check here
            pytest.skip(f"offscreen rendering unavailable ({e}); set MUJOCO_GL=egl")
        renderers.append(r)
        return r

    yield make
    for r in renderers:
        r.close()


def _instrument_pixels(model, seg: np.ndarray, arm: str) -> int:
    """Pixels showing a geom of ``arm``'s instrument (shaft, wrist, jaws)."""
    bodies = {model.body(f"{arm}/{b}").id for b in ("roll", "wrist_pitch", "wrist_yaw")}
    bodies |= {model.body(f"{arm}/jaw_{i}").id for i in (1, 2)}
    geoms = np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies])
    is_geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
    return int(np.count_nonzero(is_geom & np.isin(seg[..., 0], geoms)))


def test_stereo_endoscope_sees_all_instruments(full_model, renderer_factory):
    """640×480 left/right images are lit, differ (stereo) and show all three instruments."""
    m = full_model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("surgical").id)
    mujoco.mj_forward(m, d)
    r = renderer_factory(m, 480, 640)
    images = {}
    for cam in ("ECM/left", "ECM/right"):
        r.update_scene(d, camera=cam)
        rgb = r.render()
        assert rgb.shape == (480, 640, 3)
        assert rgb.mean() > 40  # lit, not black
        images[cam] = rgb
        r.enable_segmentation_rendering()
        r.update_scene(d, camera=cam)
        seg = r.render()
        r.disable_segmentation_rendering()
        for arm in ("PSM1", "PSM2", "PSM3"):
            assert _instrument_pixels(m, seg, arm) > 500, (cam, arm)
        assert np.count_nonzero(seg[..., 0] == m.geom("object/bead").id) > 50
    assert np.abs(images["ECM/left"].astype(int) - images["ECM/right"]).mean() > 1.0


def test_endoscope_at_dvrk_home_looks_away_from_the_instruments(full_model, renderer_factory):
    """Documented limitation: with the dVRK's simulated SUJ values the tips are out of view."""
    m = full_model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    r = renderer_factory(m, 480, 640)
    r.enable_segmentation_rendering()
    r.update_scene(d, camera="ECM/left")
    seg = r.render()
    r.disable_segmentation_rendering()
    for arm in ("PSM1", "PSM2", "PSM3"):
        assert _instrument_pixels(m, seg, arm) < 500


def test_overview_shows_cart_table_and_console(renderer_factory):
    m = build_model("psm1_ecm_mtmr")
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    r = renderer_factory(m, 480, 640)
    r.enable_segmentation_rendering()
    r.update_scene(d, camera="overview")
    seg = r.render()
    shown = {m.body(m.geom_bodyid[g]).name for g in np.unique(seg[..., 0]) if g >= 0}
    for body in ("cart", "table", "console", "PSM1/pitch", "ECM/pitch", "SUJ/PSM1/SUJ_PSM1_J2"):
        assert body in shown
