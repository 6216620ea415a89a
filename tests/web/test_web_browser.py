"""The web console in a real browser: headless Chromium (the system's, driven by Playwright)
against ``serve`` with the web console, the loop in its own process, as a user runs it.

Screenshots of each view go to the test's temporary folder (``--basetemp`` to keep them).
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest

playwright = pytest.importorskip("playwright.sync_api")

from serving import serving  # noqa: E402

from davinci_sim.bridge.app import ServeOptions  # noqa: E402
from davinci_sim.bridge.rosbridge.config import BridgeConfig  # noqa: E402
from davinci_sim.web.app import web_part  # noqa: E402
from davinci_sim.web.server import WebOptions  # noqa: E402

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: Chromium's flags for a closed network and no display (see scripts/system-deps.sh).
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    # WebGL in software for the 3-D view (no GPU here).
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed")


@pytest.fixture(scope="module")
def server():
    """``serve --task short_path`` with the web console: the loop in its own process."""
    options = ServeOptions(
        scene="psm1_ecm_mtmr",
        task=SHORT_TASK,
        home=True,
        runner="process",
        real_time=False,  # as fast as it goes: the tests wait on simulated time
        images="none",
        bridge=BridgeConfig(port=0),
        hand_inputs=("MTMR",),
        render_hz=10.0,
        frame_task=True,
    )
    parts = [web_part(WebOptions(port=0, frame_rate=10.0), bedside=True)]
    with serving(options, parts) as info:
        yield info


@pytest.fixture(scope="module")
def browser():
    with playwright.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


class Console:
    """One page of the console, with its console errors collected."""

    def __init__(
        self, browser, url: str, *, init_script: str | None = None, query: str = ""
    ) -> None:
        self.context = browser.new_context(viewport={"width": 1280, "height": 860})
        if init_script:
            self.context.add_init_script(init_script)
        self.page = self.context.new_page()
        self.errors: list[str] = []
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        self.page.goto(url + query)
        self.wait("window.davinci.last !== null && window.davinci.client !== null")

    def js(self, expression: str):
        return self.page.evaluate(expression)

    def wait(self, expression: str, timeout: float = 60.0):
        self.page.wait_for_function(expression, timeout=timeout * 1000)

    def state(self) -> dict:
        return self.js("window.davinci.last")

    def take_control(self) -> None:
        self.page.click("#control")
        self.wait("window.davinci.operator === window.davinci.client")

    def wait_following(self) -> dict:
        self.wait("window.davinci.last.console.buttons.operator_present")
        t = self.state()["time"]
        self.wait(
            f"window.davinci.last.time > {t + 0.1} && "
            "window.davinci.last.teleops.MTMR_PSM1.following"
        )
        return self.state()

    def wait_sim(self, seconds: float) -> dict:
        t = self.state()["time"]
        self.wait(f"window.davinci.last.time > {t + seconds}")
        return self.state()

    def release(self) -> None:
        if self.js("window.davinci.operator === window.davinci.client"):
            self.page.click("#control")
            self.wait("window.davinci.operator !== window.davinci.client")

    def close(self) -> None:
        self.context.close()


@pytest.fixture
def console(server, browser):
    pages: list[Console] = []

    def open_page(**kwargs) -> Console:
        page = Console(browser, server["web"], **kwargs)
        pages.append(page)
        return page

    yield open_page
    for page in reversed(pages):
        page.release()
        page.close()


def canvas_std(page: Console, selector: str) -> float:
    return page.js(
        f"""(() => {{
        const c = document.querySelector('{selector}');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let s = 0, s2 = 0, n = d.length / 4;
        for (let i = 0; i < d.length; i += 4) {{ const v = d[i + 1]; s += v; s2 += v * v; }}
        return Math.sqrt(s2 / n - (s / n) ** 2);
    }})()"""
    )


def test_the_page_draws_the_endoscope_itself_in_three_modes(console, tmp_path):
    """The default: three.js in the page, from the server's scene and poses."""
    page = console()
    page.wait("window.davinci.view !== null && window.davinci.drawn > 0")
    assert page.js("document.getElementById('view-source').textContent").startswith("drawn in")
    assert page.js("document.getElementById('endoscope').hidden")  # (the images' canvas)
    shots = {}
    for mode, width in (("left", 640), ("sbs", 1280), ("anaglyph", 640)):
        page.page.select_option("#mode", mode)
        n = page.js("window.davinci.drawn")
        page.wait(f"window.davinci.drawn > {n + 2}")  # new poses keep being drawn
        assert page.js("document.getElementById('endoscope3d').width") == width
        box = page.page.locator("#endoscope3d").bounding_box()
        shots[mode] = page.page.screenshot(path=tmp_path / f"page_{mode}.png", clip=box)
    from io import BytesIO

    from PIL import Image

    left = np.asarray(Image.open(BytesIO(shots["left"])).convert("RGB"), dtype=float)
    assert left.std() > 10  # a picture, not a blank
    anaglyph = np.asarray(Image.open(BytesIO(shots["anaglyph"])).convert("RGB"), dtype=float)
    assert (np.abs(anaglyph[..., 0] - anaglyph[..., 1]) > 40).sum() > 1000  # red and cyan
    assert page.errors == []


def test_the_page_loads_and_the_endoscope_streams_in_three_modes(console, tmp_path):
    """The server's images (``?view=server``; also where the page cannot draw)."""
    page = console(query="?view=server")
    assert "server images" in page.js("document.getElementById('view-source').textContent")
    page.wait("window.davinci.frameNumber !== undefined")
    first = page.js("window.davinci.frameNumber")
    page.wait(f"window.davinci.frameNumber > {first}")  # frames keep coming
    assert canvas_std(page, "#endoscope") > 10  # a picture, not a blank
    assert page.js("document.querySelector('#endoscope').width") == 640
    page.page.screenshot(path=tmp_path / "surgeon_left.png")
    page.page.select_option("#mode", "sbs")
    page.wait(f"window.davinci.frameNumber > {first + 2}")
    assert page.js("document.querySelector('#endoscope').width") == 1280
    page.page.screenshot(path=tmp_path / "surgeon_side_by_side.png")
    page.page.select_option("#mode", "anaglyph")
    n = page.js("window.davinci.frameNumber")
    page.wait(f"window.davinci.frameNumber > {n + 1}")
    # Red from the left eye, cyan from the right: the two channels differ somewhere.
    differs = page.js(
        """(() => { const c = document.querySelector('#endoscope');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let k = 0; for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - d[i + 1]) > 40) k++;
        return k; })()"""
    )
    assert differs > 1000
    page.page.screenshot(path=tmp_path / "surgeon_anaglyph.png")
    assert page.errors == []


def test_the_bedside_view_renders_the_system_in_3d(console, server, tmp_path):
    if "bedside" not in server:
        pytest.skip("no 3-D view in this build")
    page = console()
    page.page.click("nav button[data-tab=bedside]")
    frame = page.page.frame_locator("#bedside")
    frame.locator("canvas").first.wait_for(timeout=60_000)
    page.page.wait_for_timeout(3000)  # the scene arrives and draws
    # The page's screenshot clipped to the view: an element screenshot first waits for the
    # element to be still over two animation frames, which a software-rendered 3-D view on a
    # loaded machine may not give within the default wait (a CI run timed out there). Even
    # the box alone waited past the default 30 s once in CI, the page busy drawing in software.
    box = page.page.locator("#bedside").bounding_box(timeout=180_000)
    assert box is not None
    shot = page.page.screenshot(path=tmp_path / "bedside.png", clip=box, timeout=180_000)
    from io import BytesIO

    from PIL import Image

    pixels = np.asarray(Image.open(BytesIO(shot)).convert("L"), dtype=float)
    assert pixels.std() > 5  # something is drawn


def test_a_key_moves_the_tool_right_in_the_image_by_the_scaled_amount(console):
    page = console()
    page.take_control()
    before = page.wait_following()
    page.page.click("#screen")
    page.page.keyboard.down("KeyD")
    # Held until the tool is 15 mm on (and 1 s of simulated time at least), as a person
    # holds a key until the tool is there: a page busy drawing in software may send the
    # key's refreshes late, and a velocity not refreshed within the hand's dead-man time
    # stops (twice in eight runs the tool had gone 9 mm in a fixed 1 s hold).
    x0 = before["tips"]["PSM1"]["p_camera"][0]
    page.wait_sim(1.0)
    page.wait(f"window.davinci.last.tips.PSM1.p_camera[0] < {x0 - 0.015}")
    page.page.keyboard.up("KeyD")
    after = page.wait_sim(0.8)  # the hand's last input times out, the tool settles
    tool = np.subtract(after["tips"]["PSM1"]["p_camera"], before["tips"]["PSM1"]["p_camera"])
    mtm = np.subtract(
        after["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"], before["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"]
    )
    scale = before["teleops"]["MTMR_PSM1"]["scale"]
    # Right in the image is the camera's -x (dvrk.md 1.6), and HRSV's (dvrk.md 4.2).
    assert tool[0] < -0.01 and abs(tool[1]) < 0.3 * abs(tool[0])
    assert tool[0] == pytest.approx(scale * mtm[0], rel=0.15)
    assert after["tips"]["PSM1"]["pixel"][0] > before["tips"]["PSM1"]["pixel"][0] + 20
    assert page.errors == []


def test_the_clutch_holds_the_tool_while_the_hand_moves(console):
    page = console()
    page.take_control()
    page.wait_following()
    page.page.click("#screen")
    page.page.keyboard.down("Space")
    page.wait("window.davinci.last.teleops.MTMR_PSM1.clutched")
    before = page.state()
    page.page.keyboard.down("KeyW")
    y0 = before["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"][1]
    page.wait_sim(1.0)  # (and until the master is 15 mm up: see the D key's test)
    page.wait(f"window.davinci.last.teleops.MTMR_PSM1.p_mtm_hrsv[1] > {y0 + 0.015}")
    page.page.keyboard.up("KeyW")
    after = page.wait_sim(0.5)
    page.page.keyboard.up("Space")
    tool = np.subtract(after["tips"]["PSM1"]["p_camera"], before["tips"]["PSM1"]["p_camera"])
    mtm = np.subtract(
        after["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"], before["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"]
    )
    assert mtm[1] > 0.01  # the hand moved the master up ...
    assert np.linalg.norm(tool) < 0.001  # ... and the tool held


FAKE_GAMEPAD = """
window.fakePad = { id: "Fake standard gamepad", index: 0, connected: true, mapping: "standard",
  axes: [0, 0, 0, 0], buttons: Array.from({ length: 17 }, () => ({ pressed: false, value: 0 })),
  vibrationActuator: { effects: [], playEffect(kind, p) { this.effects.push(p);
                       return Promise.resolve("complete"); } } };
navigator.getGamepads = () => [window.fakePad];
"""


def test_a_scripted_gamepad_moves_the_tool_up(console):
    page = console(init_script=FAKE_GAMEPAD)
    page.take_control()
    before = page.wait_following()
    page.js("window.fakePad.axes[1] = -1")  # left stick pushed forward: up
    y0 = before["tips"]["PSM1"]["p_camera"][1]
    page.wait_sim(1.0)  # (and until the tool is 15 mm up: see the D key's test)
    page.wait(f"window.davinci.last.tips.PSM1.p_camera[1] > {y0 + 0.015}")
    page.js("window.fakePad.axes[1] = 0")
    after = page.wait_sim(0.8)
    tool = np.subtract(after["tips"]["PSM1"]["p_camera"], before["tips"]["PSM1"]["p_camera"])
    assert tool[1] > 0.01 and abs(tool[0]) < 0.3 * tool[1]  # camera +y is up in the image
    assert "Fake standard gamepad" in page.page.inner_text("#gamepad")


def test_a_fixture_set_in_the_page_reaches_the_running_task(console):
    page = console()
    page.take_control()
    page.page.select_option("#fixture-type", "viscous")
    page.js(
        """for (const [id, v] of [['B', 70], ['G', 6]]) {
          const el = document.getElementById(id); el.value = v;
          el.dispatchEvent(new Event('input')); }"""
    )
    page.page.click("#apply")
    page.wait("window.davinci.last.task.condition === 'viscous(B=70, G_max=6)'")
    assert page.page.inner_text("#repetition").endswith("viscous(B=70, G_max=6)")
    # (the path's deviation, which the fixture acts on, beside it)
    assert page.page.inner_text("#deviation-label") == "deviation"
    assert page.page.inner_text("#deviation").endswith(" mm")
    # Rota's fixture: the sliders are its viscous gain and its cap; the elastic term, theirs
    page.page.select_option("#fixture-type", "viscous_elastic")
    assert page.page.inner_text("#G-label") == "Fmax"
    page.js(
        """for (const [id, v] of [['B', 20], ['G', 2]]) {
          const el = document.getElementById(id); el.value = v;
          el.dispatchEvent(new Event('input')); }"""
    )
    page.page.click("#apply")
    page.wait("window.davinci.last.task.condition.startsWith('viscous_elastic(B=20,')")
    law = page.js("window.davinci.last.task.condition")
    for part in ("elastic_gain=0.8", "threshold=0.002", "half=0.002", "slope=500", "max_force=2"):
        assert part in law


def test_bad_input_from_the_page_is_refused_with_a_message(console):
    page = console()
    page.take_control()
    page.wait("window.davinci.last.hands.MTMR.holding")  # (taking control takes the handle)
    before = page.state()["hands"]
    page.js("window.davinciSend({op: 'input', mtm: 'MTMR', axes: [NaN, 0, 0]})")
    page.wait("(window.davinci.lastMessage || {}).cls === 'error'")
    assert "must be a number" in page.page.inner_text("#messages")
    page.js("window.davinciSend({op: 'launch', what: 'rockets'})")
    page.wait("document.querySelector('#messages').innerText.includes('unknown op')")
    after = page.wait_sim(0.2)["hands"]
    assert after.get("MTMR", {}).get("velocity") in (None, [0.0, 0.0, 0.0])
    assert before.get("MTMR", {}).get("holding") == after.get("MTMR", {}).get("holding")


def test_two_pages_one_operator_and_the_second_sees_the_first(console):
    a, b = console(), console()
    a.take_control()
    b.page.click("#control")
    b.wait("document.querySelector('#messages').innerText.includes('release control')")
    assert b.page.inner_text("#operator").startswith("page ")
    a.wait_following()
    tip0 = b.state()["tips"]["PSM1"]["p_camera"]
    a.page.click("#screen")
    a.page.keyboard.down("KeyA")
    a.wait_sim(0.8)
    a.page.keyboard.up("KeyA")
    b.wait_sim(0.5)
    tip1 = b.state()["tips"]["PSM1"]["p_camera"]
    assert tip1[0] - tip0[0] > 0.005  # left in the image: the camera's +x, seen by page b


def test_a_synthetic_trainee_does_a_repetition_and_its_row_is_in_the_table(console, tmp_path):
    page = console()
    page.page.fill("#trainee", "Grace")
    page.page.press("#trainee", "Enter")
    page.page.dispatch_event("#trainee", "change")
    page.take_control()
    # (every phase the page's state messages show, noted in the page: this loop, as fast as
    # it goes, can run the short path's repetition between two of the test's looks)
    page.js(
        "window.phasesSeen = new Set();"
        "setInterval(() => window.phasesSeen.add(window.davinci.last.task.phase), 5)"
    )
    page.page.click("#synthetic")
    page.wait("window.davinci.last.synthetic && window.davinci.last.synthetic.running")
    end = time.monotonic() + 300  # a deadline (the loop runs below real time when busy)
    while time.monotonic() < end:
        if page.js("document.querySelectorAll('#rows tbody tr').length") > 0:
            break
        time.sleep(0.05)
    # (the row in the table is what a finished repetition leaves, checked below)
    assert "RUNNING" in page.js("Array.from(window.phasesSeen)")
    row = page.page.inner_text("#rows tbody tr")
    assert row.startswith("Grace") and "short_path" not in row  # trainee, condition, ...
    page.page.screenshot(path=tmp_path / "task_panel.png")


def test_the_input_module_maps_keys_sticks_spacemouse_and_rumble(console):
    page = console()
    r = page.page.evaluate(
        """async () => { const m = await import('/input.js');
        const buttons = (pressed, values) => Array.from({ length: 17 }, (_, i) =>
            ({ pressed: pressed.includes(i), value: values[i] ?? (pressed.includes(i) ? 1 : 0) }));
        return {
          right: m.keyAxes(new Set(['KeyD'])), arrows: m.keyAxes(new Set(['ArrowUp'])),
          cancel: m.keyAxes(new Set(['KeyD', 'KeyA'])), deeper: m.keyAxes(new Set(['KeyR'])),
          fine: m.keyAxes(new Set(['KeyW', 'ShiftLeft'])),
          pad: m.gamepadInput({ id: 'pad', axes: [1, -1, 0, -1], buttons: buttons([0], {7: 1}) }),
          rest: m.gamepadInput({ id: 'pad', axes: [0.05, -0.1, 0, 0.11], buttons: [] }),
          mouse: m.gamepadInput({ id: '3Dconnexion SpaceMouse', axes: [1, 0, -1, 0, 0, 0],
                                  buttons: buttons([1], {}) }),
          rumble: [m.rumbleIntensity(2.5, 5), m.rumbleIntensity(-9, 5),
                   m.rumbleIntensity(NaN, 5), m.rumbleIntensity(1, 0)],
          gripperOpen: m.GRIPPER_OPEN,
          gripperClosed: m.GRIPPER_CLOSED,
        }; }"""
    )
    assert r["right"] == [1, 0, 0] and r["arrows"] == [0, 1, 0] and r["deeper"] == [0, 0, 1]
    assert r["cancel"] == [0, 0, 0] and r["fine"] == [0, 0.25, 0]
    # Standard mapping: left stick right/up (y is down on a gamepad), right stick forward =
    # deeper, A = clutch, right trigger fully pulled = gripper squeezed (-15°: jaw -20°).
    assert r["pad"]["axes"] == [1, 1, 1]
    assert r["pad"]["buttons"] == {"clutch": True, "camera": False}
    assert r["pad"]["gripper"] == pytest.approx(np.radians(-15))
    assert r["rest"]["axes"] == [0, 0, 0]  # inside the dead zone
    # A SpaceMouse: x right, z down (so up is -z), y towards the user (so deeper is -y).
    assert r["mouse"]["axes"] == [1, 1, 0] and r["mouse"]["gripper"] == pytest.approx(
        np.radians(-15)
    )
    assert r["rumble"] == [0.5, 1, 0, 0]
    assert r["gripperOpen"] == pytest.approx(np.radians(60))
    assert r["gripperClosed"] == pytest.approx(np.radians(-15))


def test_the_headset_module_maps_controller_motion_buttons_and_pulses(console):
    page = console()
    r = page.page.evaluate(
        """async () => { const m = await import('/xr.js');
        const pose = (x, y, z, q = [0, 0, 0, 1]) => ({ position: [x, y, z], orientation: q });
        const opt = { scale: 0.5, handSpeed: 0.05, turnSpeed: 0.6 };
        const half = (a) => [0, Math.sin(a / 2), 0, Math.cos(a / 2)];  // about y
        const buttons = (values) => Array.from({ length: 6 }, (_, i) =>
            ({ pressed: (values[i] ?? 0) > 0.5, value: values[i] ?? 0 }));
        return {
          right: m.xrRate(pose(0, 0, 0), pose(0.05, 0, 0), 1, opt),
          fast: m.xrRate(pose(0, 0, 0), pose(0.5, 0, -0.5), 1, opt),
          ahead: m.xrRate(pose(0, 0, 0), pose(0, 0, -0.02), 0.5, opt),
          turn: m.xrRate(pose(0, 0, 0, half(0.2)), pose(0, 0, 0, half(0.3)), 1, opt),
          first: m.xrRate(null, pose(1, 1, 1), 1, opt),
          trigger: m.xrButtons({ buttons: buttons({ 0: 1 }) }),
          idle: m.xrButtons({ buttons: buttons({}) }),
          clutch: m.xrButtons({ buttons: buttons({ 4: 1 }) }),
          camera: m.xrButtons({ buttons: buttons({ 5: 1 }) }),
          hands: [m.mtmOfHand('left'), m.mtmOfHand('right'), m.mtmOfHand('none')],
          pulses: [m.hapticPulse(2.5, 5), m.hapticPulse(0, 5)],
        }; }"""
    )
    # 5 cm/s of the controller, halved: 2.5 cm/s of the hand = half the hand's top speed.
    assert r["right"]["axes"] == pytest.approx([0.5, 0, 0]) and r["right"]["turn"] == [0, 0, 0]
    assert r["fast"]["axes"] == pytest.approx([1, 0, 1])  # capped; -z ahead is "in"
    assert r["ahead"]["axes"] == pytest.approx([0, 0, 0.4])
    assert r["turn"]["turn"] == pytest.approx([0, 0.1 / 0.6, 0], abs=1e-9)
    assert r["first"] == {"axes": [0, 0, 0], "turn": [0, 0, 0]}
    assert r["trigger"]["gripper"] == pytest.approx(np.radians(-15))
    assert r["idle"] == {"gripper": pytest.approx(np.radians(60)), "clutch": False,
                         "camera": False}  # fmt: skip
    assert r["clutch"]["clutch"] and not r["clutch"]["camera"] and r["camera"]["camera"]
    assert r["hands"] == ["MTML", "MTMR", None]
    assert r["pulses"] == [[0.5, 30], None]


# A headset as the WebXR API presents one: two eye views a few cm apart, a right controller
# whose grip pose the test moves (window.fakeGrip), the session's frames on a timer. Its
# layer draws into the page's canvas (framebuffer null, as the WebXR emulators do).
FAKE_XR = """
window.xrLog = { sessions: 0, pulses: 0, ended: 0 };
(() => {
  const mat = (tx) => { const m = new Float32Array(16); m[0] = m[5] = m[10] = m[15] = 1;
                        m[12] = tx; return m; };
  const n = 0.05, f = 100, proj = new Float32Array(16);
  proj[0] = 1; proj[5] = 1; proj[10] = -(f + n) / (f - n); proj[11] = -1;
  proj[14] = -2 * f * n / (f - n);
  const views = ["left", "right"].map((eye, k) => ({ eye, projectionMatrix: proj,
    transform: { matrix: mat(k ? 0.032 : -0.032),
                 inverse: { matrix: mat(k ? -0.032 : 0.032) } } }));
  window.fakeGrip = { position: { x: 0, y: 0, z: -0.3 }, orientation: { x: 0, y: 0, z: 0, w: 1 } };
  const source = { handedness: "right", gripSpace: { grip: true }, targetRaySpace: {},
    profiles: ["fake"], gamepad: { mapping: "xr-standard", axes: [0, 0, 0, 0],
      buttons: Array.from({ length: 6 }, () => ({ pressed: false, touched: false, value: 0 })),
      hapticActuators: [{ pulse: () => { window.xrLog.pulses++;
                                         return Promise.resolve(true); } }] } };
  const frame = { getViewerPose: () => ({ views, transform: { matrix: mat(0) } }),
                  getPose: (space) => (space.grip ? { transform: window.fakeGrip } : null) };
  class FakeSession extends EventTarget {
    constructor() { super(); this.inputSources = [source]; this.visibilityState = "visible";
                    this.renderState = {}; this.running = true; }
    updateRenderState(s) { Object.assign(this.renderState, s); }
    requestReferenceSpace() { return Promise.resolve({ local: true }); }
    requestAnimationFrame(cb) {
      return setTimeout(() => { if (this.running) cb(performance.now(), frame); }, 14); }
    cancelAnimationFrame(id) { clearTimeout(id); }
    end() { this.running = false; window.xrLog.ended++; this.dispatchEvent(new Event("end"));
            return Promise.resolve(); }
  }
  window.XRWebGLLayer = class {
    constructor(session, gl) { this.gl = gl; this.framebuffer = null; }
    getViewport(v) { const w = this.gl.drawingBufferWidth / 2, h = this.gl.drawingBufferHeight;
                     return { x: v.eye === "right" ? w : 0, y: 0, width: w, height: h }; } };
  // (headless Chromium has no XR device for its own to wait on)
  WebGL2RenderingContext.prototype.makeXRCompatible = () => Promise.resolve();
  Object.defineProperty(navigator, "xr", { configurable: true, value: {
    isSessionSupported: () => Promise.resolve(true),
    requestSession: () => { window.xrLog.sessions++; window.xrSession = new FakeSession();
                            return Promise.resolve(window.xrSession); } } });
})();
"""


def test_a_scripted_headset_moves_the_tool_through_teleoperation(console):
    page = console(init_script=FAKE_XR)
    page.wait("window.davinci.view !== null && !document.getElementById('xr').hidden")
    page.take_control()
    page.page.click("#xr")
    page.wait("window.davinci.xr && window.davinci.xr.frames > 5")
    assert page.js("document.getElementById('xr').textContent") == "Exit headset"
    before = page.wait_following()  # (the headset's presence is the head sensor)
    # The right controller moves right at ~10 cm/s (wall time) while 1 s of simulation passes.
    page.js(
        """window.moving = setInterval(() => {
             window.fakeGrip = { ...window.fakeGrip, position: { ...window.fakeGrip.position,
               x: window.fakeGrip.position.x + 0.001 } }; }, 10)"""
    )
    # (until the master has moved 6 mm: how far a wall-clock motion goes in simulated time
    # depends on the machine's load)
    x0 = before["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"][0]
    page.wait(f"window.davinci.last.teleops.MTMR_PSM1.p_mtm_hrsv[0] < {x0 - 0.006}")
    page.js("clearInterval(window.moving)")
    after = page.wait_sim(0.8)
    tool = np.subtract(after["tips"]["PSM1"]["p_camera"], before["tips"]["PSM1"]["p_camera"])
    mtm = np.subtract(
        after["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"], before["teleops"]["MTMR_PSM1"]["p_mtm_hrsv"]
    )
    # The master moved right (HRSV's -x, dvrk.md 4.2) and the tool with it, scaled: right in
    # the image is the camera's -x (dvrk.md 1.6).
    assert mtm[0] < -0.005 and abs(mtm[1]) < 0.3 * abs(mtm[0]), (mtm, tool)
    scale = before["teleops"]["MTMR_PSM1"]["scale"]
    assert tool[0] == pytest.approx(scale * mtm[0], rel=0.15), (mtm, tool)
    page.page.click("#xr")  # exit: the head leaves the viewer
    page.wait("window.davinci.xr === null")
    page.wait("!window.davinci.last.console.buttons.operator_present")
    assert page.js("window.xrLog.ended") == 1
    assert page.errors == []
