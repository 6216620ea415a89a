"""The page's endoscope against MuJoCo's server render: 20 states of the arms, each drawn by
the page's three.js view (``static/endoscope.js``, in headless Chromium) and rendered by
MuJoCo with the same model and camera; the tool's and the task path's silhouettes agree
(IoU ≥ 0.95) and the jaws' centre is within 2 px (issue 22's fidelity check)."""

from __future__ import annotations

import base64
import json
import shutil
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
import pytest

from davinci_sim.system import SystemDescription, TaskDescription
from davinci_sim.system.build import scene_model
from davinci_sim.web.endoscope_stream import PoseStream
from davinci_sim.web.vendor import three_dir, vendor_file

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--use-gl=angle", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader"]  # fmt: skip
SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")
TOOL_BODIES = ("PSM1/roll", "PSM1/wrist_pitch", "PSM1/wrist_yaw", "PSM1/jaw_1", "PSM1/jaw_2")
JAW_BODIES = ("PSM1/jaw_1", "PSM1/jaw_2")
ORIGIN = "http://fidelity.test"

pytestmark = [
    pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed"),
    pytest.mark.skipif(three_dir() is None, reason="three.js is not installed (make install)"),
]


def states(model, n: int = 20) -> list[np.ndarray]:
    """The surgical pose with PSM1's and the ECM's joints moved (the tool in view, seen from
    several endoscope poses) and the jaws opened and closed."""
    rng = np.random.default_rng(22)
    q0 = model.key_qpos[model.key("surgical").id]
    out = []
    for _ in range(n):
        q = q0.copy()
        for j in range(model.njnt):
            name = model.joint(j).name
            if name.startswith(("PSM1/", "ECM/")) and model.jnt_limited[j]:
                lo, hi = model.jnt_range[j]
                adr = model.jnt_qposadr[j]
                span = 0.04 if name.startswith("ECM/") else 0.15
                q[adr] = np.clip(q[adr] + rng.uniform(-span, span) * (hi - lo), lo, hi)
        out.append(q)
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


@pytest.fixture(scope="module")
def model():
    return scene_model(SystemDescription(scene="psm1_ecm_mtmr", task=TaskDescription(SHORT_TASK)))


def page_segmentations(scene: dict, messages: list[bytes]) -> list[np.ndarray]:
    from playwright.sync_api import sync_playwright

    def serve(route) -> None:
        path = route.request.url[len(ORIGIN) :]
        if path.startswith("/vendor/"):
            body = vendor_file(path[len("/vendor/") :])
        elif path == "/endoscope.js":
            body = resources.files("davinci_sim.web").joinpath("static/endoscope.js").read_bytes()
        else:
            body = b"<!doctype html><canvas id=c width=640 height=480></canvas>"
        kind = "text/html" if path == "/" else "text/javascript"
        route.fulfill(status=200 if body else 404, body=body or b"", content_type=kind)

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            page.route(f"{ORIGIN}/**", serve)
            page.goto(f"{ORIGIN}/")
            ids = page.evaluate(
                """async ([scene, messages]) => {
                const THREE = await import('/vendor/three.module.js');
                const { EndoscopeView } = await import('/endoscope.js');
                const view = new EndoscopeView(THREE, document.getElementById('c'), scene);
                const out = [];
                for (const m of messages) {
                  const bytes = Uint8Array.from(atob(m), (c) => c.charCodeAt(0));
                  view.applyPoses(bytes.buffer);
                  const seg = view.segmentation(0);
                  const bytes8 = new Uint8Array(seg.buffer);
                  let text = '';
                  for (let i = 0; i < bytes8.length; i += 8192)
                    text += String.fromCharCode(...bytes8.subarray(i, i + 8192));
                  out.push(btoa(text));
                }
                return out;
            }""",
                [scene, [base64.b64encode(m).decode() for m in messages]],
            )
        finally:
            browser.close()
    h, w = scene["cameras"][0]["height"], scene["cameras"][0]["width"]
    return [np.frombuffer(base64.b64decode(s), np.int32).reshape(h, w) for s in ids]


def mujoco_segmentations(model, qs: list[np.ndarray]) -> list[np.ndarray]:
    data = mujoco.MjData(model)
    out = []
    with mujoco.Renderer(model, 480, 640) as renderer:
        renderer.enable_segmentation_rendering()
        for q in qs:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_camlight(model, data)
            renderer.update_scene(data, camera="ECM/left")
            seg = renderer.render()
            ids = np.where(seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seg[..., 0], -1)
            out.append(ids)
    return out


def test_the_pages_view_matches_mujocos_render_of_the_same_states(model):
    # (JSON round trip: what the page gets over the socket)
    stream = PoseStream(model)
    scene = json.loads(json.dumps(stream.scene(0.005)))
    qs = states(model)
    page = page_segmentations(scene, [stream.message(q, k, 0.001 * k) for k, q in enumerate(qs)])
    server = mujoco_segmentations(model, qs)
    body_of = model.geom_bodyid
    names = [model.body(b).name for b in range(model.nbody)]
    tool = np.array([names[body_of[g]] in TOOL_BODIES for g in range(model.ngeom)] + [False])
    jaws = np.array([names[body_of[g]] in JAW_BODIES for g in range(model.ngeom)] + [False])
    path = np.array([model.geom(g).name.startswith("task/") for g in range(model.ngeom)] + [False])
    tool_seen = 0
    for k, (a, b) in enumerate(zip(page, server, strict=True)):
        # (ids of -1 index the appended False: background)
        for label, kind in (("tool", tool), ("path", path)):
            mask_a, mask_b = kind[a], kind[b]
            if mask_b.sum() < 50:  # (out of view in this state)
                continue
            assert iou(mask_a, mask_b) >= 0.95, f"state {k}: {label} IoU {iou(mask_a, mask_b)}"
        jaw_a, jaw_b = jaws[a], jaws[b]
        if jaw_b.sum() >= 50:
            tool_seen += 1
            centre_a = np.argwhere(jaw_a).mean(axis=0)
            centre_b = np.argwhere(jaw_b).mean(axis=0)
            assert np.linalg.norm(centre_a - centre_b) <= 2.0, f"state {k}: jaws {centre_a}"
    assert tool_seen >= 10  # the states show the tool
