"""Collision classes: which geoms may touch which (contype/conaffinity bits).

Contacts are kept cheap and robust: only the instruments (shaft, wrist, jaws), the endoscope
shaft, the environment (floor, table, phantom) and graspable objects collide. Arm and console
structure is visual only.

Instruments collide with each other (a clash of two PSMs' instruments, or of an instrument
and the endoscope, is a contact the trainer counts) but never with themselves: each arm's
tool geoms carry their own bit (:data:`INSTRUMENT_BITS`, :func:`tool_bits`) in ``contype``
and every *other* arm's bit in ``conaffinity``, so one instrument's two jaws (siblings,
which MuJoCo would otherwise report as touching) and its shaft and wrist never make a pair,
while the pairs of two arms do. Their ``contype`` also keeps :data:`TOOL_BIT`, the bit the
environment and objects accept.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

GeomKind = Literal["visual", "env", "tool", "object"]

ENV_BIT = 1
TOOL_BIT = 2
OBJECT_BIT = 4

#: Each instrument's own bit (see the module docstring): the arms that carry a tool geom.
INSTRUMENT_BITS: dict[str, int] = {"PSM1": 8, "PSM2": 16, "PSM3": 32, "ECM": 64}
ALL_INSTRUMENTS = sum(INSTRUMENT_BITS.values())

#: kind -> (contype, conaffinity). MuJoCo makes a pair collide when
#: (contype1 & conaffinity2) or (contype2 & conaffinity1) is non-zero. A ``tool`` geom's
#: bits also depend on its arm (:func:`tool_bits`); these are the arm-less ones.
COLLISION_BITS: dict[str, tuple[int, int]] = {
    "visual": (0, 0),
    "env": (ENV_BIT, TOOL_BIT | OBJECT_BIT),
    "tool": (TOOL_BIT, ENV_BIT | OBJECT_BIT),
    "object": (OBJECT_BIT, ENV_BIT | TOOL_BIT | OBJECT_BIT),
}

#: Rendering groups: 0 = geoms that collide, 1 = visual-only structure. Both are shown by
#: MuJoCo's default visualisation options.
GEOM_GROUP = {"visual": 1, "env": 0, "tool": 0, "object": 0}

# Grasping needs high friction and torsional friction (condim 4) so that a small bead held
# at two contacts does not spin out. MuJoCo's soft contacts yield in proportion to the
# contact's mobility, which is large for a gram-sized bead: with the default impedance the
# 0.16 N·m jaws (≈ 20 N at the bead) would sink centimetres into it and squeeze it out.
# Tool and object contacts are therefore nearly hard (impedance 0.99-0.999) with a 3 ms
# time constant (≥ 2 timesteps at 1 ms, MuJoCo's stability advice): ≈ 1 mm under full grip.
TOOL_FRICTION = np.array([1.2, 0.02, 0.0001])
OBJECT_FRICTION = np.array([1.0, 0.02, 0.0001])
ENV_FRICTION = np.array([0.8, 0.005, 0.0001])
CONTACT_SOLREF = np.array([0.003, 1.0])
CONTACT_SOLIMP = np.array([0.99, 0.999, 0.0005, 0.5, 2.0])
CONTACT_CONDIM = 4


def tool_bits(arm: str) -> tuple[int, int]:
    """(contype, conaffinity) of a tool geom of ``arm`` (a key of :data:`INSTRUMENT_BITS`):
    it touches the environment, objects and the other arms' tools, not its own arm's."""
    if arm not in INSTRUMENT_BITS:
        raise ValueError(f"no instrument bit for arm {arm!r}; arms: {sorted(INSTRUMENT_BITS)}")
    own = INSTRUMENT_BITS[arm]
    return TOOL_BIT | own, ENV_BIT | OBJECT_BIT | (ALL_INSTRUMENTS & ~own)


def apply(geom, kind: GeomKind, arm: str | None = None) -> None:
    """Give ``geom`` the collision bits, group and contact parameters of ``kind``; a
    ``tool`` geom of an ``arm`` (``PSM1``, ``ECM``, ...) collides with the other arms'
    tools too (:func:`tool_bits`; without an arm, with none)."""
    if kind not in COLLISION_BITS:
        raise ValueError(f"unknown geom kind {kind!r}; known: {sorted(COLLISION_BITS)}")
    if kind == "tool" and arm is not None:
        geom.contype, geom.conaffinity = tool_bits(arm)
    else:
        geom.contype, geom.conaffinity = COLLISION_BITS[kind]
    geom.group = GEOM_GROUP[kind]
    if kind == "visual":
        geom.density = 0.0
        return
    geom.condim = CONTACT_CONDIM
    geom.solref = CONTACT_SOLREF
    geom.solimp = CONTACT_SOLIMP
    geom.friction = {"env": ENV_FRICTION, "tool": TOOL_FRICTION, "object": OBJECT_FRICTION}[kind]
