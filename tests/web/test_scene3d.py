"""The bedside view (davinci_sim.web.scene3d): the model's geometry in viser, live poses
from snapshots, the guidance force arrow, camera presets, a clean stop."""

from __future__ import annotations

import functools
import threading
import time

import mujoco
import numpy as np
import pytest

from davinci_sim.console.haptic_loop import HapticsState
from davinci_sim.console.teleop_psm import TeleopPSMState
from davinci_sim.model import appearance
from davinci_sim.model.cameras import OVERVIEW
from davinci_sim.sim.handle import Snapshot, take_snapshot
from davinci_sim.system import (
    SystemDescription,
    TaskDescription,
    build_simulation,
    build_system,
    scene_model,
)
from davinci_sim.web.scene3d import BedsideView
from davinci_sim.web.scene3d_model import capsule_mesh, geom_rgba
from davinci_sim.web.viser_probe import ViserProbe

POSE_MESSAGES = ("SetPositionMessage", "SetOrientationMessage")
#: viser skips a pose within ``np.allclose`` (1e-5 relative) of the last one it sent, and
#: the view skips bodies that moved less than 1e-7: poses agree to ~10 µm at 1 m.
POSE_ATOL = 2e-5


class SnapshotHandle:
    """The part of a SimHandle the view uses, on a simulation this test ticks itself."""

    def __init__(self, sim):
        self.sim = sim

    def snapshot(self):
        return take_snapshot(self.sim)


def psm1_sim():
    return build_simulation(SystemDescription("psm1", publish_qpos=True, runner="none", home=True))


def wait(predicate, timeout=30.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


def mujoco_poses(sim):
    """Body poses MuJoCo gives for the simulation's current qpos (``sim.data.xpos`` after a
    step belongs to the qpos before it: mj_step computes positions, then integrates)."""
    data = mujoco.MjData(sim.model)
    data.qpos[:] = sim.data.qpos
    mujoco.mj_kinematics(sim.model, data)
    return data.xpos.copy(), data.xquat.copy()


def same_rotation(q1, q2):
    return min(np.abs(np.asarray(q1) - q2).max(), np.abs(np.asarray(q1) + q2).max())


def test_full_scene_has_one_node_per_geom_mujoco_draws():
    description = SystemDescription("full", task=TaskDescription("seed_path"))
    model = scene_model(description)
    # What MuJoCo's own visualiser draws with its default options: the reference.
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = mujoco.MjvScene(model, 10000)
    mujoco.mjv_updateScene(
        model, data, mujoco.MjvOption(), None, mujoco.MjvCamera(), mujoco.mjtCatBit.mjCAT_ALL, scene
    )
    drawn = {
        scene.geoms[i].objid
        for i in range(scene.ngeom)
        if scene.geoms[i].objtype == mujoco.mjtObj.mjOBJ_GEOM
    }
    with BedsideView(functools.partial(scene_model, description)) as view:
        assert set(view.geom_nodes) == drawn
        assert len(view.geom_nodes) == len(drawn) > 200
        # The task's path is there, in the task's colour.
        tubes = [g for g in view.geom_nodes if model.geom(g).name.startswith("task/tube")]
        assert tubes
        path_rgb = np.array(load_path_rgba()[:3]) * 255
        for g in tubes:
            assert np.allclose(view.geom_nodes[g].color, path_rgb, atol=1.0)
        # A box is as large as the model's, in its material's colour.
        top = model.geom("table/top").id
        assert np.allclose(view.geom_nodes[top].dimensions, 2 * model.geom_size[top])
        table_rgb = np.array(appearance.MATERIALS["table"][0][:3]) * 255
        assert np.allclose(view.geom_nodes[top].color, table_rgb, atol=1.0)
        # Every moving body has a node; the world's static geoms hang off fixed frames.
        assert set(view.moving) <= set(view.body_nodes)
        assert not set(view.moving) & {0, model.body("table").id, model.body("cart").id}


@pytest.mark.parametrize("fast_poses", [True, False], ids=["queue", "setters"])
def test_an_update_of_every_arm_is_one_websocket_frame(fast_poses):
    model = scene_model(SystemDescription("full"))
    q = model.key("surgical").qpos.copy()
    hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    with BedsideView(lambda: model) as view, ViserProbe(view.url) as probe:
        view.fast_poses = fast_poses
        assert wait(lambda: any("ReplayDoneMessage" in f.types for f in probe.received()))
        assert wait(lambda: probe.gui_uuid("View") is not None)
        n_frames = len(probe.received())
        q[model.jnt_qposadr[hinges]] += 0.1
        assert view.update(Snapshot(0.0, 1, {}, {"qpos": q}))
        assert wait(lambda: len(probe.received()) > n_frames)
        time.sleep(0.2)  # (a second frame, if any, would follow at once)
        frames = [f for f in probe.received()[n_frames:] if set(f.types) & set(POSE_MESSAGES)]
        assert len(frames) == 1
        named = {
            n
            for t, n in zip(frames[0].types, frames[0].names, strict=True)
            if t == "SetOrientationMessage"
        }
        assert len(named) > 64  # every arm's links turned
        # A browser that connects now gets the new poses (viser replays the latest ones).
        data = mujoco.MjData(model)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        with ViserProbe(view.url) as late:
            assert wait(lambda: any("ReplayDoneMessage" in f.types for f in late.received()))
            replay = [m for f in late.received() for m in f.messages]
        last = {}
        for m in replay:
            if m.get("type") == "SetPositionMessage":
                last[m["name"]] = m["position"]
        for b in view.moving:
            name = view.body_nodes[int(b)].name
            assert np.allclose(last[name], data.xpos[b], rtol=0, atol=POSE_ATOL)


def load_path_rgba():
    from davinci_sim.tasks import load_task

    return load_task("seed_path").visual.path_rgba


def test_floor_colour_is_its_checker_texture_average():
    model = scene_model(SystemDescription("psm1"))
    floor = model.geom("floor").id
    # model/appearance.py: the checker's two colours on a white material.
    expected = (np.array([0.32, 0.33, 0.35]) + [0.26, 0.27, 0.29]) / 2
    assert np.allclose(geom_rgba(model, floor)[:3], expected, atol=0.01)


def test_capsule_mesh_is_a_closed_capsule():
    r, h = 0.01, 0.03
    vertices, faces = capsule_mesh(r, h, segments=48, cap_rings=16)
    v = vertices.astype(float)
    # Every vertex is r from the axis segment.
    closest = np.clip(v[:, 2], -h, h)
    dist = np.linalg.norm(v - np.stack([0 * closest, 0 * closest, closest], 1), axis=1)
    assert np.allclose(dist, r, rtol=1e-5)
    # Outward triangles: the divergence theorem gives a positive volume close to the
    # capsule's (inscribed polyhedron: a little less).
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    exact = np.pi * r**2 * 2 * h + 4 / 3 * np.pi * r**3
    assert 0.97 * exact < volume < exact
    # Closed: every edge is shared by exactly two triangles.
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)


@pytest.mark.parametrize("fast_poses", [True, False], ids=["queue", "setters"])
def test_a_moved_arm_moves_its_nodes_to_mujocos_poses_and_nothing_else_is_sent(fast_poses):
    sim = psm1_sim()
    sim.run_for(0.3)
    handle = SnapshotHandle(sim)
    model = sim.model
    with BedsideView(lambda: model) as view, ViserProbe(view.url) as probe:
        view.fast_poses = fast_poses
        assert view._pose_queue is not None  # viser 1.1's internals are as expected
        assert view.update(handle.snapshot())
        static_before = {
            b: (n.position.copy(), n.wxyz.copy())
            for b, n in view.body_nodes.items()
            if b not in set(view.moving)
        }
        xpos_before, xquat_before = sim.data.xpos.copy(), sim.data.xquat.copy()
        psm = sim.arms["PSM1"]
        q = psm.measured_jp().copy()
        q[:3] += [0.3, -0.2, 0.03]
        assert psm.move_jp(q).accepted
        sim.run_for(1.5)
        assert np.allclose(psm.measured_jp()[:3], q[:3], atol=1e-3)
        assert wait(lambda: any("ReplayDoneMessage" in f.types for f in probe.received()))
        n_frames = len(probe.received())
        assert view.update(handle.snapshot())
        assert not view.update(handle.snapshot())  # same tick: nothing to send
        xpos, xquat = mujoco_poses(sim)
        for b in view.moving:
            node = view.body_nodes[int(b)]
            assert np.allclose(node.position, xpos[b], rtol=0, atol=POSE_ATOL)
            assert same_rotation(node.wxyz, xquat[b]) < POSE_ATOL
        for b, (p, q_wxyz) in static_before.items():
            assert np.array_equal(view.body_nodes[b].position, p)
            assert np.array_equal(view.body_nodes[b].wxyz, q_wxyz)

        # The frames sent name the bodies that moved (PSM1's links; the bead may settle by
        # microns), none that stayed (SUJ, ECM, the world's).
        def changed(threshold):
            return {
                view.body_nodes[int(b)].name
                for b in view.moving
                if max(
                    np.abs(sim.data.xpos[b] - xpos_before[b]).max(),
                    same_rotation(sim.data.xquat[b], xquat_before[b]),
                )
                > threshold
            }

        arm = changed(1e-3)
        assert arm and all("PSM1." in name for name in arm)
        assert wait(lambda: len(probe.received()) > n_frames)
        sent = {
            n
            for f in probe.received()[n_frames:]
            for t, n in zip(f.types, f.names, strict=True)
            if t in POSE_MESSAGES
        }
        assert arm <= sent <= changed(1e-7)
        assert not any("ECM" in name or "SUJ" in name for name in sent)
        assert len(probe.received()) == n_frames + 1  # one update, one websocket frame


def test_thread_runner_live_view_follows_the_simulation():
    description = SystemDescription(
        "psm1",
        publish_qpos=True,
        runner="thread",
        real_time=False,
        home=True,
        snapshot_period=0.001,
    )
    system = build_system(description)
    view = BedsideView(system.model_source, system.handle, rate_hz=50.0)
    try:
        system.start()
        view.start()
        h = system.handle
        assert wait(lambda: h.snapshot().arms["PSM1"].operating_state.is_homed)
        q = np.array(h.snapshot().arms["PSM1"].measured_js.position, dtype=float)
        q[:3] += [-0.25, 0.15, 0.02]
        assert h.call("PSM1", "move_jp", q).result(timeout=30).accepted

        def arrived():
            position = h.snapshot().arms["PSM1"].measured_js.position
            return np.allclose(position[:3], q[:3], atol=1e-3)

        assert wait(arrived)
        h.stop()  # the loop stops; its last snapshot is the simulation's state
        final = h.snapshot().tick
        assert wait(lambda: view.last_tick == final)
        assert view.error is None and view.updates >= 2
        xpos, xquat = mujoco_poses(system.sim)
        for b in view.moving:
            node = view.body_nodes[int(b)]
            assert np.allclose(node.position, xpos[b], rtol=0, atol=POSE_ATOL)
            assert same_rotation(node.wxyz, xquat[b]) < POSE_ATOL
    finally:
        view.stop()
        system.stop()


class RecordingHandle:
    """A handle's snapshots, each kept by tick (to check what the view drew)."""

    def __init__(self, handle):
        self.handle = handle
        self.seen = {}

    def snapshot(self):
        snap = self.handle.snapshot()
        self.seen[snap.tick] = snap
        return snap


def test_process_runner_live_view_draws_the_loops_snapshots():
    """The loop in its own process: the view sees only snapshots (rebuilt in this process)."""
    description = SystemDescription(
        "psm1", publish_qpos=True, runner="process", real_time=False, home=True
    )
    system = build_system(description)
    recording = RecordingHandle(system.handle)
    view = BedsideView(system.model_source, recording, rate_hz=50.0)
    try:
        system.start()
        view.start()
        h = system.handle
        assert wait(lambda: view.updates > 0, timeout=60)
        assert wait(lambda: h.snapshot().arms["PSM1"].operating_state.is_homed, timeout=60)
        q = np.array(h.snapshot().arms["PSM1"].measured_js.position, dtype=float)
        q[:3] += [0.2, 0.1, -0.02]
        assert h.call("PSM1", "move_jp", q).result(timeout=30).accepted

        def arrived():
            position = h.snapshot().arms["PSM1"].measured_js.position
            return np.allclose(position[:3], q[:3], atol=1e-3)

        assert wait(arrived, timeout=60)
        updates = view.updates
        assert wait(lambda: view.updates > updates + 1)
        view.stop()
        drawn = recording.seen[view.last_tick]
        assert np.allclose(drawn.arms["PSM1"].measured_js.position[:3], q[:3], atol=2e-3)
        model = system.model_source()
        data = mujoco.MjData(model)
        data.qpos[:] = drawn.extras["qpos"]
        mujoco.mj_kinematics(model, data)
        for b in view.moving:
            node = view.body_nodes[int(b)]
            assert np.allclose(node.position, data.xpos[b], rtol=0, atol=POSE_ATOL)
            assert same_rotation(node.wxyz, data.xquat[b]) < POSE_ATOL
    finally:
        view.stop()
        system.stop()


def teleop_state(following: bool) -> TeleopPSMState:
    return TeleopPSMState(
        name="MTMR_PSM1",
        mtm="MTMR",
        psm="PSM1",
        current_state="ENABLED",
        desired_state="ENABLED",
        following=following,
        scale=0.2,
        rotation_locked=False,
        translation_locked=False,
        align_mtm=True,
        alignment_offset=np.eye(3),
        selected=True,
        clutched=False,
        T_hrsv_mtm=np.eye(4),
    )


def with_extras(snapshot: Snapshot, tick: int, **extras) -> Snapshot:
    return Snapshot(snapshot.time, tick, snapshot.arms, {**snapshot.extras, **extras})


def test_force_arrow_starts_at_the_tip_and_points_along_the_force_in_the_world():
    sim = psm1_sim()
    sim.run_for(0.2)
    base = take_snapshot(sim)
    f_camera = np.array([1.0, -2.0, 0.5])
    haptics = HapticsState(
        fields=(("guidance", "MTMR"),), requested={"MTMR": np.array([*f_camera, 0.0, 0.0, 0.0])}
    )
    # The reference: the simulation's own camera frame and PSM1's measured tip (camera frame).
    T_world_camera = sim.T_cart_camera()
    p_world_tip = (T_world_camera @ sim.arms["PSM1"].measured_cp().T)[:3, 3]
    scale = 0.03
    with BedsideView(lambda: sim.model, force_scale=scale) as view:
        node = view.force_nodes["PSM1"]
        view.update(with_extras(base, 1, haptics=haptics, MTMR_PSM1=teleop_state(True)))
        assert node.visible
        start, end = np.asarray(node.points, dtype=float)[0]
        assert np.allclose(start, p_world_tip, atol=1e-5)
        assert np.allclose(end - start, scale * T_world_camera[:3, :3] @ f_camera, atol=1e-5)
        # Not following (clutch, no operator): no arrow, whatever the stale request says.
        view.update(with_extras(base, 2, haptics=haptics, MTMR_PSM1=teleop_state(False)))
        assert not node.visible
        zero = HapticsState(fields=(), requested={"MTMR": np.zeros(6)})
        view.update(with_extras(base, 3, haptics=zero, MTMR_PSM1=teleop_state(True)))
        assert not node.visible
        # The page's checkbox turns the arrows off.
        view.show_forces = False
        view.update(with_extras(base, 4, haptics=haptics, MTMR_PSM1=teleop_state(True)))
        assert not node.visible


def test_presets_move_the_browsers_camera_and_the_initial_view():
    sim = psm1_sim()
    sim.run_for(0.1)
    with BedsideView(lambda: sim.model) as view, ViserProbe(view.url) as probe:
        assert {"overview", "bedside", "monitor_task", "monitor_system", "endoscope"} <= set(
            view.presets
        )
        assert "console" not in view.presets  # the psm1 scene has no console
        assert wait(lambda: len(view.server.get_clients()) == 1)
        client = next(iter(view.server.get_clients().values()))
        for name in view.presets:
            preset = view.set_preset(name)
            assert np.allclose(client.camera.position, preset.position)
            assert np.allclose(client.camera.look_at, preset.look_at)
            assert np.isclose(client.camera.fov, np.radians(preset.fovy_deg))
            assert np.allclose(view.server.initial_camera.position, preset.position)
        assert wait(lambda: any("SetCameraLookAtMessage" in f.types for f in probe.received()))
        # The overview preset is the model's overview camera (model/cameras.py).
        overview = view.set_preset("overview")
        direction = np.subtract(overview.look_at, overview.position)
        expected = np.subtract(OVERVIEW.target, OVERVIEW.position)
        assert np.allclose(overview.position, OVERVIEW.position, atol=1e-9)
        assert np.allclose(
            direction / np.linalg.norm(direction), expected / np.linalg.norm(expected), atol=1e-9
        )
        # The endoscope preset is where the ECM tip (camera frame) is now.
        view.update(take_snapshot(sim))
        endoscope = view.set_preset("endoscope")
        T = sim.T_cart_camera()
        assert np.allclose(endoscope.position, T[:3, 3], atol=1e-9)
        direction = np.subtract(endoscope.look_at, endoscope.position)
        assert np.allclose(direction / np.linalg.norm(direction), T[:3, 2], atol=1e-9)
        with pytest.raises(KeyError, match="bedside"):
            view.set_preset("nowhere")
        assert view.preset == "endoscope"
        assert np.allclose(client.camera.position, endoscope.position)


def test_the_pages_dropdown_moves_that_browsers_camera_only():
    from viser._messages import GuiUpdateMessage, ShareUrlRequest

    sim = psm1_sim()
    with (
        BedsideView(lambda: sim.model) as view,
        ViserProbe(view.url) as a,
        ViserProbe(view.url),
    ):
        assert wait(lambda: len(view.server.get_clients()) == 2)
        assert wait(lambda: a.gui_uuid("View") is not None)
        clients = view.server.get_clients()
        cameras = {cid: c.camera.position.copy() for cid, c in clients.items()}
        a.send(GuiUpdateMessage(a.gui_uuid("View"), {"value": "monitor_task"}))
        target = view.presets["monitor_task"].position
        assert wait(lambda: any(np.allclose(c.camera.position, target) for c in clients.values()))
        moved = [cid for cid, c in clients.items() if np.allclose(c.camera.position, target)]
        assert len(moved) == 1
        (other,) = set(clients) - set(moved)
        assert np.allclose(clients[other].camera.position, cameras[other])
        assert view.preset == "overview"  # the default for new browsers is unchanged
        assert np.allclose(view.server.initial_camera.position, view.presets["overview"].position)
        a.send(GuiUpdateMessage(a.gui_uuid("Guidance force"), {"value": False}))
        assert wait(lambda: view.show_forces is False)
        # No public tunnel from a page: viser's share request is refused.
        a.send(ShareUrlRequest())
        assert wait(lambda: view.share_requests_refused == 1)
        assert view.server._share_tunnel is None


def test_console_preset_exists_with_a_console():
    model = scene_model(SystemDescription("psm1_ecm_mtmr"))
    view = BedsideView(lambda: model)
    assert "console" in view.presets
    console = view.presets["console"]
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    to_mtm = data.site_xpos[model.site("MTMR/tip").id] - console.position
    forward = np.subtract(console.look_at, console.position)
    angle = np.degrees(
        np.arccos(to_mtm @ forward / np.linalg.norm(to_mtm) / np.linalg.norm(forward))
    )
    assert angle < console.fovy_deg / 2


def test_bad_snapshots_are_refused_and_the_thread_carries_on():
    sim = psm1_sim()
    good = take_snapshot(sim)
    no_qpos = Snapshot(good.time, good.tick + 1, good.arms, {})
    short = with_extras(good, good.tick + 2, qpos=np.zeros(3))
    with BedsideView(lambda: sim.model) as view:
        before = {b: n.position.copy() for b, n in view.body_nodes.items()}
        with pytest.raises(ValueError, match="publish_qpos"):
            view.update(no_qpos)
        with pytest.raises(ValueError, match="nq"):
            view.update(short)
        nan = np.array(good.extras["qpos"], dtype=float)
        nan[0] = np.nan
        with pytest.raises(ValueError):
            view.update(with_extras(good, good.tick + 3, qpos=nan))
        assert all(np.array_equal(view.body_nodes[b].position, p) for b, p in before.items())
        assert view.updates == 0

    class Handle:
        snap = no_qpos

        def snapshot(self):
            return self.snap

    handle = Handle()
    with BedsideView(lambda: sim.model, handle, rate_hz=200.0) as view:
        assert wait(lambda: view.error is not None and "publish_qpos" in view.error)
        handle.snap = good
        assert wait(lambda: view.updates == 1 and view.error is None)


def test_stop_leaves_no_thread_and_frees_the_port():
    sim = psm1_sim()
    before = set(threading.enumerate())
    view = BedsideView(lambda: sim.model, SnapshotHandle(sim), port=None).start()
    with ViserProbe(view.url) as probe:
        assert wait(lambda: probe.gui_uuid("View") is not None)
        view.set_preset("bedside")
    port = view.port
    view.stop()
    # (the probe's websocket keepalive thread ends just after its close: wait for it)
    assert wait(lambda: set(threading.enumerate()) <= before)
    with pytest.raises(RuntimeError):
        view.url  # noqa: B018
    # The port is free again: a new view can take it.
    with BedsideView(lambda: sim.model, port=port) as again:
        assert again.port == port
    assert set(threading.enumerate()) <= before


def test_bad_arguments_are_refused():
    model = scene_model(SystemDescription("psm1"))
    for kwargs in (
        {"rate_hz": 0.0},
        {"rate_hz": float("nan")},
        {"force_scale": -1.0},
        {"port": 70000},
        {"port": "80"},
    ):
        with pytest.raises(ValueError):
            BedsideView(lambda: model, **kwargs)


def test_mesh_geoms_and_hidden_groups():
    spec = mujoco.MjSpec()
    spec.add_mesh(
        name="tetra",
        uservert=[0, 0, 0, 0.1, 0, 0, 0, 0.1, 0, 0, 0, 0.1],
        userface=[0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3],
    )
    body = spec.worldbody.add_body(name="b", pos=[0.0, 0.0, 1.0])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="tetra", rgba=[0.2, 0.4, 0.6, 1.0])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], group=3)  # hidden
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], rgba=[1, 0, 0, 0])
    model = spec.compile()
    with BedsideView(lambda: model, keyframe=None) as view:
        assert list(view.geom_nodes) == [0]
        node = view.geom_nodes[0]
        assert len(node.vertices) == model.mesh_vertnum[0]
        assert len(node.faces) == model.mesh_facenum[0] == 4
        assert np.allclose(node.color, np.array([0.2, 0.4, 0.6]) * 255, atol=1.0)
        q = model.qpos0.copy()
        q[:3] = [0.3, -0.2, 0.5]
        view.update(Snapshot(0.0, 1, {}, {"qpos": q}))
        assert np.allclose(view.body_nodes[1].position, [0.3, -0.2, 0.5])
