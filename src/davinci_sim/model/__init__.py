"""Procedural MuJoCo model of the da Vinci system (dVRK): patient cart, SUJ, PSMs, ECM,
surgeon console with MTMs, operating table and phantom.

Everything is generated with :class:`mujoco.MjSpec` from the dVRK kinematics of
:mod:`davinci_sim.kinematics` (no XML or mesh files). MuJoCo's joint positions equal the
dVRK joint values; names follow ``<ARM>/<joint name>`` (bodies, joints, actuators).

Example::

    from davinci_sim.model import build_model
    model = build_model("psm1_ecm_mtmr")
"""

from davinci_sim.model.actuators import ServoGains, servo_gains
from davinci_sim.model.builder import ECM_SUJ_SURGICAL, TIMESTEP, build_model, build_spec
from davinci_sim.model.cameras import DEFAULT_ENDOSCOPE_FOVY_DEG, CameraConfig, ExternalCamera
from davinci_sim.model.config import ARM_NAMES, SCENES, SceneConfig, resolve_scene, scene_arms

__all__ = [
    "ARM_NAMES",
    "DEFAULT_ENDOSCOPE_FOVY_DEG",
    "ECM_SUJ_SURGICAL",
    "SCENES",
    "TIMESTEP",
    "CameraConfig",
    "ExternalCamera",
    "SceneConfig",
    "ServoGains",
    "build_model",
    "build_spec",
    "resolve_scene",
    "scene_arms",
    "servo_gains",
]
