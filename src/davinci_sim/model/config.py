"""Scene configurations: which arms, console, patient side and cameras a model contains."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from davinci_sim.model.cameras import CameraConfig, ExternalCamera

#: All arms in canonical order.
ARM_NAMES: tuple[str, ...] = ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR")
PATIENT_SIDE_ARMS: tuple[str, ...] = ("ECM", "PSM1", "PSM2", "PSM3")
"""Arms carried by the patient cart's setup joints (SUJ arm order = dVRK plug order)."""
MTM_NAMES: tuple[str, ...] = ("MTML", "MTMR")


def _joint_errors(given, arms: tuple[str, ...]) -> tuple:
    """:attr:`SceneConfig.joint_errors` checked and in a canonical form (sorted pairs of a
    PSM of ``arms`` and three floats; zero errors left out). ValueError otherwise."""
    pairs = given.items() if isinstance(given, dict) else given
    out = {}
    try:
        for name, errors in pairs:
            values = tuple(float(e) for e in errors)
            if name not in arms or not str(name).startswith("PSM"):
                raise ValueError(f"{name!r} is not a PSM of the scene {list(arms)}")
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                raise ValueError(f"{name}: three finite errors (yaw rad, pitch rad, "
                                 f"insertion m), got {errors!r}")  # fmt: skip
            if name in out:
                raise ValueError(f"{name} given twice")
            if any(values):
                out[name] = values
    except (TypeError, ValueError) as e:
        raise ValueError(f"joint_errors: {e}") from None
    return tuple(sorted(out.items()))


#: The largest joint errors the AccelNet Surgical Robotics Challenge draws for a PSM (its
#: ``psm_arm.py``: ±5° outer yaw, ±5° outer pitch, ±5 mm insertion): rad, rad, m.
MAX_JOINT_ERRORS = (math.radians(5.0), math.radians(5.0), 0.005)


def random_joint_errors(psms, seed: int, max_errors=MAX_JOINT_ERRORS) -> dict:
    """Joint errors for each PSM of ``psms`` drawn uniformly within ± ``max_errors`` (rad,
    rad, m) from ``seed``: a :attr:`SceneConfig.joint_errors` mapping."""
    import numpy as np

    rng = np.random.default_rng(seed)
    m = np.asarray(max_errors, dtype=float)
    return {p: tuple(float(e) for e in rng.uniform(-m, m)) for p in psms if p.startswith("PSM")}


def parse_joint_errors(texts) -> dict:
    """``["PSM1=0.044,-0.008,0.004", ...]`` (rad, rad, m) as a :attr:`SceneConfig.joint_errors`
    mapping. ValueError, naming the text, for anything else."""
    out = {}
    for text in texts:
        name, _, values = str(text).partition("=")
        try:
            errors = tuple(float(v) for v in values.split(","))
        except ValueError:
            errors = ()
        if not name.startswith("PSM") or len(errors) != 3 or name in out:
            raise ValueError(f"joint errors are PSMn=YAW,PITCH,INSERTION (rad, rad, m), once "
                             f"per PSM: got {text!r}")  # fmt: skip
        out[name] = errors
    return out


@dataclass(frozen=True)
class SceneConfig:
    """What one generated scene contains.

    Every PSM needs the ECM (the endoscope defines the camera frame the PSMs are teleoperated
    in), every PSM/ECM comes with its SUJ arm and the patient cart, and the MTMs come with
    the surgeon console.
    """

    arms: tuple[str, ...] = ARM_NAMES
    """Subset of :data:`ARM_NAMES`."""
    include_console: bool = True
    """The surgeon console (required by, and added with, any MTM)."""
    include_patient: bool = True
    """Operating table, tissue phantom and the bead ``object/bead``."""
    endoscope: CameraConfig = CameraConfig()
    cameras: tuple[ExternalCamera, ...] = ()
    """Extra named world cameras (the ``overview`` camera is always there)."""
    joint_errors: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    """The robots' kinematic inaccuracy, per PSM (a mapping or ``(name, errors)`` pairs):
    constant errors of its first three joints (outer yaw and pitch, rad; insertion, m), as
    the AccelNet Surgical Robotics Challenge perturbs its PSMs (up to 5°, 5°, 5 mm). The arm
    reads and servoes the joint values as before, by its nominal kinematics
    (``measured_js``, ``measured_cp``, IK), while its links stand at ``q + errors``: the
    instrument is where the camera sees it, not where the arm reports it. Default: none."""

    def __post_init__(self) -> None:
        arms = tuple(self.arms)
        unknown = [a for a in arms if a not in ARM_NAMES]
        if unknown:
            raise ValueError(f"unknown arms {unknown}; known arms: {list(ARM_NAMES)}")
        if len(set(arms)) != len(arms):
            raise ValueError(f"arms listed twice in {arms!r}")
        if any(a.startswith("PSM") for a in arms) and "ECM" not in arms:
            raise ValueError(f"scenes with a PSM need the ECM (camera frame), got {arms!r}")
        if any(a in MTM_NAMES for a in arms) and not self.include_console:
            raise ValueError(f"MTMs need include_console=True, got arms {arms!r}")
        names = [c.name for c in self.cameras]
        if len(set(names)) != len(names) or "overview" in names:
            raise ValueError(f"camera names must be unique and not 'overview', got {names}")
        # Canonical order, so that two configs with the same arms build the same model.
        object.__setattr__(self, "arms", tuple(a for a in ARM_NAMES if a in arms))
        object.__setattr__(self, "joint_errors", _joint_errors(self.joint_errors, self.arms))

    def errors_of(self, psm: str) -> tuple[float, float, float]:
        """``psm``'s :attr:`joint_errors` (zeros if none)."""
        return dict(self.joint_errors).get(psm, (0.0, 0.0, 0.0))

    @property
    def patient_side_arms(self) -> tuple[str, ...]:
        """PSMs/ECM of the scene, in SUJ order (ECM first)."""
        return tuple(a for a in PATIENT_SIDE_ARMS if a in self.arms)

    @property
    def mtms(self) -> tuple[str, ...]:
        return tuple(a for a in MTM_NAMES if a in self.arms)


SCENES: dict[str, SceneConfig] = {
    "full": SceneConfig(),
    "psm1_ecm_mtmr": SceneConfig(arms=("PSM1", "ECM", "MTMR")),
    "psm1": SceneConfig(arms=("PSM1", "ECM"), include_console=False),
    "psm1_open": SceneConfig(arms=("PSM1", "ECM"), include_console=False, include_patient=False),
}
"""Named scenes: everything; PSM1 + ECM + MTMR (fast teleoperation tasks); PSM1 + ECM;
PSM1 + ECM without the table and patient (room for sweeps over the whole joint range, as the
dVRK's gravity-compensation data collection makes)."""


def resolve_scene(scene: str | SceneConfig = "full", **overrides) -> SceneConfig:
    """A :class:`SceneConfig` from a scene name or config, with fields replaced by ``overrides``."""
    if isinstance(scene, str):
        if scene not in SCENES:
            raise KeyError(f"unknown scene {scene!r}; known scenes: {sorted(SCENES)}")
        scene = SCENES[scene]
    elif not isinstance(scene, SceneConfig):
        raise TypeError(f"scene must be a name or a SceneConfig, got {scene!r}")
    if overrides:
        fields = {f.name for f in dataclasses.fields(SceneConfig)}
        bad = sorted(set(overrides) - fields)
        if bad:
            raise TypeError(f"unknown SceneConfig fields {bad}; fields: {sorted(fields)}")
        scene = dataclasses.replace(scene, **overrides)
    return scene


def scene_arms(scene: str | SceneConfig = "full") -> tuple[str, ...]:
    """The arms of ``scene`` in canonical order (SUJ arms not included)."""
    return resolve_scene(scene).arms
