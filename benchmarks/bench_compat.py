"""The crtk/dvrk compatibility layer (``davinci-sim run``): what a dVRK script sees, over the
in-process bridge (no socket) and the rosbridge server (a websocket, same process).

For each transport, with the ``psm1`` scene in a real-time thread runner and PSM1 homed:

* ``check_connections_s`` — ``psm.check_connections()`` of a fresh ``dvrk.psm``;
* ``servo_latency`` — ``servo_jp`` published until ``setpoint_jp()`` (the arm's published
  setpoint, read as a script reads it) shows it, ms, 40 samples;
* ``stream_rate_hz`` — the rate a 200 Hz ``servo_jp`` loop (``ral.create_rate``) achieves
  over 2 s, and ``sim_over_wall`` the simulation's speed meanwhile;
* ``measured_cp_call`` — one ``measured_cp()`` call (the PyKDL frame from the last message), µs;
* ``state_age`` — wall clock minus the stamp of ``measured_js`` when read, ms (how old what
  a script reads is: the 100 Hz publish period plus the transport).
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np

from common import machine, summary, time_each, write
from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.server import RosbridgeServer
from davinci_sim.compat import dvrk_api as dvrk
from davinci_sim.compat import ral as ral_module
from davinci_sim.compat.inprocess import InProcessBridge, dvrk_nodes
from davinci_sim.compat.transport import RosbridgeClient, WebSocketConnection
from davinci_sim.system import SystemDescription, build_system


def measure(system, client, name: str) -> dict:
    ral_module.set_client(client)
    ral = ral_module.ral(f"bench_{name}")
    psm = dvrk.psm(ral, "PSM1")
    t0 = time.perf_counter()
    psm.check_connections(10)
    figures = {"check_connections_s": time.perf_counter() - t0}
    assert psm.enable(10) and psm.home(30)
    start = np.array([0.0, 0.0, 0.12, 0.0, 0.0, 0.0])
    psm.move_jp(start).wait()

    latencies = []
    goal = start.copy()
    for i in range(40):
        goal[0] = math.radians(0.5) * (i % 2)
        t0 = time.perf_counter()
        psm.servo_jp(goal)
        while abs(psm.setpoint_jp()[0][0] - goal[0]) > 1e-9:
            time.sleep(0.0002)
        latencies.append((time.perf_counter() - t0) * 1e6)
        time.sleep(0.05)
    figures |= summary(latencies, "servo_latency")

    rate = ral.create_rate(200)
    n = 400
    wall0, sim0 = time.perf_counter(), system.handle.snapshot().time
    for i in range(n):
        goal[0] = math.radians(3.0) * (1 - math.cos(2 * math.pi * i / n))
        psm.servo_jp(goal)
        rate.sleep()
    wall = time.perf_counter() - wall0
    figures["stream_rate_hz"] = n / wall
    figures["sim_over_wall"] = (system.handle.snapshot().time - sim0) / wall

    figures |= summary(time_each(psm.measured_cp, 2000), "measured_cp_call")
    ages = []
    for _ in range(200):
        _, t = psm.measured_jp()
        ages.append((time.time() - t) * 1000.0)
        time.sleep(0.003)
    figures["state_age_median_ms"] = statistics.median(ages)
    figures["state_age_max_ms"] = max(ages)
    return figures


def main() -> None:
    description = SystemDescription(scene="psm1", runner="thread", snapshot_period=0.01)
    system = build_system(description, start=True)
    in_process = InProcessBridge(system.handle).start()
    server = RosbridgeServer(BridgeConfig(port=0), nodes=dvrk_nodes(system.handle)).start()
    figures: dict = {"machine": machine()}
    try:
        for name, connect in (("in_process", in_process.connect),
                              ("rosbridge", lambda: WebSocketConnection(server.url))):  # fmt: skip
            client = RosbridgeClient(connect())
            try:
                figures[name] = measure(system, client, name)
            finally:
                ral_module.set_client(None)
                client.close()
            print(name, {k: round(v, 3) for k, v in figures[name].items()})
    finally:
        system.stop()
        in_process.stop()
        server.stop()
    write("compat", figures)


if __name__ == "__main__":
    main()
