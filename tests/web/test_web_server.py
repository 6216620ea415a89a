"""The web console's server seen from a page's websocket: what it streams, who may operate,
what it refuses, and that commands reach the running simulation."""

from __future__ import annotations

import io
import json
import math
import struct
import time
import urllib.error
import urllib.request
from pathlib import Path

import mujoco
import numpy as np
import pytest
from PIL import Image
from websockets.sync.client import connect

from davinci_sim.system import (
    ConsoleDescription,
    SystemDescription,
    TaskDescription,
    build_system,
)
from davinci_sim.system.build import load_description_task
from davinci_sim.web.endoscope_stream import POSE_MAGIC, decode_poses
from davinci_sim.web.server import FRAME_HEADER, WebConsole, WebOptions

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")


@pytest.fixture(scope="module")
def console():
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        home=True,
        task=TaskDescription(SHORT_TASK),
        console=ConsoleDescription(hand_inputs=("MTMR",)),
        runner="thread",
        real_time=False,  # (as fast as it goes: the synthetic trainee's repetition is ~10 s)
        publish_qpos=True,
    )
    system = build_system(description, start=True)
    frames = system.frames(15.0)
    web = WebConsole(
        system.handle,
        WebOptions(port=0, state_rate=30.0, frame_rate=15.0),
        frames=frames,
        task=load_description_task(description),
        hand_mtms=("MTMR",),
        model=system.model_source,
    ).start()
    yield web, system
    web.stop()
    frames.stop()
    system.stop()


class Page:
    """A page's websocket: messages kept by op, frames kept apart."""

    def __init__(self, web: WebConsole, token: str | None = None, hello: bool = True):
        self.ws = connect(f"ws://127.0.0.1:{web.port}/ws", open_timeout=10)
        self.hello = self.next("hello")
        if hello:
            self.send(op="hello", **({} if token is None else {"token": token}))

    def send(self, **message) -> None:
        self.ws.send(json.dumps(message))

    def send_text(self, text: str) -> None:
        self.ws.send(text)

    def receive(self, timeout: float = 10.0):
        data = self.ws.recv(timeout=timeout)
        return data if isinstance(data, bytes) else json.loads(data)

    def next(self, op: str, timeout: float = 20.0, where=lambda m: True):
        """The next message of ``op`` (``"frame"``: a binary JPEG frame, ``"poses"``: a pose
        message) that satisfies ``where``."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.receive(timeout=max(0.01, end - time.monotonic()))
            if isinstance(m, bytes):
                kind = "poses" if struct.unpack_from("<I", m)[0] == POSE_MAGIC else "frame"
            else:
                kind = m.get("op")
            if kind == op and where(m):
                return m
        raise AssertionError(f"no {op!r} message in {timeout} s")

    def take_control(self) -> None:
        self.send(op="control", take=True)
        self.next("control", where=lambda m: m["operator"] == self.hello["client"])

    def latest_state(self, timeout: float = 10.0) -> dict:
        """The newest state: skips what arrived while the test was not reading."""
        while True:
            try:
                self.receive(timeout=0)
            except TimeoutError:
                break
        return self.next("state", timeout)

    def close(self) -> None:
        self.ws.close()


def wait_following(page: Page, timeout: float = 40.0) -> dict:
    """The first state, 0.1 s of simulated time after the operator is present, in which
    the teleoperation follows (a state from before may still show an earlier following)."""
    present = page.next("state", timeout, lambda m: m["console"]["buttons"]["operator_present"])
    return page.next(
        "state",
        timeout,
        lambda m: m["time"] > present["time"] + 0.1 and m["teleops"]["MTMR_PSM1"]["following"],
    )


def test_the_page_and_its_files_are_served(console):
    web, _ = console
    base = f"http://127.0.0.1:{web.port}"
    html = urllib.request.urlopen(base + "/").read().decode()
    assert '<canvas id="endoscope"' in html and "app.js" in html
    for name in ("app.js", "input.js", "style.css"):
        assert urllib.request.urlopen(f"{base}/{name}").status == 200
    for bad in ("/nope.js", "/static/../server.py", "/..%2fserver.py", "/.hidden"):
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(base + bad)
        assert e.value.code == 404


def test_hello_describes_the_task_and_state_and_frames_stream(console):
    web, _ = console
    page = Page(web)
    try:
        hello = page.hello
        assert hello["task"]["name"] == "short_path" and hello["task"]["psm"] == "PSM1"
        assert {m["name"] for m in hello["task"]["metrics"]} >= {"deviation_error"}
        assert hello["hands"] == ["MTMR"] and hello["camera"] == {"width": 640, "height": 480}
        state = page.next("state")
        assert state["task"]["name"] == "short_path" and "PSM1" in state["tips"]
        assert len(state["tips"]["PSM1"]["p_camera"]) == 3
        frame = page.next("frame", 60.0)
        assert len(frame) == FRAME_HEADER.size + FRAME_HEADER.unpack_from(frame)[2]  # left only
        page.send(op="view", stereo=True)  # a page that shows both eyes gets both
        frame = page.next("frame", 60.0, lambda f: len(f) > 16 + FRAME_HEADER.unpack_from(f)[2])
        number, t, n_left = FRAME_HEADER.unpack_from(frame)
        body = frame[FRAME_HEADER.size :]
        left = np.asarray(Image.open(io.BytesIO(body[:n_left])))
        right = np.asarray(Image.open(io.BytesIO(body[n_left:])))
        assert left.shape == right.shape == (480, 640, 3)
        assert left.std() > 10 and right.std() > 10  # an image, not a blank
        assert not np.array_equal(left, right)  # two eyes
        later = page.next("frame", 30.0, lambda f: struct.unpack_from("<I", f)[0] != number)
        assert FRAME_HEADER.unpack_from(later)[1] >= t
    finally:
        page.close()


# (before the tests that move the tool: the trainee starts from PSM1's home pose)
def test_a_page_that_draws_the_endoscope_gets_the_scene_then_poses_and_no_images(console):
    web, system = console
    page = Page(web)
    try:
        page.send(op="view", stereo=True, source="page")
        scene = page.next("scene", 60.0)  # (the model may still be building: it comes after)
        assert [c["name"] for c in scene["cameras"]] == ["ECM/left", "ECM/right"]
        layout = web.poses.layout
        assert scene["layout"]["bodies"] == list(layout.bodies)
        raw = page.next("poses", 20.0)
        first = decode_poses(raw, layout)
        later = decode_poses(page.next("poses", 20.0, lambda m: m[4:8] != raw[4:8]), layout)
        assert later["time"] > first["time"]  # a pose message per new snapshot
        # The simulation's camera: where the snapshot's joint positions put it.
        data = mujoco.MjData(system.model_source())
        snap = system.handle.snapshot()
        data.qpos[:] = snap.extras["qpos"]
        mujoco.mj_kinematics(data.model, data)
        mujoco.mj_camlight(data.model, data)
        left = layout.cameras[0]
        np.testing.assert_allclose(later["cameras"][0, :3], data.cam_xpos[left], atol=1e-3)
        # No JPEG frame for this page while it draws the endoscope itself.
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            try:
                m = page.receive(timeout=0.2)
            except TimeoutError:
                continue
            assert not (isinstance(m, bytes) and m[:4] != struct.pack("<I", POSE_MAGIC))
        page.send(op="view", stereo=False, source="server")  # and back to the images
        page.next("frame", 30.0)
    finally:
        page.close()


def test_a_synthetic_trainees_repetition_becomes_a_tagged_row_and_csv(console):
    web, _ = console
    page = Page(web)
    try:
        page.send(op="trainee", name="Ada")
        assert page.next("trainee")["name"] == "Ada"
        page.take_control()
        page.send(op="synthetic", action="start", subject=2, practice=5)
        page.next("state", where=lambda m: (m["synthetic"] or {}).get("running") is True)
        page.send(op="input", mtm="MTMR", axes=[1, 0, 0])  # the trainee has the MTM
        assert "synthetic trainee has the MTM" in page.next("error")["message"]
        # A deadline, not a duration: one repetition is ~10 s simulated, and the served
        # loop runs far below real time on a busy 2-core machine.
        row = page.next("row", 300.0)["row"]
        assert row["trainee"] == "Ada" and row["repetition"] >= 1
        assert 0 < row["deviation_error"] < 0.005
        csv = urllib.request.urlopen(f"http://127.0.0.1:{web.port}/results.csv").read().decode()
        header, first = csv.splitlines()[:2]
        assert header.startswith("trainee,task,condition,repetition")
        assert first.startswith("Ada,short_path,")
        page.send(op="control", take=False)
    finally:
        page.close()


def test_one_operator_at_a_time_and_only_the_operator_acts(console):
    web, _ = console
    a, b = Page(web), Page(web)
    try:
        a.send(op="control", take=True)
        assert (
            a.next("control", where=lambda m: m["operator"] is not None)["operator"]
            == (a.hello["client"])
        )
        b.send(op="control", take=True)
        assert "must release control" in b.next("error")["message"]
        b.send(op="input", mtm="MTMR", axes=[1, 0, 0])
        assert "take control first" in b.next("error")["message"]
        b.send(op="task", action="reset")
        assert "take control first" in b.next("error")["message"]
        # The operator closes the page: control is free again and the hand let go.
        a.close()
        b.next("control", where=lambda m: m["operator"] is None)
        b.send(op="control", take=True)
        b.next("control", where=lambda m: m["operator"] == b.hello["client"])
        b.send(op="control", take=False)
        b.next("control", where=lambda m: m["operator"] is None)
    finally:
        b.close()


def test_the_operators_input_moves_the_tool_right_in_the_image(console):
    web, _ = console
    page = Page(web)
    try:
        page.take_control()
        before = wait_following(page)
        p0 = np.array(before["tips"]["PSM1"]["p_camera"])
        u0 = before["tips"]["PSM1"]["pixel"][0]
        # "Right" at full rate, as the page sends it, for 1 s of simulated time (the loop
        # may run slower than real time on a busy machine) and at least five times (or
        # faster: as fast as it goes, a fast machine runs 1 s in a few messages, and each
        # holds only 0.3 s of simulated time).
        sent = 0
        while page.latest_state()["time"] < before["time"] + 1.0 or sent < 5:
            page.send(op="input", mtm="MTMR", axes=[1, 0, 0])
            sent += 1
            time.sleep(0.05)
        after = page.latest_state()
        moved = np.array(after["tips"]["PSM1"]["p_camera"]) - p0
        # Right in the image is the camera frame's -x (dvrk.md 1.6: x to the image's left).
        assert moved[0] < -0.01 and abs(moved[1]) < 0.3 * abs(moved[0])
        assert after["tips"]["PSM1"]["pixel"][0] > u0 + 20
        page.send(op="control", take=False)
    finally:
        page.close()


@pytest.mark.parametrize(
    "text, words",
    [
        ('{"op": "input", "mtm": "MTMR", "axes": [NaN, 0, 0]}', "not a number"),
        ('{"op": "input", "mtm": "MTMR", "axes": [5, 0, 0]}', "axes[0] must be in"),
        ('{"op": "input", "mtm": "MTML", "axes": [1, 0, 0]}', "no hand on MTML"),
        ('{"op": "warp"}', "unknown op"),
        ("{", "not JSON"),
        ('{"op": "condition", "condition": "B=9999"}', "has no condition"),
        ('{"op": "teleop", "scale": -1}', "scale must be in"),
    ],
)
def test_bad_input_is_refused_in_the_page_and_nothing_moves(console, text, words):
    web, system = console
    page = Page(web)
    try:
        page.take_control()
        # (an earlier test's last input still moves the hand until its timeout; taking
        # control takes the handle)
        hand = lambda m: m["hands"]["MTMR"]  # noqa: E731
        still = page.next(
            "state", 30.0, lambda m: hand(m)["velocity"] == [0, 0, 0] and hand(m)["holding"]
        )
        hand_before = still["hands"]["MTMR"]
        condition = system.handle.snapshot().extras["task"].condition
        page.send_text(text)
        assert words in page.next("error")["message"]
        page.send(op="ping", t=1.0)  # the server goes on
        assert page.next("pong")["t"] == 1.0
        snap = system.handle.snapshot()
        assert snap.extras["MTMR/hand"]["velocity"] == (0.0, 0.0, 0.0)
        assert snap.extras["MTMR/hand"]["holding"] == hand_before["holding"]
        assert snap.extras["task"].condition == condition
        page.send(op="control", take=False)
    finally:
        page.close()


def test_a_condition_from_the_page_reaches_the_running_fixture(console):
    web, system = console
    page = Page(web)
    try:
        page.take_control()
        page.send(op="condition", condition={"type": "viscous", "B": 55.0, "G_max": 6.5})
        state = page.next("state", where=lambda m: "B=55" in m["task"]["condition"])
        assert state["task"]["condition"] == "viscous(B=55, G_max=6.5)"
        page.send(op="condition", condition={"type": "none"})
        page.next("state", where=lambda m: m["task"]["condition"] == "none")
        page.send(op="control", take=False)
    finally:
        page.close()


def test_a_token_is_required_when_set(console):
    _, system = console
    web = WebConsole(system.handle, WebOptions(port=0, token="s3cret")).start()
    try:
        page = Page(web, hello=False)
        assert page.hello["needs_token"] is True
        page.send(op="control", take=True)
        assert "token" in page.next("error")["message"]
        page.send(op="hello", token="wrong")
        assert "wrong" in page.next("error")["message"]
        assert set(page.hello) == {"op", "client", "needs_token"}  # nothing before the token
        page.send(op="hello", token="s3cret")
        assert page.next("hello")["camera"] == {"width": 640, "height": 480}
        page.next("welcome")
        assert page.next("state")["task"]["name"] == "short_path"
        page.close()
    finally:
        web.stop()


def test_a_token_is_required_off_loopback():
    with pytest.raises(ValueError, match="needs a token"):
        WebOptions(host="0.0.0.0")
    assert WebOptions(host="0.0.0.0", token="x").token == "x"


def test_the_wrist_input_unlocks_the_rotation_turns_the_tool_and_release_locks_it(console):
    """A rate input's teleoperation starts with the rotation locked; the page's first turn
    unlocks it (the teleoperation re-aligns, then follows), the turn about the screen's
    "up" axis swings the tool's direction towards the image's left (camera +x), and
    releasing control locks the rotation again."""
    web, system = console
    page = Page(web)

    def locked() -> bool:
        return bool(system.handle.snapshot().extras["MTMR_PSM1"].rotation_locked)

    try:
        page.take_control()
        before = wait_following(page)
        assert locked()
        z0 = np.array(before["tips"]["PSM1"]["z_camera"])
        # Turn until the teleoperation has followed, unlocked, for 0.5 s of simulated time
        # with at least three turns sent while it did: the simulation runs as fast as it
        # goes, and a turn holds only 0.3 s of simulated time (the hand input's dead-man), so
        # turns sent while it re-aligns may all have run out before it follows.
        following_since, sent_following = None, 0
        s = before
        while following_since is None or s["time"] - following_since < 0.5 or (sent_following < 3):
            assert s["time"] - before["time"] < 20.0, "the teleoperation did not follow"
            page.send(op="input", mtm="MTMR", axes=[0, 0, 0], turn=[0, 1, 0])
            if following_since is not None:
                sent_following += 1
            time.sleep(0.05)
            s = page.latest_state()
            if not (s["teleops"]["MTMR_PSM1"]["following"] and not locked()):
                following_since, sent_following = None, 0
            elif following_since is None:
                following_since = s["time"]
        time.sleep(0.5)
        z1 = np.array(page.latest_state()["tips"]["PSM1"]["z_camera"])
        swing = np.cross(z0, z1)  # rotation axis x sin(angle), camera frame
        assert swing[1] > math.sin(math.radians(5))  # about camera +y ("up"): turned ~0.5 rad
        page.send(op="control", take=False)
        page.next("control", where=lambda m: m["operator"] is None)
        end = time.monotonic() + 10
        while not locked() and time.monotonic() < end:
            time.sleep(0.05)
        assert locked()
    finally:
        page.close()


def test_advance_is_refused_by_a_console_that_keeps_its_own_time(console):
    web, _ = console
    page = Page(web)
    try:
        assert page.next("welcome") and page.hello["stepped"] is False
        page.send(op="advance", seconds=0.1)
        assert "keeps time by itself" in page.next("advanced")["refused"]
        for seconds, words in ((0, "seconds must be in (0"), (11, "seconds must be in (0")):
            page.send(op="advance", seconds=seconds)
            assert words in page.next("error")["message"]
    finally:
        page.close()


@pytest.fixture(scope="module")
def stepped():
    """A stepped console (the loop in its own process ticks only what pages ask for)."""
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        home=True,
        console=ConsoleDescription(hand_inputs=("MTMR",)),
        runner="process",
        real_time=False,
        stepped=True,
    )
    system = build_system(description, start=True)
    web = WebConsole(system.handle, WebOptions(port=0), hand_mtms=("MTMR",)).start()
    yield web, system
    web.stop()
    system.stop()


def advance(page: Page, seconds: float) -> dict:
    """``advance`` by ``seconds``: the state there (the last before ``advanced``; states on
    the way may come before it), with ``advanced``'s tick."""
    page.send(op="advance", seconds=seconds)
    messages = [page.receive()]
    while messages[-1]["op"] != "advanced":
        messages.append(page.receive())
    assert messages[-2]["op"] == "state", messages[-2]
    return {**messages[-2], "tick": messages[-1]["tick"]}


def test_a_stepped_console_ticks_what_a_page_asks_and_answers_with_the_state_there(stepped):
    """``advance``: the simulated time the page asks for passes, no more; the page gets the
    state there before ``advanced`` (the other pages get the state too); the hand's
    dead-man counts simulated time, so a page that holds a key sends its input again
    before each advance (as the page's ``window.davinci.advance`` does)."""
    web, system = stepped
    page, other = Page(web), Page(web)
    try:
        assert page.hello["stepped"] is True
        first = page.next("state")
        time.sleep(0.3)  # (wall time passes; the simulation does not)
        assert system.handle.snapshot().time == pytest.approx(first["time"], abs=1e-9)
        there = advance(page, 0.25)
        assert there["time"] == pytest.approx(first["time"] + 0.25, abs=1e-9)
        assert there["tick"] == system.handle.snapshot().tick
        other.next("state", where=lambda m: m["time"] == there["time"])

        page.take_control()
        hand = lambda m: np.array(m["hands"]["MTMR"]["target"])  # noqa: E731
        start = advance(page, 0.01)
        # One input, then 1 s: the hand moves 0.3 s of it (its dead-man), then stops ...
        page.send(op="input", mtm="MTMR", axes=[0, 0, 1])
        once = advance(page, 1.0)
        # ... held back out through 0.6 s, sent again before each 0.1 s: all the way.
        for _ in range(6):
            page.send(op="input", mtm="MTMR", axes=[0, 0, -1])
            held = advance(page, 0.1)
        page.send(op="input", mtm="MTMR", axes=[0, 0, 0])
        speed = web.options.hand_speed  # m/s at full input, along the camera's z ("in")
        assert hand(once)[2] - hand(start)[2] == pytest.approx(0.3 * speed, rel=0.1)
        assert hand(held)[2] - hand(once)[2] == pytest.approx(-0.6 * speed, rel=0.1)
    finally:
        page.close()
        other.close()
