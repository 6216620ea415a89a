"""The newcomer's path in Chromium: ``make run`` serves the console (``serve --task seed_path
--home --realtime-priority 50``: the full system, both hands on keys, stereo images, real
time, the loop in its own process), a person takes control, reads the keys for several
seconds, then drives the tool with a key. The options are the CLI's own
(:func:`davinci_sim.cli.serve_setup`); only the ports differ (any free one; the trainee
records go to the test session's temporary file, ``tests/conftest.py``). Waits are on
simulated time."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("playwright.sync_api")

from playwright.sync_api import sync_playwright  # noqa: E402
from serving import serving  # noqa: E402
from test_web_browser import CHROMIUM, CHROMIUM_ARGS, Console  # noqa: E402

from davinci_sim.cli import build_parser, serve_setup  # noqa: E402

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed")

#: The Makefile's ``run`` target's arguments, then free ports.
MAKE_RUN = ["serve", "--task", "seed_path", "--home", "--realtime-priority", "50"]
HERE = ["--port", "0", "--web-port", "0"]


@pytest.fixture(scope="module")
def make_run():
    """What ``make run`` serves; the exercises a page chooses are kept in ``info["chosen"]``
    (``serve`` would restart with one: :func:`davinci_sim.cli.serve`)."""
    chosen: list[str] = []

    def on_exercise(name: str) -> None:
        chosen.append(name)

    args = build_parser().parse_args(MAKE_RUN + HERE)
    options, parts = serve_setup(args, web=True, on_exercise=on_exercise)
    with serving(options, parts, start_timeout=180) as info:
        yield {**info, "chosen": chosen}


@pytest.fixture(scope="module")
def chromium():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def test_the_makefile_serves_what_this_test_serves():
    from pathlib import Path

    makefile = (Path(__file__).resolve().parents[2] / "Makefile").read_text()
    assert "davinci-sim " + " ".join(MAKE_RUN) in makefile


def test_take_control_wait_then_the_tool_follows_the_keys_without_a_fault(
    make_run, chromium, tmp_path
):
    page = Console(chromium, make_run["web"])
    try:
        # The session frames the view and brings the tool to point 1 first.
        page.wait("window.davinci.last.task && window.davinci.last.arms.PSM1.homed", 180)
        page.take_control()
        page.page.click("#screen")
        following = (
            "window.davinci.last.teleops.MTMR_PSM1.following && "
            "window.davinci.last.teleops.MTML_PSM2.following"
        )
        page.wait(following, 180)
        before = page.wait_sim(5.0)  # a person reads the keys before pressing one
        assert before["arms"]["PSM1"]["state"] == "ENABLED", before["arms"]
        assert before["problems"] == [] and page.js(following)
        page.page.keyboard.down("KeyD")
        page.wait_sim(1.5)
        page.page.keyboard.up("KeyD")
        after = page.wait_sim(1.0)
        assert after["arms"]["PSM1"]["state"] == "ENABLED" and after["problems"] == []
        tool = np.subtract(after["tips"]["PSM1"]["p_camera"], before["tips"]["PSM1"]["p_camera"])
        # Right in the image is the camera's -x (dvrk.md 1.6).
        assert tool[0] < -0.01, tool
        assert page.js("document.getElementById('problems').hidden")
        page.page.screenshot(path=str(tmp_path / "make_run_after_D.png"))
        assert page.errors == []
    finally:
        page.release()
        page.close()


def test_the_exercise_dropdown_shows_the_exercise_served(make_run, chromium):
    """A choice in the dropdown goes to the server, which restarts with it; until then, and
    when it is refused (the page does not operate), the dropdown shows the exercise served."""
    page = Console(chromium, make_run["web"])
    chosen = make_run["chosen"]
    try:
        page.wait("window.davinci.last.task !== null", 180)
        served = page.js("document.getElementById('exercise').value")
        assert served == "seed_path" and not page.js(
            "document.getElementById('exercise-row').hidden"
        )
        page.page.select_option("#exercise", "needle_drive")  # not the operator: refused
        page.wait("document.getElementById('messages').textContent.includes('take control')")
        assert page.js("document.getElementById('exercise').value") == served
        assert chosen == []
        page.take_control()
        page.page.select_option("#exercise", "needle_drive")
        page.wait("document.getElementById('messages').textContent.includes('switching to')")
        assert chosen == ["needle_drive"]
        assert page.js("document.getElementById('exercise').value") == served
        assert page.errors == []
    finally:
        page.release()
        page.close()
