"""A person drives the curved needle through the suture pad's marks in the web console
(``serve --task needle_drive``, both hands), doing only what a person at the page does: it
reads what the page shows (the state stream the heads-up display and the task panel are
drawn from: the tools, the needle where it is now, the pad's entry and exit marks) and
holds keys down and lets them go. The attempt ends scored in the page's task panel with the
pair passed and its entry and exit errors in mm.

Its own module (not ``test_web_exercises.py``'s) so that ``make test``'s workers, which
take whole files, run it beside the needle pick-up test rather than after it.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

pytest.importorskip("playwright.sync_api")

from test_web_exercises import (  # noqa: E402
    SIM_LIMIT,
    TURN_KEYS,
    Clutch,
    Person,
    _unit,
    browser,  # noqa: F401 (the module's browser fixture)
    keys_toward,
    person,  # noqa: F401 (the page fixture)
    screen,
    served,
    steer,
)

from davinci_sim.geometry.so3 import rotation_from_vector, rotation_vector  # noqa: E402
from davinci_sim.model.config import SceneConfig  # noqa: E402

#: The needle's plane tilted from the vertical about the marks' line while it goes through
#: (what the scripted expert does too: PSM1's jaws along its normal are then in reach).
TILT = math.radians(45.0)


def _rot(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about ``axis``."""
    return rotation_from_vector(angle * _unit(axis))


def _pose(R, p) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def tool(s: dict, psm: str) -> np.ndarray:
    """The tool's tip frame as the page shows it (camera frame): jaws along z, closing
    along y."""
    t = s["tips"][psm]
    z, y = np.array(t["z_camera"]), np.array(t["y_camera"])
    return _pose(np.column_stack([np.cross(y, z), y, z]), t["p_camera"])


def needle(s: dict) -> np.ndarray:
    """The needle's frame now (camera frame): centre at the middle of its ends (a half
    circle), x towards the swage, y towards the middle of its arc."""
    swage, top, point = (
        np.array(m["p_camera"]) for m in s["task"]["marks"]["needle"]["now"]["ends"]
    )
    c = (swage + point) / 2
    x, y = _unit(swage - c), _unit(top - c)
    return _pose(np.column_stack([x, y, np.cross(x, y)]), c)


def test_a_person_drives_the_needle_through_the_marks(browser, person):  # noqa: F811
    """The left hand takes the needle out of its foam block from above (PSM2's jaws across
    its plane), lifts it and tilts its plane 45° about the marks' line. The right hand
    takes it in a needle driver's grip near the swage (PSM1's jaws along the needle's
    normal, so that rolling the tool turns the needle in its plane); the left hand lets go.
    PSM1 brings the point just above the entry mark, the needle's circle through both
    marks, and turns it about its centre, 8° a step, until the point is out past the exit
    mark: the panel scores the pass with its entry and exit errors in mm."""
    scene = SceneConfig(arms=("PSM1", "PSM2", "ECM", "MTML", "MTMR"))
    with served("needle_drive", scene, hands=("MTML", "MTMR")) as url:
        p: Person = person(url)
        p.wait("window.davinci.last.task.phase === 'READY'")
        p.take_control()
        # (the panel shows no "deviation": the tool's distance from where the needle
        # started means nothing here)
        assert not p.page.is_visible("#deviation") and p.state()["task"]["distance"] is None
        s = p.state()
        marks = s["task"]["marks"]
        swage, top, point = (np.array(m["p_camera"]) for m in marks["needle"]["start"])
        radius = float(np.linalg.norm(swage - point)) / 2
        up = _unit(top - (swage + point) / 2)  # (it stands upright in its block)
        entry, exit_ = (np.array(marks["sutures"][0][k]["p_camera"]) for k in ("entry", "exit"))
        clutch = {"PSM1": Clutch("MTMR"), "PSM2": Clutch("MTML")}
        hand = {"PSM1": "MTMR", "PSM2": "MTML"}

        def use(psm: str) -> None:
            if p.page.input_value("#hand") != hand[psm]:
                p.tap("KeyH")
            assert p.page.input_value("#hand") == hand[psm]

        def go(psm, goal_of, tolerance=0.001, degrees=None, until=None, settle=None):
            """Steer ``psm``'s tool to ``goal_of(state)`` (4×4, camera frame): its
            position within ``tolerance`` (m) and, with ``degrees``, its orientation (or
            until ``until(state)``). With ``settle`` (s), a careful hand: there, the keys
            up and a look ``settle`` later; steered on if the tool has drifted out of the
            tolerance (what the page showed lags the loop on a busy machine, and keys held
            on a late look carry the tool on past its goal)."""
            print(f"-- {psm} t={p.state()['time']:.1f}")

            def errors(s):
                T, G = tool(s, psm), goal_of(s)
                return G[:3, 3] - T[:3, 3], rotation_vector(G[:3, :3] @ T[:3, :3].T)

            def step(s):
                e, w = errors(s)
                keys = keys_toward(screen(e), dead=0.5 * tolerance)
                if degrees is not None and math.degrees(np.linalg.norm(w)) > 0.5 * degrees:
                    keys |= keys_toward(screen(w), TURN_KEYS, dead=math.radians(0.5 * degrees),
                                        share=0.5)  # fmt: skip
                if np.linalg.norm(e) < 0.006 and (degrees is None or np.linalg.norm(w) < 0.2):
                    keys.add("ShiftLeft")
                return clutch[psm](s, keys, e)

            best = {"angle": math.inf, "since": None}

            def done(s):
                if until is not None and until(s):
                    return True
                e, w = errors(s)
                angle = math.degrees(np.linalg.norm(w))
                if angle < best["angle"] - 0.5:
                    best["angle"], best["since"] = angle, s["time"]
                # (a wrist that turns no further for 3 s, at a joint's end: the person takes
                # what it gives if that is within twice the angle they aimed for; a clean clone
                # once held the turn keys at 9.5° of a 6° aim until the test gave up)
                stuck = best["since"] is not None and s["time"] - best["since"] > 3.0
                limit = degrees if degrees is None or not stuck else 2 * degrees
                return np.linalg.norm(e) < tolerance and (degrees is None or angle < limit)

            try:
                s = steer(p, done, step, limit=2 * SIM_LIMIT)
                for _ in range(3 if settle else 0):
                    if until is not None and until(s):
                        break
                    s = wait(settle)
                    if done(s):
                        break
                    s = steer(p, done, step, limit=2 * SIM_LIMIT)
                return s
            except AssertionError:
                s = p.state()
                e, w = errors(s)
                arms = {k: v["state"] for k, v in s["arms"].items() if k.startswith("PSM")}
                raise AssertionError(f"{psm}: {1e3 * e} mm, {math.degrees(np.linalg.norm(w)):.1f}° "
                                     f"off (arms {arms}, t={s['time']:.1f} s, "
                                     f"{s['task']['progress']!r})") from None  # fmt: skip

        def wait(seconds: float) -> dict:
            p.hold(())
            t0 = p.state()["time"]
            return steer(p, lambda s: s["time"] - t0 > seconds, lambda s: set())

        def carry(psm, needle_goal, tolerance, degrees, until=None, settle=None):
            """Steer ``psm``, holding the needle, to the pose that puts it at
            ``needle_goal(state)`` (the needle's pose in the jaws read as it is now)."""

            def goal(s):
                return needle_goal(s) @ np.linalg.inv(needle(s)) @ tool(s, psm)

            return go(psm, goal, tolerance, degrees, until, settle)

        def close(psm: str) -> None:
            """E: the jaws close on the wire (stopped on it, not shut)."""
            p.tap("KeyE")
            jaw = wait(0.5)["tips"][psm]["jaw"]
            assert 0.0 < jaw < 0.8, (psm, jaw)

        # -- PSM1, brought to its start above the needle, first moves 15 mm to the right:
        # the needle will come up there
        T = tool(s, "PSM1")
        aside = _pose(T[:3, :3], T[:3, 3] + [-0.015, 0.0, 0.0])  # (camera x: the image's left)
        go("PSM1", lambda s: aside, 0.003)
        # -- the left hand: PSM2's jaws across the needle's plane, straight above its wire
        # 60 % of the way to the point, down until the wire is 8 mm into them, closed.
        use("PSM2")

        def above(s, fraction, depth):
            N, T = needle(s), tool(s, "PSM2")
            normal = N[:3, 2] if N[:3, 2] @ T[:3, 1] >= 0 else -N[:3, 2]
            # The jaws straight down onto the wire: not along the shaft (the tool straight,
            # its wrist at the roll's singularity, where the tilt below flipped the roll)
            z = _unit(-up - (-up @ normal) * normal)
            phi = math.pi * (0.5 - fraction)
            wire = N[:3, 3] + radius * (math.sin(phi) * N[:3, 0] + math.cos(phi) * N[:3, 1])
            return _pose(np.column_stack([np.cross(normal, z), normal, z]), wire - depth * z)

        go("PSM2", lambda s: above(s, 0.6, 0.020), 0.002, degrees=6)
        grip = above(p.state(), 0.6, 0.008)
        go("PSM2", lambda s: grip, 0.0012, degrees=6)
        close("PSM2")
        # -- lifted 20 mm, its plane tilted about the marks' line
        N0 = needle(p.state())
        lifted = _pose(_rot(exit_ - entry, TILT) @ N0[:3, :3], N0[:3, 3] + 0.020 * up)
        carry("PSM2", lambda s: lifted, 0.002, degrees=5)
        p.shot("needle_drive_lifted")

        # -- the right hand: PSM1's jaws along the needle's normal near the swage, the
        # wire 6 mm into them; closed; the left hand opens and backs off.
        use("PSM1")

        def driver(s, depth):
            N, T = needle(s), tool(s, "PSM1")
            z = N[:3, 2] if N[:3, 2] @ T[:3, 2] >= 0 else -N[:3, 2]
            phi = math.pi * (0.5 - 0.12)
            radial = math.sin(phi) * N[:3, 0] + math.cos(phi) * N[:3, 1]
            wire = N[:3, 3] + radius * radial
            return _pose(np.column_stack([np.cross(radial, z), radial, z]), wire - depth * z)

        go("PSM1", lambda s: driver(s, 0.018), 0.002, degrees=6)
        grip = driver(p.state(), 0.006)
        go("PSM1", lambda s: grip, 0.0012, degrees=6)
        close("PSM1")
        use("PSM2")
        p.tap("KeyE")
        s = wait(0.5)
        T, T1 = tool(s, "PSM2"), tool(s, "PSM1")
        back = _pose(T[:3, :3], T[:3, 3] - 0.012 * T[:3, 2])
        go("PSM2", lambda s: back, 0.003)
        # (and out of PSM1's way while it turns the needle: up, towards its own side)
        away = back[:3, 3] + 0.015 * up + 0.015 * _unit(T[:3, 3] - T1[:3, 3])
        go("PSM2", lambda s: _pose(back[:3, :3], away), 0.003)
        p.shot("needle_drive_driver_grip")

        # -- PSM1 drives it: the circle through both marks, its plane tilted, turned by
        # alpha about its centre (alpha = 0: the point level with the centre, over the
        # entry mark; it enters the skin at about 33°, comes out at about 147°)
        use("PSM1")
        half = float(np.linalg.norm(exit_ - entry)) / 2
        x = _unit(exit_ - entry)
        y = math.cos(TILT) * up - math.sin(TILT) * np.cross(up, x)
        centre = (entry + exit_) / 2 + math.sqrt(radius**2 - half**2) * y

        def drive(alpha: float) -> np.ndarray:
            return _pose(np.column_stack([x, y, np.cross(x, y)]) @ _rot([0, 0, 1], alpha), centre)

        above_start = drive(0.0)
        above_start[:3, 3] += 0.012 * up
        carry("PSM1", lambda s: above_start, 0.002, degrees=5)
        carry("PSM1", lambda s: drive(0.0), 0.0008, degrees=3, settle=0.3)
        p.shot("needle_drive_at_entry")

        def finished(s) -> bool:  # (the point out at the exit mark: the attempt is over)
            return s["task"]["phase"] != "RUNNING"

        for alpha in np.radians(np.arange(8.0, 206.0, 8.0)):
            s = carry("PSM1", lambda s, a=alpha: drive(a), 0.0006, 3, finished, 0.2)
            # (what the page shows of the point against the skin: in a failure's report, where
            # the drive went; the skin is level through the marks, `up` its normal)
            point = needle(s)[:3, 3] - radius * needle(s)[:3, 0]
            h = float((point - entry) @ up)
            off = float(np.linalg.norm(point - entry - h * up))
            print(
                f"-- turned {math.degrees(alpha):.0f}°: the point {1e3 * h:.1f} mm above the "
                f"skin, {1e3 * off:.1f} mm from the entry mark; {s['task']['progress']!r}"
            )
            if finished(s):
                break
        s = steer(p, lambda s: s["task"]["completed"] >= 1, lambda s: set())
        p.shot("needle_drive_scored")
        row = p.scored()
    print("the row:", {k: row[k] for k in ("passes", "entry_error", "exit_error", "tissue_trauma",
                                          "completion_time")})  # fmt: skip
    # The pass: its point in within 2.5 mm of the entry mark and out within 2.5 mm of the
    # exit mark (the passage law counts no other). Every entry was at the mark. The row's
    # exit error is the largest of the attempt's exits, and the first steps of the turn
    # bite only 0.6-1.7 mm deep (the needle's plane tilted 45°): a tool error of a key
    # held on a late look lifts the point back out now and then, counted as an exit of its
    # own once it is more than 2.5 mm from where it went in (CI, 2026-11-30: 15.2 mm from
    # the exit mark). That is the person's slip, scored as it should be: not asserted.
    assert (row["passes"], row["drops"], row["missed_targets"]) == (1, 0, 0), row
    assert row["entry_error"] < 0.0025 and math.isfinite(row["exit_error"]), row
    assert p.panel("result-score").startswith("attempt 1: score")
    shown = p.panel("result")
    for what in ("entry error", "exit error", "tissue trauma"):
        assert re.search(what + r"\s+\d+\.\d+ mm", shown), shown
