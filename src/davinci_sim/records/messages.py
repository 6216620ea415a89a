"""The messages of a simulator snapshot and of a stereo pair in a recording.

:func:`write_snapshot` writes what one published
:class:`~davinci_sim.sim.handle.Snapshot` holds (the topics listed in
:mod:`~davinci_sim.records.recording`), :func:`write_images` a rendered stereo pair as JPEG;
both for a session's recorder and an environment's (:mod:`~davinci_sim.records.episodes`).
"""

from __future__ import annotations

from davinci_sim.records.jsonvalue import plain
from davinci_sim.records.mcap_file import McapWriter
from davinci_sim.records.mcap_schemas import numbers, pose_fields, stamp, time_ns

#: Arm types whose ``measured_cp`` is recorded (the setup joints' are fixed frames).
CARTESIAN = ("PSM", "ECM", "MTM")


def write_snapshot(w: McapWriter, snap) -> None:
    """The messages of one :class:`~davinci_sim.sim.handle.Snapshot` (module docstring)."""
    t = snap.time
    ns, ts = time_ns(t), stamp(t)
    transforms = []
    for name, arm in snap.arms.items():
        for field, topic in (
            ("measured_js", "measured_js"),
            ("setpoint_js", "setpoint_js"),
            ("jaw_measured_js", "jaw/measured_js"),
            ("jaw_setpoint_js", "jaw/setpoint_js"),
            ("gripper_measured_js", "gripper/measured_js"),
        ):
            js = getattr(arm, field)
            if js is not None:
                w.write(
                    f"/{name}/{topic}",
                    "davinci_sim.JointState",
                    ns,
                    joint_message(js, ts, snap.tick),
                )
        if arm.arm_type in CARTESIAN:
            cp = arm.measured_cp
            p, q = pose_fields(cp.T)
            w.write(
                f"/{name}/measured_cp",
                "foxglove.PoseInFrame",
                ns,
                {
                    "timestamp": ts,
                    "frame_id": cp.reference_frame,
                    "pose": {"position": p, "orientation": q},
                },
            )
            transforms.append(
                {
                    "timestamp": ts,
                    "parent_frame_id": cp.reference_frame,
                    "child_frame_id": name,
                    "translation": p,
                    "rotation": q,
                }
            )
            sp = arm.setpoint_cp
            p, q = pose_fields(sp.T)
            w.write(
                f"/{name}/setpoint_cp",
                "foxglove.PoseInFrame",
                ns,
                {
                    "timestamp": ts,
                    "frame_id": sp.reference_frame,
                    "pose": {"position": p, "orientation": q},
                },
            )
    if transforms:
        w.write("/tf", "foxglove.FrameTransforms", ns, {"transforms": transforms})
    for name, state in snap.extras.items():
        if name == "qpos":
            w.write(
                "/sim/qpos",
                "davinci_sim.Qpos",
                ns,
                {"timestamp": ts, "tick": snap.tick, "qpos": numbers(state)},
            )
        elif name == "inputs":
            continue
        else:
            topic = "/task/state" if name == "task" else f"/components/{name}"
            w.write(
                topic,
                "davinci_sim.State",
                ns,
                {"timestamp": ts, "tick": snap.tick, "state": plain(state)},
            )
            for mtm, wrench in (getattr(state, "sent", None) or {}).items():
                f, m = numbers(wrench[:3]), numbers(wrench[3:6])
                w.write(
                    f"/{mtm}/wrench",
                    "davinci_sim.Wrench",
                    ns,
                    {
                        "timestamp": ts,
                        "frame_id": f"{mtm}_HRSV",
                        "force": dict(zip("xyz", f, strict=True)),
                        "torque": dict(zip("xyz", m, strict=True)),
                    },
                )


def write_images(w: McapWriter, frame, quality: int = 80) -> None:
    """A :class:`~davinci_sim.sim.runtime.render.StereoFrame` as two JPEG
    ``foxglove.CompressedImage`` messages at the time of the joint positions it shows."""
    import base64
    import io

    from PIL import Image

    ns, ts = time_ns(frame.time), stamp(frame.time)
    for side, image in (("left", frame.left), ("right", frame.right)):
        buffer = io.BytesIO()
        Image.fromarray(image).save(buffer, format="JPEG", quality=quality)
        data = base64.b64encode(buffer.getvalue()).decode()
        w.write(
            f"/endoscope/{side}/compressed",
            "foxglove.CompressedImage",
            ns,
            {"timestamp": ts, "frame_id": f"ECM/{side}", "data": data, "format": "jpeg"},
        )


def joint_message(js, ts: dict, tick: int) -> dict:
    """A :class:`~davinci_sim.sim.types.JointState` as a ``davinci_sim.JointState`` message."""
    return {
        "timestamp": ts,
        "tick": int(tick),
        "name": list(js.name),
        "position": numbers(js.position),
        "velocity": [] if js.velocity is None else numbers(js.velocity),
        "effort": [] if js.effort is None else numbers(js.effort),
    }
