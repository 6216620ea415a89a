"""The patient cart and its setup-joint (SUJ) arms (dvrk.md 1.6).

The cart frame is the world frame. Each SUJ arm is a 6-joint modified-DH chain (J0 the
vertical lift along the column) whose joints have the dVRK's names, ``SUJ/<ARM>/SUJ_<ARM>_J0``
… ``SUJ_<ARM>_J5`` (dvrk.md 1.6), below a base body
``SUJ/<ARM>/base`` placed at ``T_cart_sujbase`` (``world_origin_to_SUJ``). The visual links
follow the DH geometry: the lift carriage, the vertical posts (d) and the two horizontal
arms (a = 0.4318 m), the tilt joints and the mounting bracket of the carried arm.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.kinematics.arms import SUJArmKinematics
from davinci_sim.model.dh import add_dh_chain, link_segments
from davinci_sim.model.frames import set_pose
from davinci_sim.model.shapes import Painter, set_inertial

#: Masses of the SUJ links J0 … J5, kg. The real setup joints are heavy braked castings;
#: the values only need to be of the right order (the joints are servoed to a fixed pose).
SUJ_LINK_MASS = (6.0, 6.0, 5.0, 4.0, 2.5, 2.0)
_LINK_HALF = 0.035  # half thickness of the SUJ link bars, m
_HOUSING_RADIUS = 0.05


def add_cart(world):
    """The patient cart: base on wheels, the central column, the equipment tower."""
    cart = world.add_body(name="cart")
    paint = Painter(cart, prefix="cart/")
    paint.box([0.0, -0.18, 0.16], [0.36, 0.50, 0.10], "shell")
    paint.box([0.0, -0.48, 0.55], [0.30, 0.16, 0.30], "shell_dark")
    for x in (-0.30, 0.30):
        for y in (-0.62, 0.24):
            paint.cylinder([x - 0.03, y, 0.06], [x + 0.03, y, 0.06], 0.06, "black")
    paint.box([0.0, -0.015, 1.05], [0.10, 0.085, 0.80], "shell")
    paint.box([0.0, -0.015, 1.90], [0.13, 0.11, 0.05], "shell_dark")
    return cart


def add_suj_arm(cart, suj: SUJArmKinematics, q_ref) -> list:
    """One SUJ arm below ``cart``; returns its six link bodies (the last one carries the arm)."""
    prefix = f"SUJ/{suj.name}"
    base = cart.add_body(name=f"{prefix}/base")
    set_pose(base, suj.T_cart_sujbase)
    bodies = add_dh_chain(base, suj.chain, prefix, q_ref)
    owners = [base, *bodies]
    # Lift carriage on the column (J0 is prismatic: its travel is the column itself).
    Painter(bodies[0], prefix=f"{prefix}/").box([-0.02, 0.0, 0.0], [0.05, 0.07, 0.09], "shell_dark")
    for i, joint in enumerate(suj.chain.joints):
        segments = link_segments(suj.chain, i, q_ref)
        for owner, p0, p1 in segments:
            body = owners[i] if owner == "parent" else owners[i + 1]
            Painter(body).bar(p0, p1, _LINK_HALF, _LINK_HALF, "shell")
        body = bodies[i]
        if joint.is_revolute:
            Painter(body).cylinder([0, 0, -0.05], [0, 0, 0.05], _HOUSING_RADIUS, "shell_dark")
        child_mids = [(p0 + p1) / 2 for owner, p0, p1 in segments if owner == "child"]
        com = np.mean(child_mids, axis=0) if child_mids else np.zeros(3)
        mass = SUJ_LINK_MASS[i]
        set_inertial(body, mass, com, mass * 0.15**2)
    return bodies
