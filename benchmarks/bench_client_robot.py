"""Client mode's robot on the remote (bridge/client_robot.py): the bytes per second it sends
to the remote rosbridge for ``/tf`` and ``{ns}/joint_states`` at 50 Hz (what
``--no-robot-description`` saves), beside the arms' own state topics, and the CPU time of
one tick (building both messages).

Client mode runs against the built-in server standing in for the remote; every rosbridge
operation roslibpy sends is counted (its JSON text, the websocket payload, before framing)
per topic over ``SECONDS`` of real-time simulation; the bytes/s at the nominal rate are the
mean message size times 50 Hz (the measured rate falls short on a loaded machine). The
latched messages (descriptions, ``/tf_static``) go once at start and are reported in bytes,
not per second.
"""

from __future__ import annotations

import json
import threading
import time

from common import summary, time_each, write
from davinci_sim.bridge import BridgeConfig, RosbridgeServer
from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.runtime.render import QposProbe
from davinci_sim.sim.simulation import Simulation

SECONDS = 5.0
TF_RATE = 50.0


def measure(scene: str, ros_version: int) -> dict:
    sim = Simulation(scene)
    sim.add_component(QposProbe(sim))
    handle = ThreadedSimulation(sim, real_time=True, snapshot_period=0.001).start()
    server = RosbridgeServer(BridgeConfig(port=0, ros_version=ros_version)).start()
    config = ClientModeConfig(server.url, namespace="/sim", mtms=(), ros_version=ros_version,
                              tf_rate=TF_RATE)  # fmt: skip
    client = RosClientMode(handle, config)
    sent: dict[str, list[int]] = {}
    lock = threading.Lock()
    counting = {"on": True}
    try:
        import roslibpy

        original = roslibpy.Ros.send_on_ready

        def counted(ros, message):
            msg = dict(message)
            if msg.get("op") == "publish" and counting["on"]:
                n = len(json.dumps(msg).encode())
                with lock:
                    sent.setdefault(msg["topic"], []).append(n)
            return original(ros, message)

        roslibpy.Ros.send_on_ready = counted
        try:
            client.start()
            with lock:
                latched = {k: sum(v) for k, v in sent.items()}
                sent.clear()
            time.sleep(SECONDS)
            counting["on"] = False
            with lock:
                window = {k: list(v) for k, v in sent.items()}
        finally:
            roslibpy.Ros.send_on_ready = original
        robot = client.robot
        tick = time_each(lambda: robot.tick(handle.snapshot(), lambda *a: None), 200)
    finally:
        client.stop()
        server.stop()
        handle.stop()
    rate = {k: sum(v) / SECONDS for k, v in window.items()}
    per_msg = {k: sum(v) / len(v) for k, v in window.items() if v}
    robot_topics = {"/tf", "/sim/joint_states"}
    key = f"{scene}_ros{ros_version}"
    return {
        f"{key}_links": len(robot.robot.links),
        f"{key}_tf_transforms": len(robot.robot.moving),
        f"{key}_tf_Bps": rate.get("/tf", 0.0),
        f"{key}_joint_states_Bps": rate.get("/sim/joint_states", 0.0),
        f"{key}_robot_Bps": sum(v for k, v in rate.items() if k in robot_topics),
        f"{key}_arm_states_Bps": sum(v for k, v in rate.items() if k not in robot_topics),
        f"{key}_tf_msgs_per_s": len(window.get("/tf", [])) / SECONDS,
        # the size of one message times the nominal rate: what 50 Hz costs when it is kept
        # (a loaded machine publishes fewer ticks, so the measured bytes/s are lower)
        f"{key}_tf_bytes_per_msg": per_msg.get("/tf", 0.0),
        f"{key}_joint_states_bytes_per_msg": per_msg.get("/sim/joint_states", 0.0),
        f"{key}_robot_Bps_at_nominal_rate": TF_RATE
        * sum(per_msg.get(k, 0.0) for k in robot_topics),
        f"{key}_latched_description_bytes": sum(
            v for k, v in latched.items() if k.endswith("robot_description")
        ),
        f"{key}_latched_tf_static_bytes": latched.get("/tf_static", 0),
        **summary(tick, f"{key}_tick"),
    }


def main() -> None:
    figures = {"tf_rate_hz": TF_RATE, "seconds": SECONDS}
    for scene, ros_version in (("psm1", 2), ("psm1", 1), ("full", 2)):
        figures.update(measure(scene, ros_version))
    write("client_robot", figures)


if __name__ == "__main__":
    main()
