"""A scripted operator for the task tests whose objects are grasped in physics (peg
transfer, the needle): ``move_cp`` and streamed ``servo_cp`` of the tips (world frame,
orientation kept), jaw moves, and a task monitor fed every few ticks."""

import numpy as np

from davinci_sim.model import SceneConfig
from davinci_sim.sim.simulation import Simulation
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.state import TaskMonitor
from davinci_sim.tasks.trainer import InstrumentContacts

SCENE = SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False)


class Operator:
    """A scripted operator: move_cp of the tips (world frame, orientation kept) and jaw
    move_jp, waiting for each; a task monitor fed every ``every`` ticks."""

    def __init__(self, task, every=4, counts=("transferred", "handoffs", "dropped")):
        self.task = task
        self.sim = Simulation(SCENE, keyframe="surgical", edit_spec=lambda spec: task.draw(spec))
        m, d = self.sim.model, self.sim.data
        self.probe = task.probe(m)
        self.monitor = TaskMonitor(task)
        contacts = InstrumentContacts(m, task.teleop.psm, task.CONTACT_IGNORE)
        self.totals = dict.fromkeys(counts, 0)
        self._every, self._ticks, cache = every, 0, {}
        op = self

        class Watch:
            name = "watch"

            def pre_step(self, t):
                pass

            def post_step(self, t):
                op._ticks += 1
                if op._ticks % op._every:
                    return
                tip = d.site_xpos[m.site(f"{task.teleop.psm}/tip").id]
                count, force = contacts.measure(m, d)
                op.monitor.observe(Sample.of(t, tip, contacts=count, tool_force=force,
                                             **task.scene_fields(m, d, cache)))  # fmt: skip
                for k in op.totals:
                    op.totals[k] += int(op.monitor.observations[k][0])

            def snapshot(self):
                return None

        self.sim.add_component(Watch())
        for n in ("PSM1", "PSM2", "ECM"):
            assert self.sim.arms[n].state_command("enable")
            assert self.sim.arms[n].state_command("home")
        assert self.sim.run_until(lambda: all(self.sim.arms[n].is_homed() and not
                                              self.sim.arms[n].is_busy() for n in self.sim.arms),
                                  20)  # fmt: skip
        self.T_camera_world = np.linalg.inv(self.sim.T_cart_camera())
        self.R = {n: self.tip(n)[:3, :3].copy() for n in ("PSM1", "PSM2")}

    def tip(self, n):
        m, d = self.sim.model, self.sim.data
        s = m.site(f"{n}/tip").id
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = d.site_xmat[s].reshape(3, 3), d.site_xpos[s]
        return T

    def move(self, n, p_world, wait=True):
        G = np.eye(4)
        G[:3, :3], G[:3, 3] = self.R[n], p_world
        result = self.sim.arms[n].move_cp(self.T_camera_world @ G)
        assert result, result.message
        if wait:
            self.wait(n)

    def glide(self, moves, speed=0.15):
        """Stream ``servo_cp`` setpoints along straight lines to ``moves`` (arm → world
        point) at once, minimum-jerk timed (peak ``speed``, m/s): a script's (or a
        teleoperation's) motion, faster than ``move_cp``'s joint trajectories."""
        sim = self.sim
        lines = {n: (self.tip(n)[:3, 3].copy(), np.asarray(p, float)) for n, p in moves.items()}
        far = max(np.linalg.norm(b - a) for a, b in lines.values())
        duration = max(0.1, 1.875 * far / speed)
        t0 = sim.time
        while sim.time - t0 < duration:
            x = min(1.0, (sim.time - t0 + sim.model.opt.timestep) / duration)
            s = x**3 * (10 - 15 * x + 6 * x * x)
            for n, (a, b) in lines.items():
                G = np.eye(4)
                G[:3, :3], G[:3, 3] = self.R[n], a + s * (b - a)
                assert sim.arms[n].servo_cp(self.T_camera_world @ G)
            sim.tick()
        sim.run_for(0.1)

    def wait(self, *arms):
        assert self.sim.run_until(lambda: not any(self.sim.arms[n].is_busy() for n in arms), 10)
        self.sim.run_for(0.02)

    def jaw(self, n, angle, wait=True, servo=False):
        """move_jp (the dVRK's jaw trajectory), or servo_jp for 0.1 s (as a teleoperation
        streams the gripper's angle)."""
        if servo:
            assert self.sim.arms[n].jaw.servo_jp(angle)
            self.sim.run_for(0.1 if wait else 0.0)
            return
        assert self.sim.arms[n].jaw.move_jp(angle)
        if wait:
            assert self.sim.run_until(lambda: not self.sim.arms[n].jaw.is_busy(), 5)
