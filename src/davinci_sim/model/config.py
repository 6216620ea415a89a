"""Scene configurations: which arms, console, patient side and cameras a model contains."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from davinci_sim.model.cameras import CameraConfig, ExternalCamera

#: All arms in canonical order.
ARM_NAMES: tuple[str, ...] = ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR")
PATIENT_SIDE_ARMS: tuple[str, ...] = ("ECM", "PSM1", "PSM2", "PSM3")
"""Arms carried by the patient cart's setup joints (SUJ arm order = dVRK plug order)."""
MTM_NAMES: tuple[str, ...] = ("MTML", "MTMR")


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
