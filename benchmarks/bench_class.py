"""How many trainees one machine holds: ``davinci-sim class`` with N trainees, each with a
page connected, every loop at >= 995 Hz.

For N = 1, 2, … the class starts (the seed's task, each loop process on SCHED_FIFO as
``make run`` asks), and each trainee's page is a websocket client that asks for the view the
page draws itself (the scene, then pose and state messages, read and dropped: the drawing is
the trainee's browser's, on the trainee's machine). Once every system is ready and has run
``settle`` s, for ``seconds`` s the benchmark reads the simulation time in each system's state
messages: the simulated seconds per wall second over that window, times 1000, is the loop's
achieved rate (the loop ticks 1 ms of simulation per tick), and the pose messages each page
got per second (what its drawing can show: a page draws a frame per pose message). Then the
class stops and each loop's own figures over its whole run (start-up included) are kept too.
N grows until a system's loop falls under ``min_hz`` or its page gets fewer than
``min_poses`` pose messages a second (the loops run on SCHED_FIFO and hold longest; the
servers' page streams starve first); the figure is the largest N that held, per core, and
that rate extrapolated to a 32-core server (the systems share nothing but the cores).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import threading
import time

from common import machine, write


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Page:
    """A trainee's page as the server sees it: hello, the page's own view, states read."""

    def __init__(self, port: int) -> None:
        from websockets.sync.client import connect

        self.ws = connect(f"ws://127.0.0.1:{port}/ws", open_timeout=30, max_size=None)
        self.ws.send(json.dumps({"op": "hello"}))
        self.ws.send(json.dumps({"op": "view", "stereo": False, "source": "page"}))
        self.last: tuple[float, float] | None = None  # (wall s, sim time s)
        self.bytes = 0
        self.poses = 0
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                m = self.ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            except Exception:
                return
            self.bytes += len(m)
            self.poses += isinstance(m, bytes)
            if isinstance(m, str):
                message = json.loads(m)
                if message.get("op") == "state":
                    self.last = (time.monotonic(), message["time"])

    def close(self) -> None:
        self._stop.set()
        self.ws.close()
        self.thread.join(2)


def run(n: int, seconds: float, settle: float, task: str, priority: int | None) -> dict:
    from davinci_sim.web.classroom import ClassOptions, Classroom

    names = tuple(f"trainee-{k + 1}" for k in range(n))
    room = Classroom(ClassOptions(names, task=task, port=_free_port(),
                                  realtime_priority=priority)).start()  # fmt: skip
    pages: list[_Page] = []
    try:
        if not room.wait_ready(600):
            raise RuntimeError(f"the class of {n} did not start: {room.status()}")
        pages = [_Page(s["port"]) for s in room.status()]
        time.sleep(settle)
        start = [p.last for p in pages]
        bytes0 = [p.bytes for p in pages]
        poses0 = [p.poses for p in pages]
        time.sleep(seconds)
        end = [p.last for p in pages]
        rates = []
        for a, b in zip(start, end, strict=True):
            if a is None or b is None or b[0] <= a[0]:
                rates.append(float("nan"))
            else:
                rates.append(round(1000.0 * (b[1] - a[1]) / (b[0] - a[0]), 1))
        page_kbps = [
            round((p.bytes - b) / seconds / 1000, 1) for p, b in zip(pages, bytes0, strict=True)
        ]
        poses_hz = [round((p.poses - b) / seconds, 1) for p, b in zip(pages, poses0, strict=True)]
    finally:
        for p in pages:
            p.close()
        final = room.stop()
    return {
        "trainees": n,
        "loop_hz_in_window": rates,
        "page_kB_per_s": page_kbps,
        "pose_messages_per_s": poses_hz,
        "loop_over_whole_run": [
            next((x for x in s["notes"] if x.startswith("loop: ")), "") for s in final
        ],  # fmt: skip
    }


def main(seconds: float = 30.0, settle: float = 10.0, max_n: int = 8, min_hz: float = 995.0,
         min_poses: float = 30.0,
         task: str = "seed_path", priority: int | None = 50) -> dict:  # fmt: skip
    result: dict = {"machine": machine(), "seconds": seconds, "task": task, "runs": []}
    held = 0
    for n in range(1, max_n + 1):
        r = run(n, seconds, settle, task, priority)
        result["runs"].append(r)
        print(r, flush=True)
        if not all(hz >= min_hz for hz in r["loop_hz_in_window"]):
            break
        if not all(hz >= min_poses for hz in r["pose_messages_per_s"]):
            break
        held = n
    cores = os.cpu_count() or 1
    result["trainees_held"] = held
    result["trainees_per_core"] = held / cores
    result["extrapolated_32_cores"] = int(32 * held / cores)
    result["target"] = f"every loop >= {min_hz} Hz, every page >= {min_poses} pose messages/s"
    write("class", result)
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--max", type=int, default=8, dest="max_n")
    a = parser.parse_args()
    print(main(a.seconds, max_n=a.max_n))
