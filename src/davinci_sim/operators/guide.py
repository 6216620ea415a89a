"""A scripted hand that brings a teleoperated tool to a point through its MTM: what a
benchmark or a test does to put an instrument somewhere (on the suture pad's skin, say) the
way a person at the console would, the teleoperation and its scale in between."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def guide_tool(
    sim,
    teleop: str,
    p_goal_world,
    until: Callable[[], bool],
    *,
    max_move: float = 0.004,
    period: float = 0.2,
    descend: float = 0.001,
    moves: int = 60,
) -> bool:
    """Move the hand on ``teleop``'s MTM (its simulated device) so that its PSM's tool tip
    goes to ``p_goal_world`` (world frame, m), at most ``max_move`` (m, at the tool) a move,
    one move every ``period`` s of simulated time, until ``until()`` holds; once the tip is
    within 1 mm of the goal, the goal goes down ``descend`` m a move (pressing on what lies
    under it). The teleoperation must be following. Returns ``until()`` after at most
    ``moves`` moves."""
    tel = sim.components["console"].psm_teleops[teleop]
    device, scale = tel.device, tel.config.scale
    site = sim.model.site(f"{tel.psm.name}/tip").id
    goal = np.array(p_goal_world, dtype=float)
    for _ in range(moves):
        if until():
            return True
        step = goal - sim.data.site_xpos[site]
        if np.linalg.norm(step) < 0.001:
            goal[2] -= descend
        step *= min(1.0, max_move / max(float(np.linalg.norm(step)), 1e-9))
        T = device.input().T_hrsv_tip.copy()  # (HRSV: the camera's axes, scaled)
        T[:3, 3] += sim.T_cart_camera()[:3, :3].T @ step / scale
        device.move_hand(T)
        sim.run_for(period)
    return until()
