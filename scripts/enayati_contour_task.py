#!/usr/bin/env python
"""Write the ``enayati_contour`` task file: a stand-in for the static task of Enayati et al.
(IROS 2016, training.md §4), the study the seed's viscous law comes from.

    PYTHONPATH=src python scripts/enayati_contour_task.py

Their static task: "tension and cut along the curved contour of a mass" in a virtual
environment, the cutting tool guided by their law (``VR``: B = 80 N·s/m, the force capped at
F = 5 N, B scaled down by ‖d‖/D_m within D_m = 2 mm of the path), the user's motion scaled
down by 3. The paper gives neither the contour's shape nor its size (its Fig. 4 shows a
rounded mass), so this task is a stand-in chosen before any simulation of it was run: half
of a circle of radius :data:`RADIUS_M` around a mass, in a horizontal plane 3 cm above the
tissue pad (the seed path's first height), centred beside the seed's path where PSM1
reaches it and the `surgical` endoscope sees it (``davinci-sim task check
enayati_contour``). Not modelled: the tensioning second tool, the cut (penetrating the
tissue), their 14 Hz display; their dynamic task (the scene oscillating at 0.3 Hz) needs
a moving path, which the simulator does not have.

Their law in our kinds: the seed's ``viscous`` law with ``transition`` = D_m. Enayati scale
B by ‖d‖/D_m before the cap (``min(F, B'·…)``), the ``transition`` ramp scales the capped
force (``min(1, ‖d‖/D_m)·min(F, …)``): the two are equal wherever the uncapped force is
below F, which at B = 80 N·s/m is every tool speed below F/B = 62.5 mm/s; beyond D_m they
are the same law.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src/davinci_sim/tasks/data/enayati_contour.yaml"
#: The mass's centre in the world frame, m: beside the seed's path, at its first height.
CENTRE = (0.080, 1.185, 0.795)
#: The contour's radius, m (half a circle: 47.1 mm of path).
RADIUS_M = 0.015
#: Vertices of the polyline: chords of 3°, within 21 µm of the circle.
VERTICES = 61

HEADER = """\
# A stand-in for the static task of Enayati et al., IROS 2016 (training.md §4): cut along
# the curved contour of a mass, guided by their viscosity-based law (VR), the motion scaled
# down by 3. Units: m, N, s. Written by scripts/enayati_contour_task.py (its docstring says
# what was chosen and why, and what is not modelled): do not edit.
#
# Half a circle of radius {radius_mm:g} mm ({length_mm:.1f} mm of path) around a mass
# centred at {centre} m, 3 cm above the tissue pad, beside the seed's path.
"""


def waypoints() -> np.ndarray:
    """The contour's vertices, (VERTICES, 3) m: from the mass's left (−x) round its far
    side (+y) to its right (+x)."""
    angle = np.linspace(np.pi, 0.0, VERTICES)
    centre = np.asarray(CENTRE)
    offsets = RADIUS_M * np.column_stack([np.cos(angle), np.sin(angle), np.zeros(VERTICES)])
    return centre + offsets


def document() -> str:
    points = waypoints()
    length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    centre = "(" + ", ".join(f"{c:g}" for c in CENTRE) + ")"
    lines = [HEADER.format(radius_mm=RADIUS_M * 1e3, length_mm=length * 1e3, centre=centre)]
    lines.append(
        "name: enayati_contour\n"
        "description: >-\n"
        "  Follow the curved contour around the mass from its start to its end (a stand-in\n"
        "  for the static task of Enayati et al. 2016, guided by their viscous law).\n"
        "frame: world\n"
        "waypoints:\n"
    )
    lines += [f"  - [{p[0]:.6f}, {p[1]:.6f}, {p[2]:.6f}]\n" for p in points]
    vr = "type: viscous, B: 80.0, G_max: 5.0, transition: 0.002"
    lines.append(
        "corner_radius: 0.0        # (a smooth curve already)\n"
        f"numbered: [0, {VERTICES - 1}]       # (its ends: one stroke)\n"
        "start_tolerance: 0.003\n"
        "finish_tolerance: 0.003\n"
        "min_progress: 0.5\n"
        "tube_radius: 0.003\n"
        "teleop:\n"
        "  psm: PSM1\n"
        "  mtm: MTMR\n"
        "  scale: 0.333333        # theirs: the motion scaled down by a factor of 3\n"
        "  keyframe: surgical\n"
        "fixture:                  # theirs, VR (Table I: F = 5 N, B = 80 N s/m, D_m = 2 mm)\n"
        f"  {vr.replace(', ', chr(10) + '  ')}\n"
        "conditions:               # their UC (unconstrained) and VR cases\n"
        '  - {name: "UC", type: none}\n'
        f'  - {{name: "VR", {vr}}}\n'
        "visual:\n"
        "  tube_radius: 0.0006\n"
        "  marker_radius: 0.0018\n"
        "  path_rgba: [0.2, 0.5, 1.0, 0.6]   # their semi-transparent blue line\n"
        "  marker_rgba: [1.0, 0.85, 0.1, 1.0]\n"
    )
    return "".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    args.out.write_text(document())
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
