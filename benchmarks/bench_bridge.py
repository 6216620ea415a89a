"""rosbridge server: publish-to-receive latency of measured_js, and the highest sustained rate
of 7 arms' measured_js to 4 subscribers while the 1 kHz loop keeps real time.

The clients run in a separate process (a lean websockets client speaking rosbridge JSON), so
they do not share the server's interpreter lock. Latency = arrival time at the client minus the
header stamp, which the server sets (wall clock) when it builds the message. The loop's period
is measured by a probe component in the simulation (wall time at each tick).

Three set-ups for the rate: the whole simulator with the in-process ``ThreadedSimulation``
(the loop, its snapshots and the bridge share one interpreter), the same with the loop in its
own process (issue 3's ``ProcessSimulation``, when present), and the bridge alone fed from a
fixed snapshot (what the server itself sustains).
"""

from __future__ import annotations

import functools
import json
import statistics
import subprocess
import sys
import time

from common import RESULTS, write
from davinci_sim.bridge import BridgeConfig, RosbridgeServer
from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.bridge.endoscope import EndoscopeNode, QposProbe
from davinci_sim.sim.handle import ThreadedSimulation, take_snapshot
from davinci_sim.sim.simulation import Simulation

ARMS = ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR", "SUJ/PSM1")

CLIENT = r"""
import asyncio, json, sys, time
from websockets.asyncio.client import connect

url, topics = sys.argv[1], sys.argv[2].split(",")
n_clients, seconds, warmup = int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5])

async def one(k, out):
    counts = {t: 0 for t in topics}
    lat = []
    async with connect(url, compression=None, max_size=None, max_queue=None) as ws:
        for t in topics:
            await ws.send(json.dumps({"op": "subscribe", "topic": t, "id": f"{k}:{t}"}))
        t_start = time.time() + warmup
        t_end = t_start + seconds
        while True:
            left = t_end - time.time()
            if left <= 0:
                break
            try:
                data = await asyncio.wait_for(ws.recv(), left)
            except asyncio.TimeoutError:
                break
            now = time.time()
            if now < t_start:
                continue
            # the topic without decoding the whole message: '{"op":"publish","topic":"/..."'
            i = data.index('"topic":"') + 9
            topic = data[i:data.index('"', i)]
            counts[topic] += 1
            if k == 0 and topic == topics[0]:
                s = json.loads(data)["msg"]["header"]["stamp"]
                lat.append(now - (s["sec"] + 1e-9 * s["nanosec"]))
    out[k] = {"counts": counts, "latency": lat}

async def main():
    out = {}
    await asyncio.gather(*(one(k, out) for k in range(n_clients)))
    print(json.dumps(out))

asyncio.run(main())
"""


class TickProbe:
    """A simulation component recording the wall time of every tick."""

    name = "probe"

    def __init__(self) -> None:
        self.times: list[float] = []

    def pre_step(self, t: float) -> None:
        self.times.append(time.perf_counter())

    def snapshot(self) -> None:
        return None


class FixedHandle:
    """A handle whose snapshot never changes: the bridge alone, without a simulation loop."""

    def __init__(self, snap) -> None:
        self._snap = snap

    def snapshot(self):
        return self._snap

    def subscribe(self, callback):
        return lambda: None

    def call(self, *args, **kwargs):
        raise RuntimeError("no simulation")


def run_clients(url: str, topics, n_clients: int, seconds: float, warmup: float = 1.0) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", CLIENT, url, ",".join(topics), str(n_clients), str(seconds),
         str(warmup)],
        capture_output=True, text=True, timeout=seconds + warmup + 60, check=True,
    )  # fmt: skip
    return json.loads(out.stdout)


def percentile(values, q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))] if s else float("nan")


def loop_figures(probe: TickProbe, t0: float, t1: float) -> dict:
    times = [t for t in probe.times if t0 <= t <= t1]
    periods = [1000 * (b - a) for a, b in zip(times, times[1:], strict=False)]
    if not periods:
        return {}
    return {
        "loop_rate_hz": (len(times) - 1) / (times[-1] - times[0]),
        "loop_period_p50_ms": statistics.median(periods),
        "loop_period_p99_ms": percentile(periods, 0.99),
        "loop_period_max_ms": max(periods),
    }


def measure(handle, rate: float, n_clients: int, seconds: float, probe=None) -> dict:
    server = RosbridgeServer(BridgeConfig(port=0), nodes=[DvrkNode(handle, rate=rate)]).start()
    try:
        topics = [f"/{a}/measured_js" for a in ARMS]
        t0 = time.perf_counter() + 1.0
        result = run_clients(server.url, topics, n_clients, seconds)
        t1 = t0 + seconds
        stats = server.stats()
    finally:
        server.stop()
    received = [sum(r["counts"].values()) for r in result.values()]
    expected = rate * len(topics) * seconds
    lat = [1000 * x for x in result["0"]["latency"]]
    out = {
        "rate_hz": rate,
        "received_fraction_min": min(received) / expected,
        "dropped": sum(s["dropped"] for s in stats["sessions"]),
        "latency_p50_ms": statistics.median(lat) if lat else float("nan"),
        "latency_p99_ms": percentile(lat, 0.99),
    }
    if probe is not None:
        out.update(loop_figures(probe, t0, t1))
    return out


def sustained(rows: list[dict], with_loop: bool) -> float:
    """Highest rate with >= 95 % delivered to every client, nothing dropped (queues did not
    overflow) and, with the simulation, the loop still at >= 995 Hz (real time)."""
    best = 0.0
    for r in rows:
        ok = r["received_fraction_min"] >= 0.95 and r["dropped"] == 0
        if with_loop:
            ok = ok and r.get("loop_rate_hz", 0) >= 995
        if ok:
            best = max(best, r["rate_hz"])
    return best


def measure_images(seconds: float) -> dict:
    """Stereo JPEG at 30 Hz plus measured_js at 100 Hz to one client, full scene."""
    sim = Simulation("full", keyframe="surgical")
    probe = TickProbe()
    sim.add_component(probe)
    sim.add_component(QposProbe(sim))
    handle = ThreadedSimulation(sim, real_time=True, snapshot_period=0.01).start()
    endo = EndoscopeNode(handle, "full", rate=30.0)
    server = RosbridgeServer(BridgeConfig(port=0), nodes=[DvrkNode(handle), endo]).start()
    try:
        topics = ["/PSM1/measured_js", "/jhu_daVinci/left/image_raw/compressed",
                  "/jhu_daVinci/right/image_raw/compressed"]  # fmt: skip
        t0 = time.perf_counter() + 3.0
        result = run_clients(server.url, topics, 1, seconds, warmup=3.0)  # render start-up
        loop = loop_figures(probe, t0, t0 + seconds)
        render_ms = 1000 * statistics.median(endo.render_times) if endo.render_times else 0.0
    finally:
        server.stop()
        handle.stop()
    counts = result["0"]["counts"]
    return {
        "images_left_per_s": counts[topics[1]] / seconds,
        "images_right_per_s": counts[topics[2]] / seconds,
        "images_render_encode_ms_p50": render_ms,
        **{f"images_{k}": v for k, v in loop.items()},
    }


FIRST_FRAME_CLIENT = r"""
import asyncio, json, sys, time
from websockets.asyncio.client import connect

url, topic, n = sys.argv[1], sys.argv[2], int(sys.argv[3])

async def main():
    out = []
    async with connect(url, compression=None, max_size=None) as ws:
        for k in range(n):
            await ws.send(json.dumps({"op": "subscribe", "topic": topic, "id": f"s{k}"}))
            t0 = time.perf_counter()
            while True:
                data = await asyncio.wait_for(ws.recv(), 120)
                if '"op":"publish"' in data[:40]:
                    break
            out.append(time.perf_counter() - t0)
            await ws.send(json.dumps({"op": "unsubscribe", "topic": topic, "id": f"s{k}"}))
            await asyncio.sleep(1.0)  # the node sees no subscriber, the renderer idles
            while True:  # drop what was queued before the unsubscribe took effect
                try:
                    await asyncio.wait_for(ws.recv(), 0.05)
                except asyncio.TimeoutError:
                    break
    print(json.dumps(out))

asyncio.run(main())
"""


def first_frames(url: str, n: int) -> list[float]:
    """Seconds from each of ``n`` subscriptions to the left JPEG topic to its first image
    message (one client in another process; unsubscribed for 1 s between)."""
    topic = "/jhu_daVinci/left/image_raw/compressed"
    out = subprocess.run([sys.executable, "-c", FIRST_FRAME_CLIENT, url, topic, str(n)],
                         capture_output=True, text=True, timeout=300, check=True)  # fmt: skip
    return json.loads(out.stdout)


def measure_first_frame(n: int = 5) -> dict:
    """Time to first frame (item 2 of issue 11): subscribe → first endoscope image, with the
    render pipeline started with the server. Two set-ups: the node's own render process
    (``serve --no-web``: thread runner, full scene) and ``serve``'s (the process runner
    renders at the image rate, as with the web console), each timed from start to its first
    frame too (``…_pipeline_start_s``: what a subscriber waited before, when the pipeline
    started at the first subscription)."""
    import threading

    from davinci_sim.bridge.app import ServeOptions, serve

    figures = {}
    for tag, runner, render_hz in (("node", "thread", None), ("runner", "process", 30.0)):
        ready, stop = {}, threading.Event()
        options = ServeOptions(scene="full", bridge=BridgeConfig(port=0), runner=runner,
                               render_hz=render_hz, images="jpeg")  # fmt: skip
        t0 = time.perf_counter()
        thread = threading.Thread(target=serve, args=(options,), daemon=True,
                                  kwargs={"stop": stop, "on_ready": ready.update})  # fmt: skip
        thread.start()
        try:
            while "url" not in ready:
                time.sleep(0.05)
            figures[f"first_frame_{tag}_serve_ready_s"] = time.perf_counter() - t0
            figures[f"first_frame_{tag}_pipeline_start_s"] = ready.get("first_frame_s", -1.0)
            times = [1000 * t for t in first_frames(ready["url"], n)]
        finally:
            stop.set()
            thread.join(60)
        figures[f"first_frame_{tag}_subscribe_to_image_ms_median"] = statistics.median(times)
        figures[f"first_frame_{tag}_subscribe_to_image_ms_max"] = max(times)
        print(tag, times, flush=True)
    figures["first_frame_subscriptions"] = n
    return figures


def measure_reader(n: int = 2000) -> dict:
    """What the process runner's reader spends per published state for a 1 kHz bridge: the
    snapshot of the full scene, every arm's operating state and 7 arms' ``measured_js``
    (computed on its mirror), in this process, µs (median of ``n``)."""
    import pickle
    import threading

    from davinci_sim.sim.runtime import process

    sim = Simulation("full")
    for _ in range(50):
        sim.tick()
    reader = process.ProcessSimulation.__new__(process.ProcessSimulation)
    reader._mirror = Simulation(sim.config)
    reader._mirror_lock = threading.Lock()
    reader._mirror_holds = None
    data = process._published_state(sim)
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        snap = reader._rebuild(pickle.loads(data[process.STATE_HEADER.size :]))
        for a in snap.arms.values():
            a.operating_state  # noqa: B018
        for name in ARMS:
            snap.arms[name].measured_js  # noqa: B018
        times.append(1e6 * (time.perf_counter() - t0))
    t0 = time.perf_counter()
    for _ in range(200):
        process._published_state(sim)
    loop_us = 1e6 * (time.perf_counter() - t0) / 200
    return {
        "process_reader_snapshot_7_arms_us_p50": statistics.median(times),
        "process_loop_publish_state_us_mean": loop_us,
    }


def main(seconds: float = 5.0) -> None:
    if "--first-frame" in sys.argv:  # only the time to first frame, into the last results
        figures = json.loads((RESULTS / "bridge.json").read_text())
        figures.pop("machine", None)
        figures.update(measure_first_frame())
        write("bridge", figures)
        return
    figures: dict = {}
    figures.update(measure_first_frame())
    figures.update(measure_reader())
    figures.update(measure_images(seconds))
    print(figures, flush=True)
    # -- the whole simulator: full scene, in-process loop -------------------------------
    rows = []
    for rate in (100.0, 250.0, 500.0, 1000.0):
        sim = Simulation("full")
        probe = TickProbe()
        sim.add_component(probe)
        handle = ThreadedSimulation(sim, real_time=True, snapshot_period=1.0 / rate).start()
        try:
            if rate == 100.0:  # latency at the dVRK's default rate, one subscriber
                one = measure(handle, rate, 1, seconds)
                figures["latency_100hz_p50_ms"] = one["latency_p50_ms"]
                figures["latency_100hz_p99_ms"] = one["latency_p99_ms"]
            probe.times.clear()
            rows.append(measure(handle, rate, 4, seconds, probe))
        finally:
            handle.stop()
        print(rows[-1], flush=True)
    for r in rows:
        tag = f"sim_{int(r['rate_hz'])}hz"
        for k, v in r.items():
            if k != "rate_hz":
                figures[f"{tag}_{k}"] = v
    figures["sustained_rate_7_arms_4_clients_with_sim_hz"] = sustained(rows, True)
    # -- the loop in its own process (issue 3's runner) ---------------------------------
    try:
        from davinci_sim.sim.runtime.process import ProcessSimulation
    except ImportError:
        ProcessSimulation = None
    if ProcessSimulation is not None:
        rows = []
        for rate in (100.0, 250.0, 500.0, 1000.0):
            handle = ProcessSimulation(functools.partial(Simulation, "full"),
                                       snapshot_period=1.0 / rate).start()  # fmt: skip
            try:
                time.sleep(1.0)
                before = handle.period_statistics()
                row = measure(handle, rate, 4, seconds)
                after = handle.period_statistics()
            finally:
                handle.stop()
            ticks = after.ticks - before.ticks
            row["loop_rate_hz"] = ticks / (after.elapsed - before.elapsed)
            row["loop_period_p99_ms"] = 1000 * after.period_p99
            row["loop_period_max_ms"] = 1000 * after.period_max
            rows.append(row)
            print(row, flush=True)
        for r in rows:
            tag = f"process_{int(r['rate_hz'])}hz"
            for k, v in r.items():
                if k != "rate_hz":
                    figures[f"{tag}_{k}"] = v
        figures["sustained_rate_7_arms_4_clients_process_runner_hz"] = sustained(rows, True)
    # -- the bridge alone ----------------------------------------------------------------
    sim = Simulation("full")
    handle = FixedHandle(take_snapshot(sim))
    rows = []
    for rate in (250.0, 500.0, 1000.0):
        rows.append(measure(handle, rate, 4, seconds))
        print(rows[-1], flush=True)
    for r in rows:
        tag = f"bridge_only_{int(r['rate_hz'])}hz"
        for k, v in r.items():
            if k != "rate_hz":
                figures[f"{tag}_{k}"] = v
    figures["sustained_rate_7_arms_4_clients_bridge_only_hz"] = sustained(rows, False)
    figures["latency_1khz_bridge_only_p50_ms"] = rows[-1]["latency_p50_ms"]
    figures["latency_1khz_bridge_only_p99_ms"] = rows[-1]["latency_p99_ms"]
    figures["seconds_per_point"] = seconds
    write("bridge", figures)


if __name__ == "__main__":
    main()
