"""The needle kinds' compiled step (:mod:`davinci_sim.tasks.needle_row`) against their numpy
step, the oracle: the same bits, sample after sample, for trials whose needle is picked up,
handed over, dropped, lifted and delivered, or driven into the skin, through it, out of it
at its marks and away from them, and backed out where it went in."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from davinci_sim.tasks import load_task
from davinci_sim.tasks.base import Sample

PSM1_JAWS, PSM2_JAWS = 0b11, 0b1100
GRASPS = (0, 0, PSM1_JAWS, PSM2_JAWS, PSM1_JAWS | PSM2_JAWS, 0b01, 0b0100)


def _needle_in_pad(theta: float, dx: float, dy: float, tilt: float, r: float) -> np.ndarray:
    """The needle's frame in the pad's: turned by ``theta`` about its centre in the pad's
    x-z plane (the point goes down into the skin as theta grows, through the default marks'
    circle), its centre moved ``dx``, ``dy`` and its plane tilted ``tilt`` about x."""
    R0 = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    c, s = math.cos(-theta), math.sin(-theta)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    c, s = math.cos(tilt), math.sin(tilt)
    Rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    T = np.eye(4)
    T[:3, :3] = Rx @ Ry @ R0
    T[:3, 3] = [dx, dy, math.sqrt(r * r - 0.007**2)]
    return T


class Trials:
    """n trials' samples: each trial's jaws change now and then, its needle rests, moves,
    jumps up and falls back; with ``pad`` (the drive) the needle turns about its centre
    through the skin and back, its centre off the marks by a trial's own amount."""

    def __init__(self, task, n: int, seed: int, pad: bool) -> None:
        self.task, self.n, self.pad = task, n, pad
        self.rng = np.random.default_rng(seed)
        self.t = np.zeros(n)
        self.grasp = np.zeros(n, dtype=np.int64)
        self.p = np.tile(task.T_world_start[:3, 3], (n, 1))
        self.theta = np.zeros(n)
        self.turn = self.rng.choice([-1.0, 1.0], n) * math.radians(1.5)
        self.off = self.rng.uniform(-0.003, 0.003, (n, 2)) * (np.arange(n) % 2)[:, None]
        self.tilt = self.rng.uniform(-0.3, 0.3, n)
        self.k, self.parked = 0, 60

    def sample(self) -> Sample:
        rng, n = self.rng, self.n
        self.t = self.t + rng.choice([0.001, 0.01, 0.05], n)
        change = rng.random(n) < 0.05
        self.grasp = np.where(change, rng.choice(GRASPS, n), self.grasp)
        if self.pad and self.k < self.parked:  # (the drive: in its park, then taken)
            self.k += 1
            self.grasp[:] = 0 if self.k < self.parked else PSM1_JAWS
            tip = self.p + 0.01
            return Sample.of(self.t.copy(), tip, objects=self.p[:, None].copy(),
                             grasp=self.grasp[:, None].copy(),
                             T_task_object=np.tile(self.task.T_world_start, (n, 1, 1)))  # fmt: skip
        moving = rng.random(n) < 0.5
        self.p = self.p + moving[:, None] * rng.normal(scale=0.0005, size=(n, 3))
        jump = rng.random(n) < 0.01
        self.p[jump, 2] += rng.choice([0.02, -0.02], jump.sum())
        home = rng.random(n) < 0.005
        self.p[home] = self.task.T_world_start[:3, 3]
        tip = self.p + rng.normal(scale=0.01, size=(n, 3))
        T_task_object = None
        if self.pad:
            self.theta += self.turn
            back = (self.theta > math.radians(175)) | (self.theta < math.radians(-5))
            self.turn = np.where(back | (rng.random(n) < 0.01), -self.turn, self.turn)
            self.off = self.off + rng.normal(scale=0.00003, size=(n, 2))
            T_pad_world = self.task.T_pad_world
            T_task_object = np.stack([
                np.linalg.inv(T_pad_world) @ _needle_in_pad(
                    self.theta[i], *self.off[i], self.tilt[i], self.task.needle.radius)
                for i in range(n)])  # fmt: skip
            self.p = T_task_object[:, :3, 3].copy()
        return Sample.of(self.t.copy(), tip, objects=self.p[:, None].copy(),
                         grasp=self.grasp[:, None].copy(), T_task_object=T_task_object)  # fmt: skip


def _same(a, b, where: str) -> None:
    if isinstance(a, tuple):
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{k}]")
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (where, a.dtype, b.dtype, a.shape, b.shape)
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), (where, a, b)


def _run(task, pad: bool, seed: int, steps: int = 1500, n: int = 8) -> dict:
    """Both steps on the same samples from the same state; the observations' totals."""
    trials = Trials(task, n, seed, pad)
    compiled = oracle = task.initial_state(n)
    totals: dict = {}
    phases = set()
    for k in range(steps):
        sample = trials.sample()
        compiled, obs = task.step(compiled, sample)
        oracle, expected = task.step_arrays(oracle, sample)
        _same(tuple(compiled), tuple(oracle), f"state at sample {k}")
        assert list(obs) == list(expected)
        for name in obs:
            _same(obs[name], expected[name], f"{name} at sample {k}")
            totals[name] = totals.get(name, 0) + np.nansum(np.abs(obs[name]) > 0)
        phases.update(int(p) for p in compiled.phase)
    totals["phases"] = phases
    return totals


@pytest.mark.parametrize("seed", [1, 2])
def test_the_compiled_pickup_step_is_the_numpy_step_bit_for_bit(seed):
    task = dataclasses.replace(load_task("needle_pickup"), hold_time=0.05, rest_time=0.05,
                               time_limit=3.0, lift_height=0.005)  # fmt: skip
    totals = _run(task, pad=False, seed=seed)
    # (the samples made every event and phase happen)
    assert totals["phases"] == {0, 1, 2, 3, 4}
    for name in ("handoffs", "dropped", "missed", "held"):
        assert totals[name] > 0, (name, totals)


@pytest.mark.parametrize("seed", [1, 2])
def test_the_compiled_drive_step_is_the_numpy_step_bit_for_bit(seed):
    task = dataclasses.replace(load_task("needle_drive"), rest_time=0.05, time_limit=8.0)
    totals = _run(task, pad=True, seed=seed)
    assert totals["phases"] == {0, 1, 2, 3, 4}
    for name in ("passes", "entry_error", "exit_error", "trauma", "missed", "handoffs"):
        assert totals[name] > 0, (name, totals)
