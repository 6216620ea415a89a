"""Taking control of the console that ``make run`` serves, as a person does: the full system,
the seed's path, both hands, then a pause to read the keys before pressing one. Seen from a
page's websocket against the same system on a thread runner (as fast as it goes: the test
waits on simulated time); ``test_web_make_run.py`` does it in Chromium against ``serve``."""

from __future__ import annotations

import numpy as np
import pytest
from test_web_server import Page  # (the page's websocket, as the server tests use it)

from davinci_sim.system import ConsoleDescription, SystemDescription, TaskDescription, build_system
from davinci_sim.system.build import load_description_task
from davinci_sim.tasks.session import VIEW_DISTANCE
from davinci_sim.web.server import WebConsole, WebOptions

HANDS = ("MTML", "MTMR")


@pytest.fixture(scope="module")
def console():
    """What ``make run`` builds (``serve --task seed_path --home``: full scene, both hands
    on keys, the view framed), without images and with a thread runner."""
    description = SystemDescription(
        scene="full",
        home=True,
        task=TaskDescription("seed_path", frame_view=VIEW_DISTANCE),
        console=ConsoleDescription(hand_inputs=HANDS),
        runner="thread",
        real_time=False,
    )
    system = build_system(description, start=True)
    web = WebConsole(
        system.handle,
        WebOptions(port=0, state_rate=30.0),
        task=load_description_task(description),
        hand_mtms=HANDS,
    ).start()
    yield web, system
    web.stop()
    system.stop()


def wait_state(page: Page, where, seconds: float, errors: list | None = None) -> dict:
    """The first state within ``seconds`` of simulated time that satisfies ``where``
    (AssertionError if none), those that arrived while the test was not reading included;
    the error messages on the way (those too) are added to ``errors``."""
    t0 = None
    backlog = True
    while True:
        try:
            s = page.receive(timeout=0 if backlog else 300.0)
        except TimeoutError:  # (the backlog read: from now on, wait for what comes)
            backlog = False
            continue
        if isinstance(s, bytes):
            continue
        if s["op"] == "error" and errors is not None:
            errors.append(s["message"])
        if s["op"] != "state":
            continue
        t0 = s["time"] if t0 is None else t0
        if where(s) or s["time"] > t0 + seconds:
            break
    assert where(s), f"not within {seconds} s of simulated time: {s['arms']} {s['teleops']}"
    return s


def following(s: dict) -> bool:
    return all(s["teleops"][n]["following"] for n in ("MTMR_PSM1", "MTML_PSM2"))


def test_a_person_who_waits_after_taking_control_keeps_the_tools_still(console):
    web, _ = console
    page = Page(web)
    try:
        wait_state(page, lambda s: s["arms"]["PSM1"]["homed"] and s["task"]["phase"], 60)
        page.take_control()
        start = wait_state(page, following, 30)
        assert all(page.latest_state()["hands"][m]["holding"] for m in HANDS)
        # A person reads the keys for several seconds before pressing one.
        t0 = start["time"]
        late = page.next("state", 300, lambda m: m["time"] > t0 + 6.0)
        assert {late["arms"][a]["state"] for a in ("PSM1", "PSM2", "MTMR", "MTML")} == {"ENABLED"}
        assert following(late) and late["problems"] == []
        for psm in ("PSM1", "PSM2"):
            moved = np.subtract(late["tips"][psm]["p_camera"], start["tips"][psm]["p_camera"])
            assert np.linalg.norm(moved) < 0.002, psm
    finally:
        page.send(op="control", take=False)
        page.close()


def psm1_faulted_and_not_followed(s: dict) -> bool:
    return s["arms"]["PSM1"]["state"] == "FAULT" and not s["teleops"]["MTMR_PSM1"]["following"]


def test_a_fault_is_shown_with_its_reason_and_recovered_in_one_click(console):
    web, system = console
    page = Page(web)
    try:
        page.take_control()
        wait_state(page, following, 30)
        # A hand shoves the handle (40 N): the tool is driven faster than PSM1 can follow.
        system.handle.call("MTMR/device", "push", [0.0, 0.0, -40.0]).result(10)
        errors: list[str] = []
        # (the teleoperation sees the fault on its next tick: a state may fall between the two)
        faulted = wait_state(page, psm1_faulted_and_not_followed, 30, errors)
        system.handle.call("MTMR/device", "push", [0.0, 0.0, 0.0]).result(10)
        shown = wait_state(
            page, lambda s: "MTMR" in {p["source"] for p in s["problems"]}, 2, errors
        )
        assert any(e.startswith("PSM1: tracking error") for e in errors), errors
        fault = next(p for p in shown["problems"] if p["source"] == "PSM1")
        assert fault["kind"] == "fault" and "tracking error" in fault["reason"]
        # (the MTM, held where it was when its teleoperation stopped, faulted under the push)
        assert not faulted["teleops"]["MTMR_PSM1"]["following"]
        page.send(op="recover")
        back = wait_state(page, lambda s: following(s) and s["arms"]["PSM1"]["homed"], 60)
        assert back["arms"]["PSM1"]["state"] == "ENABLED" and back["problems"] == []
    finally:
        page.send(op="control", take=False)
        page.close()


def test_only_the_operator_can_recover(console):
    web, _ = console
    operator, watcher = Page(web), Page(web)
    try:
        operator.take_control()
        watcher.send(op="recover")
        assert "take control first" in watcher.next("error")["message"]
    finally:
        operator.send(op="control", take=False)
        operator.close()
        watcher.close()
