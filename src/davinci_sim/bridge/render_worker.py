"""The endoscope render process: ``python -m davinci_sim.bridge.render_worker FD``.

It receives ``(scene, encoding, quality)`` then ``(stamp, qpos)`` requests on the socket
``FD`` and answers each with ``("frame", fields of Frame)`` (plain data, so that nothing
refers to this ``__main__`` module), see :class:`davinci_sim.bridge.endoscope.RenderWorker`.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from multiprocessing.connection import Connection

from davinci_sim.bridge.endoscope import CAMERAS, Frame, _encode_pair


def main(conn: Connection) -> None:
    """Build the model, then render each ``qpos`` it is sent."""
    import mujoco

    from davinci_sim.model import build_model
    from davinci_sim.sim.sensors import CameraRenderer

    scene, encoding, quality = conn.recv()
    model = build_model(scene)
    data = mujoco.MjData(model)
    renderer = CameraRenderer(model)
    w, h = scene.endoscope.width, scene.endoscope.height
    conn.send(("ready", model.nq))
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):
            break
        if request is None:
            break
        stamp, qpos = request
        t0 = time.perf_counter()
        try:
            data.qpos[:] = qpos
            mujoco.mj_forward(model, data)
            left, right = (renderer.render(data, camera, w, h, fast=True) for _, camera in CAMERAS)
            jpeg, raw, _ = _encode_pair(left, right, encoding, quality)
            frame = Frame(stamp, jpeg, raw, w, h, time.perf_counter() - t0)
            conn.send(("frame", dataclasses.astuple(frame)))  # plain data: see __main__
        except Exception as e:  # report and carry on
            conn.send(("error", f"{type(e).__name__}: {e}"))
    renderer.close()


if __name__ == "__main__":
    main(Connection(int(sys.argv[1])))
