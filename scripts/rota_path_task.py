#!/usr/bin/env python
"""Write the ``rota_path`` task file: the Path task of Rota's dVRK-console study in our scene.

    PYTHONPATH=src python scripts/rota_path_task.py --clone rota

reads the trajectory the study's trainees followed (``Training1_0_traj0.csv`` of a trial at
the commit of ``scripts/derive_rota_reference.py``: 2,600 vertices, 115.8 mm, in Unity's
left-handed y-up world, metres), turns it into a right-handed z-up frame as the thesis's
post-processing does (x' = −x, y' = −z, z' = y), keeps the vertices the Ramer-Douglas-Peucker
simplification needs for a 20 µm tolerance (80 of them: under half their vertex spacing, so
the shape is theirs), and places it rigidly in our cart (world) frame: turned so that it
runs across the view (``TURN_DEG``), its bounding box centred beside the seed's path where
PSM1 reaches every vertex and the `surgical` endoscope sees them (``davinci-sim task check
rota_path``). The torus their trainees carried in the jaws (its size from their scene
``Assets/Training1.unity``: ``TORUS``) and the wrist's turns along the path (their control
group's mean, ``docs/study/rota_path/wrist.json``, written by ``scripts/rota_wrist.py``)
make the task's ``carry`` section. Writes ``src/davinci_sim/tasks/data/rota_path.yaml`` (or
``--out``).
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import json
import math
from pathlib import Path

import numpy as np

from davinci_sim.geometry.se3 import rot_z

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src/davinci_sim/tasks/data/rota_path.yaml"
TRAJECTORY = "Assessment/Evaluation/SubjectA/Training1/Training1_0/Training1_0_traj0.csv"
TOLERANCE_M = 2e-5
#: The path's bounding-box centre in the world frame, m (beside the seed's path).
CENTRE = (0.080, 1.185, 0.810)
#: The turn about the vertical that places it, deg: its long axis across the view. Their
#: endoscope's line of sight to the path is 99 deg from its long axis (its position solved
#: from the logs, scripts/rota_wrist.py): across their view too. (Placed unturned, receding
#: from our endoscope, the synthetic trainees finished none of 4 trials, mean deviation
#: 15-22 mm: their plan and corrections do not handle a path along the line of sight.)
TURN_DEG = 90.0
#: The wrist's turns along the path (scripts/rota_wrist.py).
WRIST = ROOT / "docs/study/rota_path/wrist.json"
#: Their torus (the ``Subject`` of ``Assets/Training1.unity``: eight capsule colliders of
#: radius 0.0843 on an octagon of apothem 0.767, in a parent scaled by 0.008008, Unity
#: units being metres): tube radius 0.675 mm, centre line 6.14 mm (apothem) to 6.65 mm
#: (corners) from its centre; a circle of 6.4 mm here. m.
TORUS = {"torus_radius": 0.0064, "tube_radius": 0.000675}


def _source():
    spec = importlib.util.spec_from_file_location(
        "derive_rota_reference", ROOT / "scripts" / "derive_rota_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def simplified(points: np.ndarray, tolerance: float) -> np.ndarray:
    """The vertices of ``points`` (n, 3) that Ramer-Douglas-Peucker keeps at ``tolerance``."""
    keep = np.zeros(len(points), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(points) - 1)]
    while stack:
        a, b = stack.pop()
        if b <= a + 1:
            continue
        chord = points[b] - points[a]
        length = np.linalg.norm(chord)
        rel = points[a + 1 : b] - points[a]
        if length > 0:
            dist = np.linalg.norm(np.cross(rel, chord / length), axis=1)
        else:
            dist = np.linalg.norm(rel, axis=1)
        i = int(np.argmax(dist))
        if dist[i] > tolerance:
            keep[a + 1 + i] = True
            stack += [(a, a + 1 + i), (a + 1 + i, b)]
    return points[keep]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clone", type=Path, required=True, help="a clone of their repository")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    source = _source()
    unity = np.loadtxt(io.StringIO(source.read(args.clone, TRAJECTORY)), delimiter=",",
                       skiprows=1)  # fmt: skip
    theirs = np.stack([-unity[:, 0], -unity[:, 2], unity[:, 1]], axis=1)
    waypoints = simplified(theirs, TOLERANCE_M)
    turned = waypoints @ rot_z(math.radians(TURN_DEG)).T
    box = (turned.min(axis=0) + turned.max(axis=0)) / 2
    world = turned - box + np.array(CENTRE)
    length = float(np.linalg.norm(np.diff(theirs, axis=0), axis=1).sum())
    wrist = json.loads(WRIST.read_text())
    largest = wrist["largest_turn_deg"]
    kept = float(np.linalg.norm(np.diff(world, axis=0), axis=1).sum())
    header = f"""\
# The Path task of Rota's dVRK-console training study (MSc thesis, Politecnico di Milano
# 2022/23; training.md §4): follow a 3-D trajectory that rises as it runs across the
# view, guided by their fixture (viscous + elastic, the sum capped at 3 N), at their
# motion scale 0.5. Units: m, N, s. Written by scripts/rota_path_task.py: do not edit.
#
# Source: github.com/{source.REPOSITORY}
# at {source.SOURCE_COMMIT[:8]}, {TRAJECTORY}:
# {len(theirs)} vertices, {1e3 * length:.2f} mm, in Unity's frame, turned right-handed z-up as
# their post-processing does; kept: the {len(world)} vertices Ramer-Douglas-Peucker needs at
# {1e6 * TOLERANCE_M:.0f} um ({1e3 * kept:.2f} mm). Turned {TURN_DEG:g} deg about the
# vertical (its long axis across the view; TURN_DEG in the script says why), its box
# centred at {CENTRE} m beside the seed's path, where PSM1 reaches it and
# the `surgical` endoscope sees it (`davinci-sim task check rota_path`); their camera's
# pose is not ours. The torus carried in the jaws: their scene's (TORUS in the script);
# the wrist's turns: their control group's mean, from the same commit's logs
# (docs/study/rota_path/wrist.json; a trial's largest turn: median
# {largest["median"]:g} deg, {largest["min"]:g}-{largest["max"]:g}).
"""
    lines = [
        "name: rota_path",
        "description: >-",
        "  Follow the rising trajectory from its start to its end (Rota's dVRK-console",
        "  training task, guided by their viscous and elastic fixture).",
        "frame: world",
        "waypoints:",
        *(f"  - [{x:.6f}, {y:.6f}, {z:.6f}]" for x, y, z in world),
        "corner_radius: 0.0        # (their trajectory is already smooth)",
        f"numbered: [0, {len(world) - 1}]       # (its ends: the rest is the curve's shape)",
        "start_tolerance: 0.003",
        "finish_tolerance: 0.003",
        "min_progress: 0.5",
        "tube_radius: 0.003",
        "teleop:",
        "  psm: PSM1",
        "  mtm: MTMR",
        "  scale: 0.5              # theirs (rosws/src/dvrk_simulator/setscale.py)",
        "  keyframe: surgical",
        "fixture:                  # theirs, at full assistance (training.md §4)",
        "  type: viscous_elastic",
        "  B: 15.0",
        "  elastic_gain: 0.8",
        "  threshold: 0.002",
        "  half: 0.002",
        "  slope: 500.0",
        "  max_force: 3.0",
        "conditions:               # their control group, and their assisted group's days",
        '  - {name: "control", type: none}',
        *(
            f'  - {{name: "assisted x{a:g}", type: viscous_elastic, B: 15.0, '
            f"elastic_gain: 0.8, threshold: 0.002, half: 0.002, slope: 500.0, "
            f"max_force: 3.0, assistance: {a:g}}}"
            for a in (1.0, 0.75, 0.5, 0.25)
        ),
        "carry:                    # their torus, and their control group's wrist turns",
        f"  torus_radius: {TORUS['torus_radius']}",
        f"  tube_radius: {TORUS['tube_radius']}",
        "  grasp_depth: 0.006",
        f"  progress: [{', '.join(f'{s:g}' for s in wrist['knots'])}]",
        "  turn:                   # rad, world axes: from the start orientation",
        *(f"    - [{x:.6f}, {y:.6f}, {z:.6f}]" for x, y, z in wrist["mean_turn_rad"]),
        "visual:",
        "  tube_radius: 0.0006",
        "  marker_radius: 0.0018",
        "  path_rgba: [0.2, 0.9, 0.3, 0.9]",
        "  marker_rgba: [1.0, 0.85, 0.1, 1.0]",
    ]
    args.out.write_text(header + "\n".join(lines) + "\n")
    print(f"{len(world)} waypoints ({1e3 * kept:.2f} of {1e3 * length:.2f} mm) -> {args.out}")


if __name__ == "__main__":
    main()
