"""The README's picture of the robot in a browser-based URDF viewer (docs/images/robot_viewer.png).

Starts ``davinci-sim serve`` (the full system, arms homed, no images), serves
``examples/robot_viewer.html`` (roslibjs + urdf-loader + three.js: the robot from
``/robot_description``, posed from ``/joint_states``) and takes a screenshot in headless
Chromium once the robot is drawn and moving. The page's libraries come from a local
``node_modules`` folder (``npm install three@0.160.0 urdf-loader@0.13.1 roslib@1.4.1``)::

    python scripts/robot_viewer_screenshot.py --modules path/to/node_modules
"""

from __future__ import annotations

import argparse
import functools
import http.server
import shutil
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOFTWARE_GL = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--modules", required=True, help="node_modules with three, urdf-loader, roslib"
    )
    parser.add_argument("--output", default=str(ROOT / "docs" / "images" / "robot_viewer.png"))
    parser.add_argument("--scene", default="full")
    parser.add_argument("--size", default="1280x720", help="viewport, pixels")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    from davinci_sim.bridge.app import ServeOptions, serve
    from davinci_sim.bridge.rosbridge.config import BridgeConfig

    width, height = (int(x) for x in args.size.split("x"))
    ready: dict = {}
    stop = threading.Event()
    options = ServeOptions(scene=args.scene, images="none", home=True,
                           bridge=BridgeConfig(port=0))  # fmt: skip
    thread = threading.Thread(target=lambda: serve(options, stop=stop, on_ready=ready.update))
    thread.start()
    with tempfile.TemporaryDirectory() as tmp:
        site = Path(tmp)
        shutil.copy(ROOT / "examples" / "robot_viewer.html", site / "robot_viewer.html")
        (site / "node_modules").symlink_to(Path(args.modules).resolve())
        handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=tmp)
        httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        threading.Thread(target=httpd.serve_forever, daemon=True).start()
        try:
            deadline = time.monotonic() + 60
            while "url" not in ready and time.monotonic() < deadline:
                time.sleep(0.1)
            ws = ready["url"]
            page_url = (f"http://127.0.0.1:{httpd.server_port}/robot_viewer.html"
                        f"?url={ws}&modules=/node_modules/")  # fmt: skip
            with sync_playwright() as p:
                chromium = shutil.which("chromium") or shutil.which("chromium-browser")
                browser = p.chromium.launch(executable_path=chromium, args=SOFTWARE_GL)
                page = browser.new_page(viewport={"width": width, "height": height})
                page.on("console", lambda m: print("page:", m.text))
                page.goto(page_url)
                page.wait_for_function(
                    "window.viewerState && window.viewerState.links > 0 "
                    "&& window.viewerState.jointStates > 50",
                    timeout=120_000,
                )
                time.sleep(3.0)  # the arms finish homing
                page.screenshot(path=args.output)
                state = page.evaluate(
                    "({links: viewerState.links, joints: viewerState.joints, "
                    "tf: viewerState.tfFrames.size})"
                )
                print(f"{args.output}: {state}")
                browser.close()
        finally:
            httpd.shutdown()
            stop.set()
            thread.join(30)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
