"""Sensors beyond joint states: contact forces on instruments and offscreen cameras."""

from __future__ import annotations

import mujoco
import numpy as np

#: Bodies of an instrument (PSM) or endoscope (ECM) whose contacts count as tool contacts.
INSTRUMENT_BODIES = {
    "PSM": ("roll", "wrist_pitch", "wrist_yaw", "jaw_1", "jaw_2"),
    "ECM": ("roll",),
}


def body_ids(model: mujoco.MjModel, names) -> np.ndarray:
    """Ids of the named bodies that exist in ``model``."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in names]
    return np.array([i for i in ids if i >= 0], dtype=int)


def instruments(model: mujoco.MjModel, arm_types: dict) -> dict:
    """Per arm with an instrument (``arm_types``: arm name → its kind, PSM or ECM: the
    :data:`INSTRUMENT_BODIES` of its kind), ``(body ids, per-geom mask)``: the arguments of
    :func:`contact_force` after the model and data, computed once per model."""
    out = {}
    for name, kind in arm_types.items():
        if kind in INSTRUMENT_BODIES:
            bodies = body_ids(model, [f"{name}/{b}" for b in INSTRUMENT_BODIES[kind]])
            out[name] = (bodies, instrument_geoms(model, bodies))
    return out


def instrument_geoms(model: mujoco.MjModel, bodies: np.ndarray) -> np.ndarray:
    """Per geom of ``model`` ((ngeom,) bool): whether it is on one of
    ``bodies`` (:func:`contact_force`'s selection, computed once per model)."""
    member = np.zeros(model.nbody, dtype=bool)
    member[bodies] = True
    return member[model.geom_bodyid]


def contact_force(
    model: mujoco.MjModel, data: mujoco.MjData, bodies: np.ndarray, geoms: np.ndarray | None = None
) -> np.ndarray:
    """Total contact force (N, world frame) that the environment exerts on ``bodies``
    (``geoms``: their :func:`instrument_geoms`, if the caller keeps them).

    Contacts between two of ``bodies`` (e.g. jaw against jaw) cancel out and are skipped.
    """
    total = np.zeros(3)
    if data.ncon == 0 or bodies.size == 0:
        return total
    # Vectorised selection of the contacts between ``bodies`` and the rest (this runs every
    # tick in the haptic loop).
    if geoms is None:
        geoms = instrument_geoms(model, bodies)
    contacts = data.contact
    inside = geoms[contacts.geom]  # (ncon, 2): geom1's and geom2's
    b2 = inside[:, 1]
    f6 = np.zeros(6)
    for i in np.flatnonzero(inside[:, 0] != b2):
        mujoco.mj_contactForce(model, data, int(i), f6)
        # f6 is in the contact frame (rows of frame); it acts on geom2, from geom1.
        f_world = contacts.frame[i].reshape(3, 3).T @ f6[:3]
        total += f_world if b2[i] else -f_world
    return total


def _renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """``mujoco.Renderer``, or a RuntimeError saying why MuJoCo has no OpenGL context: it
    takes its backend from ``MUJOCO_GL`` when it is first imported, so a program that imports
    mujoco before davinci_sim (which sets ``MUJOCO_GL=egl`` when unset) without a display
    gets GLFW, which cannot start headless."""
    try:
        return mujoco.Renderer(model, height, width)
    except mujoco.FatalError as e:
        if "OpenGL platform library" not in str(e):
            raise
        from mujoco.rendering.classic import gl_context

        backend = getattr(getattr(gl_context, "GLContext", None), "__module__", "unknown")
        raise RuntimeError(
            f"MuJoCo has no OpenGL context to render with (its backend: {backend}). MuJoCo "
            "chooses it when it is first imported: set MUJOCO_GL=egl (or osmesa) in the "
            "environment, or import davinci_sim before mujoco (it sets MUJOCO_GL=egl when "
            "unset)"
        ) from e


class CameraRenderer:
    """Offscreen renderer for named cameras of one model, one GL context per image size.

    ``fast=True`` (used for the endoscope) renders without shadows and without multisample
    anti-aliasing: on a CPU renderer (llvmpipe) shadow maps cost most of the frame, and an
    endoscope's light sits at the lens, so its own shadows are hardly visible anyway.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self._model = model
        self._renderers: dict[tuple[int, int, bool], mujoco.Renderer] = {}

    def render(
        self,
        data: mujoco.MjData,
        camera: str,
        width: int = 640,
        height: int = 480,
        *,
        fast: bool = False,
    ) -> np.ndarray:
        """RGB image (height x width x 3, uint8) from the named camera."""
        if mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
            names = [self._model.camera(i).name for i in range(self._model.ncam)]
            raise KeyError(f"no camera {camera!r}; cameras: {names}")
        key = (width, height, fast)
        if key not in self._renderers:
            vis = self._model.vis
            vis.global_.offwidth = max(vis.global_.offwidth, width)
            vis.global_.offheight = max(vis.global_.offheight, height)
            samples = vis.quality.offsamples
            if fast:  # the sample count is read when the GL context is made
                vis.quality.offsamples = 0
            try:
                self._renderers[key] = _renderer(self._model, height, width)
            finally:
                vis.quality.offsamples = samples
        r = self._renderers[key]
        r.update_scene(data, camera=camera)
        r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = not fast
        return r.render()

    def close(self) -> None:
        """Free the GL contexts. Each is made current first, so that MuJoCo's close does not
        restore the context that was current before: that may be another renderer's, which
        the garbage collector can free while this one closes (an unclosed simulation's), and
        restoring a freed context fails (EGL_BAD_CONTEXT)."""
        for r in self._renderers.values():
            context = getattr(r, "_gl_context", None)
            if context is not None:
                context.make_current()
            r.close()
        self._renderers.clear()
