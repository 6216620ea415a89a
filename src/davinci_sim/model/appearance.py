"""Materials, textures, lights and rendering settings shared by the whole scene.

Everything is procedural (MuJoCo builtin textures, flat colours): the model ships no files.
Colours follow the look of the real system and of the paper's Unity scene (seed fig. 1):
white arm shells, yellow/red parallelogram links, black insertion rails, a coloured
instrument carriage per PSM, a blue operating table.
"""

from __future__ import annotations

import mujoco

#: material name -> (rgba, specular, shininess)
MATERIALS: dict[str, tuple[tuple[float, float, float, float], float, float]] = {
    "shell": ((0.93, 0.93, 0.91, 1.0), 0.3, 0.4),
    "shell_dark": ((0.55, 0.56, 0.58, 1.0), 0.3, 0.4),
    "black": ((0.08, 0.08, 0.09, 1.0), 0.4, 0.5),
    "metal": ((0.72, 0.74, 0.77, 1.0), 0.8, 0.8),
    "steel_dark": ((0.35, 0.36, 0.38, 1.0), 0.7, 0.7),
    "link_yellow": ((0.93, 0.85, 0.25, 1.0), 0.3, 0.4),
    "link_red": ((0.88, 0.30, 0.25, 1.0), 0.3, 0.4),
    "carriage_PSM1": ((0.95, 0.62, 0.10, 1.0), 0.3, 0.4),
    "carriage_PSM2": ((0.25, 0.75, 0.30, 1.0), 0.3, 0.4),
    "carriage_PSM3": ((0.25, 0.50, 0.90, 1.0), 0.3, 0.4),
    "carriage_ECM": ((0.30, 0.30, 0.33, 1.0), 0.3, 0.4),
    "table": ((0.10, 0.55, 0.80, 1.0), 0.2, 0.3),
    "table_frame": ((0.80, 0.80, 0.82, 1.0), 0.5, 0.5),
    "tissue": ((0.85, 0.45, 0.42, 1.0), 0.4, 0.6),
    "organ": ((0.78, 0.28, 0.22, 1.0), 0.5, 0.7),
    "bead": ((0.15, 0.80, 0.95, 1.0), 0.5, 0.6),
    "console": ((0.62, 0.63, 0.66, 1.0), 0.3, 0.4),
    "console_dark": ((0.22, 0.23, 0.25, 1.0), 0.3, 0.4),
    "viewer_glass": ((0.05, 0.10, 0.20, 1.0), 0.9, 0.9),
    "mtm": ((0.85, 0.86, 0.88, 1.0), 0.4, 0.5),
    "mtm_dark": ((0.25, 0.25, 0.28, 1.0), 0.4, 0.5),
}


def add_materials(spec: mujoco.MjSpec) -> None:
    """Add the scene's materials, the checker floor texture and the sky box."""
    for name, (rgba, specular, shininess) in MATERIALS.items():
        spec.add_material(name=name, rgba=rgba, specular=specular, shininess=shininess)
    spec.add_texture(
        name="floor_checker",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.32, 0.33, 0.35],
        rgb2=[0.26, 0.27, 0.29],
        width=256,
        height=256,
    )
    floor = spec.add_material(name="floor", texrepeat=[8, 8])
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "floor_checker"
    spec.add_texture(
        name="sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.55, 0.68, 0.82],
        rgb2=[0.20, 0.22, 0.26],
        width=256,
        height=256,
    )


def configure_visual(spec: mujoco.MjSpec, *, offwidth: int, offheight: int) -> None:
    """Offscreen buffer size, lighting and near clipping suited to a 1 cm endoscope view."""
    spec.visual.global_.offwidth = offwidth
    spec.visual.global_.offheight = offheight
    # The endoscope looks at tissue 2-10 cm away: the default near plane (1 % of the model
    # extent, ~4 cm here) would clip the instruments.
    spec.visual.map.znear = 0.002
    spec.visual.map.zfar = 60.0
    spec.visual.quality.shadowsize = 4096
    spec.visual.headlight.ambient = [0.25, 0.25, 0.25]
    spec.visual.headlight.diffuse = [0.35, 0.35, 0.35]
    spec.visual.headlight.specular = [0.1, 0.1, 0.1]
    spec.visual.rgba.haze = [0.15, 0.18, 0.22, 1.0]


def add_room_lights(world) -> None:
    """Ceiling lights of the operating room (the endoscope carries its own light)."""
    world.add_light(
        name="ceiling_key",
        pos=[0.6, 0.3, 3.2],
        dir=[-0.15, 0.25, -1.0],
        diffuse=[0.6, 0.6, 0.6],
        specular=[0.2, 0.2, 0.2],
        castshadow=True,
    )
    world.add_light(
        name="ceiling_fill",
        pos=[-1.8, -1.0, 3.0],
        dir=[0.3, 0.3, -1.0],
        diffuse=[0.35, 0.35, 0.35],
        specular=[0.05, 0.05, 0.05],
        castshadow=False,
    )
