"""The bedside view in a real browser: headless Chromium (Debian's, driven by Playwright)
loads viser's page from the view's port and draws the model; a preset changes the picture.

Skipped where Playwright or a system Chromium is missing. WebGL in headless Chromium needs
the software rasteriser (SwiftShader through ANGLE); the page's first frame takes seconds
with it (script, shaders), hence one small page for the whole test."""

from __future__ import annotations

import io
import shutil
import time

import numpy as np
import pytest

from davinci_sim.system import SystemDescription, TaskDescription, scene_model
from davinci_sim.web.scene3d import BedsideView

playwright = pytest.importorskip("playwright.sync_api")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no system chromium")
SOFTWARE_GL = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
#: Longest wait for one screenshot or the first drawing, ms (a stuck page fails, it does not
#: hang; no duration is asserted).
SLOW_FRAME_MS = 180_000


def canvas_pixels(page) -> np.ndarray:
    from PIL import Image

    # (the page is the canvas and a small panel). A software-rendered frame can take tens of
    # seconds on a busy machine (make test runs another worker beside this one).
    png = page.screenshot(timeout=SLOW_FRAME_MS)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)


def drawn(pixels: np.ndarray) -> bool:
    """Not blank: many distinct colours (a cleared canvas has one or two)."""
    colours = np.unique((pixels // 8).reshape(-1, 3), axis=0)
    return len(colours) > 50 and pixels.std() > 10


def test_the_page_draws_the_system_and_a_preset_moves_the_view(tmp_path):
    description = SystemDescription("psm1_ecm_mtmr", task=TaskDescription("seed_path"))
    with BedsideView(lambda: scene_model(description)) as view:
        with playwright.sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=SOFTWARE_GL)
            try:
                page = browser.new_page(viewport={"width": 480, "height": 360})
                errors = []
                page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
                page.on("pageerror", lambda e: errors.append(str(e)))
                page.goto(view.url)
                page.wait_for_selector("canvas", timeout=SLOW_FRAME_MS)
                deadline = time.monotonic() + SLOW_FRAME_MS / 1000
                first = canvas_pixels(page)
                while not drawn(first) and time.monotonic() < deadline:
                    time.sleep(0.5)
                    first = canvas_pixels(page)
                assert drawn(first)
                page.screenshot(path=tmp_path / "bedside_overview.png", timeout=SLOW_FRAME_MS)
                view.set_preset("monitor_task")
                second = canvas_pixels(page)
                while np.abs(second - first).mean() < 5 and time.monotonic() < deadline:
                    time.sleep(0.5)
                    second = canvas_pixels(page)
                assert np.abs(second - first).mean() >= 5
                assert drawn(second)
                page.screenshot(path=tmp_path / "bedside_monitor_task.png", timeout=SLOW_FRAME_MS)
                assert errors == []
            finally:
                browser.close()


def test_behind_the_token_gate_the_page_loads_and_connects():
    from davinci_sim.web.token_gate import TokenGate

    description = SystemDescription("psm1_ecm_mtmr")
    with (
        BedsideView(lambda: scene_model(description)) as view,
        TokenGate(view.port, "class-token", "0.0.0.0") as gate,
    ):
        with playwright.sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=SOFTWARE_GL)
            try:
                page = browser.new_page(viewport={"width": 320, "height": 240})
                refused = page.goto(f"http://127.0.0.1:{gate.port}/")
                assert refused.status == 403
                assert view.server.get_clients() == {}
                page.goto(f"http://127.0.0.1:{gate.port}/?token=class-token")
                assert "token" not in page.url  # (the gate took it once: a cookie holds it)
                page.wait_for_selector("canvas", timeout=SLOW_FRAME_MS)
                # viser's client opens its websocket at the page's address: through the gate
                deadline = time.monotonic() + SLOW_FRAME_MS / 1000
                while not view.server.get_clients() and time.monotonic() < deadline:
                    time.sleep(0.2)
                assert view.server.get_clients()
            finally:
                browser.close()
