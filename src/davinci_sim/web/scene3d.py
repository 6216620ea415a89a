"""The bedside view: the whole system in 3-D in a browser, live, with viser.

:class:`BedsideView` runs a `viser <https://viser.studio>`_ server (its own HTTP and
websocket port, its own thread) whose scene is the compiled MuJoCo model's geometry
(:mod:`davinci_sim.web.scene3d_model`): one scene node per visible geom, under one frame
node per body, so that a live update is one pose per moving body. Boxes, spheres,
ellipsoids and cylinders are viser primitives; capsules and meshes are triangle meshes; the
floor plane is a grid. A task's path is geometry of the model (``System.model_source``
includes the task's drawing) and shows like any other static body.

Live updates come from a :class:`~davinci_sim.sim.handle.SimHandle`'s snapshots only (the
loop may run in another process; the view never touches the ``Simulation``): a thread polls
``handle.snapshot()`` at ``rate_hz``; when the tick changed it puts the snapshot's
``extras["qpos"]`` (published by :class:`~davinci_sim.sim.runtime.render.QposProbe`: build
the system with ``publish_qpos=True``) into a local ``MjData`` of the same model, runs
``mj_kinematics`` and sends the poses of the bodies that moved, grouped with viser's
``atomic()`` so that a browser applies a frame as one, then ``flush()``-ed. One update is
one websocket frame (viser's window of 128 messages is widened to a full update), and the
pose messages are queued directly rather than through the handles' setters, whose per-call
checks cost ~85 % of an update (both against viser 1.1 internals, with the public setters
as the fallback; :mod:`davinci_sim.web.viser_compat`). A browser that connects later gets
the latest poses from viser's replay.

The page is read-only apart from its camera dropdown and a checkbox for the force arrows;
viser's "share" button (a public tunnel through share.viser.studio) is hidden and its
request refused. Viser has no authentication: keep it on loopback (the default) unless the
network is trusted.

The guidance force is drawn as an arrow at each PSM's tool tip (see
:meth:`BedsideView.force_arrows`): the haptic loop publishes, per MTM, the fields' summed
wrench in the camera frame's axes (``extras["haptics"].requested``, N; camera axes are the
HRSV axes of the hand, :mod:`davinci_sim.haptics.fixture`); each following PSM
teleoperation (``extras[<MTM>_<PSM>]``) says which PSM that MTM drives. The force is
rotated into the world by ``R_world_camera``, the orientation of the ``ECM/tip`` site (the
camera frame, the same as ``Simulation.T_cart_camera``) from the same kinematics, and drawn
from the ``<PSM>/tip`` site.

Camera presets (:func:`~davinci_sim.web.scene3d_model.camera_presets`) are offered in a
dropdown of the viser page (for the browser that picks one) and by :meth:`set_preset` (for
every browser, and the view new browsers start with). Orbit, pan and zoom are viser's own.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from davinci_sim.web import viser_compat
from davinci_sim.web.hosts import shown_host
from davinci_sim.web.scene3d_model import (
    INFINITE_PLANE_HALF_EXTENT,
    CameraPreset,
    GeomVisual,
    camera_presets,
    capsule_mesh,
    guidance_arrows,
    moving_bodies,
    visible_geoms,
)

log = logging.getLogger(__name__)

#: Length of the force arrow per newton, m/N (the seed's G_max of a few N → a few cm).
DEFAULT_FORCE_SCALE_M_PER_N = 0.02
FORCE_RGB = (255, 220, 0)
DEFAULT_PRESET = "overview"


def _node_name(model: mujoco.MjModel, body: int) -> str:
    # Body names contain "/", which viser reads as nesting: keep one level per body.
    name = model.body(body).name or f"body{body}"
    return f"/bodies/{body}_{name.replace('/', '.')}"


class BedsideView:
    """The live 3-D view of the system in a viser server; see the module docstring.

    Args:
        model_source: callable returning the compiled ``mujoco.MjModel`` to draw (in the app
            ``System.model_source``: the scene with the task's drawing); it must be the model
            the handle's simulation runs (same ``nq``).
        handle: the running simulation's handle (``snapshot()`` only); None: nothing moves
            until :meth:`update` is given snapshots.
        host, port: where viser serves its page and websocket; port 0 or None: a free port
            chosen by the system (:attr:`url` tells which). A port in use makes viser take the
            next free one.
        rate_hz: how often the thread polls the handle (updates are sent only when the tick
            changed).
        force_scale: arrow length per newton of guidance force, m/N.
        keyframe: the model pose drawn before the first snapshot (None: ``qpos0``).
    """

    def __init__(
        self,
        model_source: Callable[[], mujoco.MjModel],
        handle: Any = None,
        *,
        host: str = "127.0.0.1",
        port: int | None = 0,
        rate_hz: float = 30.0,
        force_scale: float = DEFAULT_FORCE_SCALE_M_PER_N,
        keyframe: str | None = "surgical",
    ) -> None:
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
        if not (np.isfinite(force_scale) and force_scale > 0):
            raise ValueError(f"force_scale must be a positive number (m/N), got {force_scale!r}")
        if port is not None and not (isinstance(port, int) and 0 <= port < 65536):
            raise ValueError(f"port must be 0..65535 or None, got {port!r}")
        self.model: mujoco.MjModel = model_source()
        self.data = mujoco.MjData(self.model)
        if (
            keyframe is not None
            and mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, keyframe) >= 0
        ):
            mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key(keyframe).id)
        mujoco.mj_kinematics(self.model, self.data)
        self.handle = handle
        self.host = host
        self.rate_hz = float(rate_hz)
        self.force_scale = float(force_scale)
        self._requested_port = 0 if port is None else port
        self.geoms: list[GeomVisual] = visible_geoms(self.model)
        self.moving = moving_bodies(self.model)
        self.presets: dict[str, CameraPreset] = camera_presets(self.model, self.data)
        self.preset = DEFAULT_PRESET if DEFAULT_PRESET in self.presets else next(iter(self.presets))
        self._site = {self.model.site(i).name: i for i in range(self.model.nsite)}
        self.psms = tuple(
            n.split("/")[0] for n in self._site if n.startswith("PSM") and n.endswith("/tip")
        )
        self.server = None
        self.body_nodes: dict[int, Any] = {}
        self.geom_nodes: dict[int, Any] = {}
        self.force_nodes: dict[str, Any] = {}
        self._sent_pose = np.full((self.model.nbody, 7), np.nan)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.last_tick: int | None = None
        self.updates = 0
        """Frames sent (ticks drawn) since start."""
        self.error: str | None = None
        """The last update's error (e.g. snapshots without ``qpos``), None when fine."""
        self.show_forces = True
        """Draw the guidance force arrows (the page's checkbox)."""
        self._dropdowns: dict[int, Any] = {}
        self._pose_queue = None
        self.share_requests_refused = 0
        self.fast_poses = True
        """Send poses through viser's message queue directly
        (:func:`~davinci_sim.web.viser_compat.pose_queue`); False: the public setters."""

    # ------------------------------------------------------------ lifecycle
    @property
    def url(self) -> str:
        """The page's address (after :meth:`start`)."""
        if self.server is None:
            raise RuntimeError("the bedside view is not started")
        return f"http://{shown_host(self.server.get_host())}:{self.server.get_port()}"

    @property
    def port(self) -> int:
        if self.server is None:
            raise RuntimeError("the bedside view is not started")
        return int(self.server.get_port())

    def start(self) -> BedsideView:
        """Start the viser server, build the scene and (with a handle) the update thread."""
        if self.server is not None:
            return self
        import viser

        with viser_compat.quiet():
            server = viser.ViserServer(host=self.host, port=self._requested_port, verbose=False)
        self.server = server
        server.scene.set_up_direction("+z")
        # viser's default image-based light washes the model's colours out; halved, the
        # scene looks as MuJoCo renders it (materials' colours, room lights from above).
        server.scene.configure_environment_map("warehouse", environment_intensity=0.5)
        # One update, one websocket frame (two messages per moving body, the arrows).
        viser_compat.widen_message_window(server, 2 * len(self.moving) + 2 * len(self.psms) + 16)
        viser_compat.refuse_share_url(server, self._refuse_share_url)  # no public tunnel
        with server.atomic():
            self._build_scene(server)
            self._build_gui(server)
        self._pose_queue = viser_compat.pose_queue(
            server, next(iter(self.body_nodes.values()), None)
        )
        self._apply_preset(self.presets[self.preset], clients=())
        if self.handle is not None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="bedside-view", daemon=True)
            self._thread.start()
        return self

    def _refuse_share_url(self) -> None:
        self.share_requests_refused += 1
        log.warning("bedside view: a page asked for a public share URL; refused")

    def stop(self) -> None:
        """Stop the update thread and the viser server (its threads end with it)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self.server is not None:
            server, self.server = self.server, None
            with viser_compat.quiet():
                server.stop()
            viser_compat.shutdown_executor(server)

    def __enter__(self) -> BedsideView:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------ scene
    def _build_scene(self, server) -> None:
        model, data = self.model, self.data
        moving = set(int(b) for b in self.moving)
        for b in sorted({g.body for g in self.geoms} | moving):
            self.body_nodes[b] = server.scene.add_frame(
                _node_name(model, b),
                show_axes=False,
                position=data.xpos[b].copy(),
                wxyz=data.xquat[b].copy(),
            )
            self._sent_pose[b] = np.concatenate([data.xpos[b], data.xquat[b]])
        for g in self.geoms:
            self.geom_nodes[g.geom] = self._add_geom(server, g)
        for psm in self.psms:
            self.force_nodes[psm] = server.scene.add_arrows(
                f"/forces/{psm}",
                points=np.zeros((1, 2, 3)),
                colors=FORCE_RGB,
                shaft_radius=0.002,
                head_radius=0.005,
                head_length=0.01,
                visible=False,
            )

    def _add_geom(self, server, g: GeomVisual):
        name = f"{_node_name(self.model, g.body)}/g{g.geom}"
        rgb = tuple(float(c) for c in g.rgba[:3])
        opacity = None if g.rgba[3] >= 1.0 else float(g.rgba[3])
        pose = {"position": g.p_body_geom, "wxyz": g.q_body_geom}
        look = {"opacity": opacity, **pose}
        s = g.size
        if g.shape == "box":
            return server.scene.add_box(name, color=rgb, dimensions=2 * s, **look)
        if g.shape == "sphere":
            return server.scene.add_icosphere(name, radius=s[0], color=rgb, subdivisions=2, **look)
        if g.shape == "ellipsoid":
            return server.scene.add_icosphere(
                name, radius=1.0, color=rgb, subdivisions=2, scale=tuple(s), **look
            )
        if g.shape == "cylinder":
            return server.scene.add_cylinder(
                name, radius=s[0], height=2 * s[1], color=rgb, radial_segments=16, **look
            )
        if g.shape == "capsule":
            vertices, faces = capsule_mesh(s[0], s[1])
            return server.scene.add_mesh_simple(name, vertices, faces, color=rgb, **look)
        if g.shape == "mesh":
            vertices, faces = g.mesh
            return server.scene.add_mesh_simple(name, vertices, faces, color=rgb, **look)
        # plane: MuJoCo's size is the half-extent (0: infinite); viser's grid is xy, centred.
        w = 2 * (s[0] if s[0] > 0 else INFINITE_PLANE_HALF_EXTENT)
        h = 2 * (s[1] if s[1] > 0 else INFINITE_PLANE_HALF_EXTENT)
        shade = tuple(int(255 * min(1.0, c * 1.25)) for c in g.rgba[:3])
        return server.scene.add_grid(
            name,
            width=w,
            height=h,
            plane="xy",
            cell_size=0.25,
            section_size=1.0,
            cell_color=shade,
            section_color=shade,
            plane_color=rgb,
            plane_opacity=1.0,
            **pose,
        )

    def _build_gui(self, server) -> None:
        # One dropdown per browser (client-scoped): a pick moves that browser's camera only.
        # (Async: runs in viser's event loop, before a quick disconnect is processed.)
        @server.on_client_connect
        async def _(client) -> None:
            dropdown = client.gui.add_dropdown(
                "View",
                tuple(self.presets),
                initial_value=self.preset,
                hint="camera presets; drag to orbit, scroll to zoom",
                order=0.0,
            )
            self._dropdowns[client.client_id] = dropdown

            @dropdown.on_update
            def _(event) -> None:
                if event.client is not None:  # (not a server-side set_preset)
                    preset = self._fresh_preset(dropdown.value)
                    self._apply_preset(preset, clients=(event.client,), initial=False)

        @server.on_client_disconnect
        async def _(client) -> None:
            self._dropdowns.pop(client.client_id, None)

        arrows = server.gui.add_checkbox(
            "Guidance force",
            initial_value=True,
            hint="the guidance force at each tool tip",
            order=1.0,
        )

        @arrows.on_update
        def _(event) -> None:
            self.show_forces = bool(arrows.value)

    # ------------------------------------------------------------ presets
    def set_preset(self, name: str) -> CameraPreset:
        """Move every connected browser's camera, and the view new ones start with, to the
        preset ``name`` (``endoscope`` is recomputed from the current pose).

        Raises:
            KeyError: an unknown preset (the message lists the known ones).
        """
        preset = self._fresh_preset(name)
        self.preset = name
        if self.server is not None:
            self._apply_preset(preset, clients=tuple(self.server.get_clients().values()))
            for dropdown in list(self._dropdowns.values()):
                dropdown.value = name  # (a server-side change: no client, no echo)
        return preset

    def _fresh_preset(self, name: str) -> CameraPreset:
        if name not in self.presets:
            raise KeyError(f"unknown camera preset {name!r}; presets: {list(self.presets)}")
        if name == "endoscope":  # where the endoscope is now
            with self._lock:
                self.presets = camera_presets(self.model, self.data)
        return self.presets[name]

    def _apply_preset(self, p: CameraPreset, clients, *, initial: bool = True) -> None:
        fov = float(np.radians(p.fovy_deg))
        if initial:  # new browsers start here, and viser's "reset view" returns here
            cam = self.server.initial_camera
            cam.position, cam.look_at, cam.up, cam.fov = p.position, p.look_at, p.up, fov
        for client in clients:
            with client.atomic():
                client.camera.up_direction = p.up
                client.camera.position = p.position
                client.camera.look_at = p.look_at
                client.camera.fov = fov
            client.flush()

    # ------------------------------------------------------------ updates
    def update(self, snapshot=None) -> bool:
        """Draw ``snapshot`` (default: the handle's latest) if its tick is new; True if a
        frame was sent.

        Raises:
            ValueError: a snapshot without ``extras["qpos"]`` or with one of the wrong size
                (nothing is drawn).
        """
        snap = self.handle.snapshot() if snapshot is None else snapshot
        if snap is None or snap.tick == self.last_tick:
            return False
        qpos = snap.extras.get("qpos")
        if qpos is None:
            raise ValueError(
                "the snapshots carry no qpos: build the system with publish_qpos=True "
                "(QposProbe) for the bedside view"
            )
        q = np.asarray(qpos, dtype=float)
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise ValueError(
                f"qpos of shape {q.shape} (finite: {np.all(np.isfinite(q))}) "
                f"does not fit the model's nq = {self.model.nq}"
            )
        with self._lock:
            self.data.qpos[:] = q
            mujoco.mj_kinematics(self.model, self.data)
            server = self.server
            if server is None:
                return False
            with server.atomic():
                self._send_poses()
                self._send_forces(snap)
            server.flush()
            self.last_tick = snap.tick
            self.updates += 1
        return True

    def _send_poses(self) -> None:
        """The poses of the moving bodies that moved more than 1e-7 (m, quaternion units)
        since last sent."""
        b = self.moving
        pose = np.concatenate([self.data.xpos[b], self.data.xquat[b]], axis=1)
        changed = np.flatnonzero(~np.all(np.abs(pose - self._sent_pose[b]) <= 1e-7, axis=1))
        self._sent_pose[b[changed]] = pose[changed]
        nodes = [self.body_nodes[int(body)] for body in b[changed]]
        send = self._pose_queue if self.fast_poses else None
        if send is None:  # viser's public setters (each checks and casts its value)
            for node, row in zip(nodes, pose[changed], strict=True):
                node.position = row[:3]
                node.wxyz = row[3:]
            return
        for node, row in zip(nodes, pose[changed].tolist(), strict=True):
            send(node, tuple(row[:3]), tuple(row[3:]))

    def force_arrows(self, snapshot) -> dict[str, np.ndarray]:
        """PSM -> the guidance force arrow ``[[start], [end]]`` (2, 3), world frame, m, for
        each PSM whose teleoperation is following and whose MTM has a requested wrench
        in ``snapshot`` (call after the kinematics of that snapshot; see the module
        docstring for the frames)."""
        ecm = self._site.get("ECM/tip")
        R_world_camera = np.eye(3) if ecm is None else self.data.site_xmat[ecm].reshape(3, 3)
        tips = {psm: self.data.site_xpos[self._site[f"{psm}/tip"]] for psm in self.psms}
        return guidance_arrows(snapshot.extras, tips, R_world_camera, self.force_scale)

    def _send_forces(self, snapshot) -> None:
        arrows = self.force_arrows(snapshot) if self.show_forces else {}
        for psm, node in self.force_nodes.items():
            points = arrows.get(psm)
            if points is None:
                node.visible = False
                continue
            node.points = points[None].astype(np.float32)
            node.visible = True

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        next_poll = time.monotonic()
        while not self._stop.is_set():
            try:
                self.update()
                self.error = None
            except Exception as e:  # the view carries on: the next snapshot may be fine
                if str(e) != self.error:  # bad snapshots: a warning; a handle not ready: debug
                    level = logging.WARNING if isinstance(e, ValueError) else logging.DEBUG
                    log.log(level, "bedside view: %s", e)
                self.error = str(e)
            # Polls on a fixed grid (an update's own time does not lower the rate); after a
            # stall it starts a new grid instead of bursting to catch up.
            next_poll += period
            now = time.monotonic()
            if next_poll < now:
                next_poll = now
            self._stop.wait(next_poll - now)
