"""A script at the page of a stepped console (``serve --stepped``): what one look costs.

``serve --task needle_targeting --stepped`` as the browser tests serve an exercise (PSM1, the
ECM and MTMR, the loop in its own process, ticking only what a page asks for; the web
console drawing 10 poses a second), one headless Chromium page (Playwright, the system's
Chromium) that draws the endoscope itself. The page takes control and waits until the
teleoperation follows; then, a move key held, it calls ``window.davinci.advance(dt)``
``looks`` times for each ``dt`` and reads the state it resolves with (what a scripted
person does at each look). Written for each ``dt``:

- ``dt_<ms>ms_page_ms_p50``: the wall time of one look (the page's input sent again, the
  advance, the state back to the script), and ``…_page_sim_over_wall``: simulated over
  wall seconds;
- ``dt_<ms>ms_loop_ms_p50``: the same advance asked of the loop process directly (no page,
  no web server: the simulation's own share), and ``…_loop_sim_over_wall``.

A script that looks every ``dt`` of simulated time runs faster than real time only where
``page_sim_over_wall`` > 1.
"""

from __future__ import annotations

import json
import shutil
import statistics
import threading
import time

from common import write

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update",
                 "--disable-sync"]  # fmt: skip
#: Simulated time between two looks, s.
STEPS = (0.001, 0.01, 0.04, 0.2)


def main(looks: int = 40) -> dict:
    from playwright.sync_api import sync_playwright

    from davinci_sim.bridge.app import ServeOptions, serve
    from davinci_sim.bridge.rosbridge.config import BridgeConfig
    from davinci_sim.web.app import web_part
    from davinci_sim.web.server import WebOptions

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("bench_stepped needs Chromium (scripts/system-deps.sh installs it)")
    options = ServeOptions(scene="psm1_ecm_mtmr", task="needle_targeting", home=True,
                           runner="process", real_time=False, stepped=True, images="none",
                           bridge=BridgeConfig(port=0), hand_inputs=("MTMR",), render_hz=10.0,
                           frame_task=True)  # fmt: skip
    got: dict = {}
    make_web = web_part(WebOptions(port=0, frame_rate=10.0, pose_rate=10.0), bedside=False)

    def part(system, info):
        got["handle"] = system.handle
        return make_web(system, info)

    stop = threading.Event()
    info: dict = {}
    thread = threading.Thread(target=lambda: serve(options, stop=stop, on_ready=info.update,
                                                   parts=[part]))  # fmt: skip
    thread.start()
    while "web" not in info and thread.is_alive():
        time.sleep(0.1)
    result: dict = {"looks": looks}
    look = "(s) => window.davinci.advance(s).then((state) => JSON.stringify(state))"
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": 1280, "height": 860})
            page.goto(info["web"])
            page.wait_for_function("window.davinci.last !== null", timeout=120e3)
            state = json.loads(page.evaluate(look, 0.2))
            while state["task"]["phase"] != "READY" and state["time"] < 60:
                state = json.loads(page.evaluate(look, 0.2))
            page.click("#control")
            page.wait_for_function("window.davinci.operator === window.davinci.client")
            page.click("#screen")
            while not state["teleops"]["MTMR_PSM1"]["following"] and state["time"] < 120:
                state = json.loads(page.evaluate(look, 0.2))
            for dt in STEPS:
                page_ms, loop_ms = [], []
                for i in range(looks):  # (back and forth: the hand stays in reach)
                    key = "KeyA" if (i // 10) % 2 else "KeyD"
                    page.keyboard.down(key)
                    t0 = time.perf_counter()
                    json.loads(page.evaluate(look, dt))
                    page_ms.append(1e3 * (time.perf_counter() - t0))
                    page.keyboard.up(key)
                for _ in range(looks):
                    t0 = time.perf_counter()
                    got["handle"].advance(dt).result(60)
                    loop_ms.append(1e3 * (time.perf_counter() - t0))
                page_p50, loop_p50 = statistics.median(page_ms), statistics.median(loop_ms)
                label = f"dt_{1e3 * dt:g}ms"
                result[f"{label}_page_ms_p50"] = page_p50
                result[f"{label}_page_sim_over_wall"] = 1e3 * dt / page_p50
                result[f"{label}_loop_ms_p50"] = loop_p50
                result[f"{label}_loop_sim_over_wall"] = 1e3 * dt / loop_p50
                print(f"dt {dt:5.3f} s: a look {page_p50:6.1f} ms "
                      f"({1e3 * dt / page_p50:5.2f}x real time), the loop alone "
                      f"{loop_p50:6.1f} ms ({1e3 * dt / loop_p50:5.2f}x)", flush=True)  # fmt: skip
            browser.close()
    finally:
        stop.set()
        thread.join(60)
    write("stepped_page", result)
    return result


if __name__ == "__main__":
    main()
