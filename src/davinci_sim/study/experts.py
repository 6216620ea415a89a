"""Expert-parameter scripted operators of the skill exercises: the attempts behind their pass marks.

The study's synthetic trainees follow paths through the MTM (:mod:`davinci_sim.operators`);
the exercises need grasping, orienting and camera moves they do not make. The expert
reference of an exercise (:mod:`davinci_sim.study.reference`) is therefore made by scripted
operators at the simulated console, one per kind, each repetition an attempt recorded by the
task's own session (:class:`~davinci_sim.tasks.session.TaskSession`: the same samples,
state machine and metrics as a person's attempt), with the arms driven through their API
(``servo_cp`` streamed at 1 kHz, jaws by ``servo_jp``, the ECM by ``move_cp``) and the
task's teleoperation clutched:

* ``needle_targeting``: reach each target pointing along its direction (undershooting, so
  as not to pass through it: leaving a target unhit is a miss), hold for the dwell;
* ``ring_walk``: carry the ring along the wire from its start to its end;
* ``camera_targeting``: bring the endoscope, on the line from its RCM through each target, to
  the task's depth (ECM ``move_cp``), hold for the dwell;
* ``needle_pickup``: PSM2 lifts the needle out of its park a third of the way from its
  swage, PSM1 grasps it near its point (both with the jaws closing across the needle's
  plane), PSM2 lets go and moves away, PSM1 holds it;
* ``needle_drive`` (and the running suture): PSM2 lifts the needle and tilts its plane,
  PSM1 takes it in a needle driver's grip and turns it about its centre in at the entry
  mark and out at the exit; between pairs PSM2 takes the point and pulls the needle
  through, and hands it back. The shipped reference (3 experts x 2 attempts of seed 9001):
  all 6 attempts finished, entry and exit 0.04-0.06 mm off their marks, 0.14 mm of trauma.
  PSM1 holds the wire 8.5 mm into its 10 mm jaws (:data:`DRIVE_GRIP_DEPTH`): at 6 mm the
  jaw past the wire, 45° down along the needle's normal, pressed on the skin for the last
  ~60° of the turn and pushed PSM1's wrist off its setpoint (entry 0.37 mm, trauma 0.44 mm
  then; in the running suture a wrist tracking fault). The start of the drive is 3 mm
  above the skin (:data:`DRIVE_START`): 1.1 mm above, three of six attempts grazed the
  skin 2-3 mm from the entry mark on the way down. **The running suture** (four pairs):
  PSM2 takes the point from above (its jaws down the needle's normal: along PSM2's own
  direction they came from under the skin), and before each later pair turns the needle
  back in the air over it to the pose of the drive's exit (:data:`HAND_BACK`), where PSM1
  takes it; PSM2 lets go, moves out of the way (:data:`RETREAT`), and PSM1 turns the
  needle to the drive's start. Grips that close wider than :data:`JAW_HELD` are taken
  again. The shipped reference rests on **4 of its 6 attempts** (3 experts x 2 of seed
  9001): 130 ± 6 s, 1.30 m of tip path, entries 1.1 mm and exits 0.25 mm off their marks,
  0.33 mm of trauma, no drop; one of the other two ends in a tracking fault of PSM1's
  insertion (reaching for its driver grip at the second hand-back, PSM1 pressed a jaw into
  the skin, ~100 N). (Before the park's foam, ``needle_scene.FOAM_SOLIMP``, the two ended at the
  first hand-back as PSM2 let go: PSM1's new grip did not hold and the needle fell, or the
  wire stayed on one of PSM2's jaws and, as PSM2 backed away, dragged PSM1's wrist into a
  tracking fault.)
  The arms also press on the pad and touch each other on the way (~20 N of peak tissue
  force, 360-410 collision onsets an attempt, not traced to their moments), so the
  reference leaves those metrics out (:data:`NOT_MEASURED_OF_TASK`);
* ``peg_transfer`` (and its ICRA variant): PSM2 lifts each ring off its start peg, carries it
  to the middle (over the wall), hands it to PSM1, which threads it on a target peg. **Not
  yet reliable**: the open jaw inside a ring's hole reached its peg and the arm stalled
  against it (the third ring of the board, measured: the tip 10 mm off its setpoint);
  PSM2 now opens less around a ring on its peg (:data:`JAW_OPEN_AT_PEG`). Of the six
  attempts a reference takes (3 experts x 2 of seed 9001, checked on 2026-11-29) two
  transferred all three rings; four ended in a tracking fault. In both of expert 3's,
  PSM2's open jaws struck the board on the straight glide to their grasp of the third
  ring: a ring on the board is now reached from above (:data:`ON_BOARD`), the jaws
  opened there. Since then, four of the six finish, all four with three clean hand-offs
  since PSM2 backs out along its jaws before it moves away from the hand-off (its open
  jaws, dragged sideways round the ring's tube, pulled the ring out of PSM1's grasp: two
  of the four had a drop before). Two do not: in expert 2's first a ring slips out of
  PSM1's jaws as it is lowered over its target peg and falls off the board, PSM1 reaches
  for it out of range and faults; in expert 3's first a ring falls from PSM2 on the way to
  the hand-off, PSM1 picks it off the board and faults dragging a jaw on the board as it
  carries it across. The shipped peg reference is the four finished attempts' metrics
  (``tasks/data/reference/peg_transfer.json``: 4 of 6 finished).

**The expert's variability** (:class:`Motor`): each attempt draws from the expert's
parameters (:func:`~davinci_sim.operators.params.sample_experts`; repetition j scales them
by the power law's practice factor f = 1 + E·j^(−α), as the trainees' are: speed / f,
noise k·f):

* a reach of amplitude A at mean speed v ends off its aim by a normal error of SD
  k·√(A·v·2τ·10/7) per axis — the open-loop endpoint SD of signal-dependent noise for a
  minimum-jerk reach of duration A/v (:mod:`davinci_sim.operators.noise`, τ its 40 ms
  muscle filter); the operator then looks (the visuomotor delay) and corrects with a new,
  shorter reach, until it is within the task's tolerance (at most :data:`MAX_CORRECTIONS`);
  an orientation error is drawn alike from the rotation's angle at :data:`ANGULAR_SPEED`;
* the reaches' mean speed is the expert's practised tool speed times
  :data:`REACH_SPEED_FACTOR`; a wire is followed at the practised speed itself, the ring
  off the wire by a lateral wander (an Ornstein-Uhlenbeck process with the visuomotor
  delay as correlation time and the endpoint SD of a reach of one delay's travel as SD);
* every streamed setpoint carries the expert's physiological tremor, scaled by the task's
  motion scale (the hand's tremor reaches the tool scaled), one sinusoid per axis at the
  expert's tremor frequency with random phases; each sub-movement starts after the
  expert's reaction time.

:data:`REACH_SPEED_FACTOR` and :data:`ANGULAR_SPEED` are **assumptions** (no published
expert value for these exercises; they put an expert's reaches at ~5 cm/s, of the order of
the tool speeds reported for robotic training tasks). The masters do not move (the arms
are scripted), so the master workspace is not measured (:func:`not_measured`; nor the
instrument's economy and out-of-view distance in camera targeting, where the scripted
expert leaves the instrument alone): no reference value, so no default pass mark for them
(their score still uses the task's ``expert``/``fail`` scale).

Size: the motion model, the six scripts and the attempt driver are one unit (~900 lines):
the scripts share the motion model's primitives and nothing else uses them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from davinci_sim.geometry.so3 import rotation_from_vector, rotation_vector
from davinci_sim.operators.noise import MUSCLE_TIME_CONSTANT
from davinci_sim.operators.params import SubjectParams
from davinci_sim.tasks.needle_drive import (
    DRIVE_GRIP,
    DRIVE_GRIP_DEPTH,
    DRIVE_OUT,
    DRIVE_START,
    DRIVE_TILT,
)

#: Mean speed of a reach over the practised path-following speed (assumption, see above).
REACH_SPEED_FACTOR = 3.0
#: Mean angular speed of a reorientation, rad/s (assumption).
ANGULAR_SPEED = 1.0
#: Corrective reaches after the first, at most.
MAX_CORRECTIONS = 4
#: The kinds these operators do.
EXERCISES = (
    "needle_targeting",
    "ring_walk",
    "camera_targeting",
    "peg_transfer",
    "needle_pickup",
    "needle_drive",
)
#: The kinds whose attempts use both PSMs (the console's system, both homed).
TWO_HANDED = ("peg_transfer", "needle_pickup", "needle_drive")
#: Metrics a scripted expert does not exercise, and why (left out of its reference).
NOT_MEASURED = {
    "master_workspace": "the scripted experts drive the arms (teleoperation clutched): the "
    "masters do not move",
}
#: ... and those of one kind only.
NOT_MEASURED_OF_KIND = {
    "camera_targeting": {
        "path_length": "the scripted camera expert leaves the instrument alone (its "
        "teleoperation clutched): it does not move",
        "out_of_view": "the instrument does not move (see path_length)",
    },
}
#: ... and those of one task.
NOT_MEASURED_OF_TASK = {
    "running_suture": {
        name: "the scripted arms press on the pad and touch each other on the way (~20 N "
        "of peak tissue force, 360-410 collision onsets an attempt, not traced to their "
        "moments): the script's, not an expert's"
        for name in ("tissue_force", "instrument_collisions", "excessive_force")
    },
}


def not_measured(kind: str, name: str | None = None) -> dict[str, str]:
    """The metrics the scripted expert of a ``kind`` (the task ``name``) does not exercise
    as an expert would, and why."""
    return {**NOT_MEASURED, **NOT_MEASURED_OF_KIND.get(kind, {}),
            **NOT_MEASURED_OF_TASK.get(name or "", {})}  # fmt: skip


_SPREAD = 2.0 * MUSCLE_TIME_CONSTANT * 10.0 / 7.0


@dataclass
class Motor:
    """One attempt's motion style of one expert (see the module docstring)."""

    speed: float
    """Path-following tool speed, m/s."""
    noise: float
    """Signal-dependent noise coefficient k."""
    tremor: float
    """Tool tremor, 3-D rms, m."""
    tremor_hz: float
    delay: float
    """Visuomotor delay, s."""
    reaction: float
    """Reaction time before a sub-movement, s."""
    rng: np.random.Generator
    phase: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def of(cls, params: SubjectParams, index: int, repetition: int, scale: float,
           rng: np.random.Generator) -> Motor:  # fmt: skip
        """Expert ``index`` of ``params`` at repetition ``repetition`` (≥ 1), the task's
        motion ``scale``, drawing from ``rng``."""
        f = float(params.practice_factor(repetition)[index])
        return cls(
            speed=float(params.speed[index]) / f,
            noise=float(params.noise[index]) * f,
            tremor=float(params.tremor_amplitude[index]) * scale,
            tremor_hz=float(params.tremor_frequency[index]),
            delay=float(params.delay[index]),
            reaction=float(params.reaction_time[index]),
            rng=rng,
            phase=rng.uniform(0.0, 2.0 * math.pi, 3),
        )

    @property
    def reach_speed(self) -> float:
        return REACH_SPEED_FACTOR * self.speed

    def endpoint_sd(self, amplitude: float, speed: float) -> float:
        """SD per axis of the end of an open-loop reach of ``amplitude`` at mean ``speed``."""
        return self.noise * math.sqrt(max(amplitude, 0.0) * speed * _SPREAD)

    def aim(self, start, goal) -> np.ndarray:
        """Where a reach from ``start`` towards ``goal`` (3,) ends, m."""
        a, g = np.asarray(start, float), np.asarray(goal, float)
        sd = self.endpoint_sd(float(np.linalg.norm(g - a)), self.reach_speed)
        return g + self.rng.normal(0.0, sd, 3)

    def aim_rotation(self, R_start, R_goal) -> np.ndarray:
        """Where a reorientation from ``R_start`` towards ``R_goal`` ends."""
        angle = float(np.linalg.norm(rotation_vector(R_start.T @ R_goal)))
        sd = self.endpoint_sd(angle, ANGULAR_SPEED)
        return R_goal @ rotation_from_vector(self.rng.normal(0.0, sd, 3))

    def duration(self, distance: float, angle: float = 0.0, speed: float | None = None) -> float:
        """Duration of a reach, s (at least 0.15 s)."""
        v = self.reach_speed if speed is None else speed
        return max(0.15, distance / v, angle / ANGULAR_SPEED)

    def tremor_at(self, t: float) -> np.ndarray:
        """The tool's tremor displacement at time ``t`` s, (3,) m."""
        amp = self.tremor * math.sqrt(2.0 / 3.0)  # per axis: rms tremor/√3
        return amp * np.sin(2.0 * math.pi * self.tremor_hz * t + self.phase)


def min_jerk(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


def slerp(R0: np.ndarray, R1: np.ndarray, s: float) -> np.ndarray:
    return R0 @ rotation_from_vector(s * rotation_vector(R0.T @ R1))


class Streamer:
    """Streams ``servo_cp`` setpoints of PSMs, given in the task's frame, tick by tick.

    ``sees_tips``: the operator corrects by what it sees of each tool, as on a robot whose
    kinematics are off (:attr:`SceneConfig.joint_errors
    <davinci_sim.model.config.SceneConfig.joint_errors>`): after each reach it looks where
    the tip is (its MuJoCo site), takes the offset from where it sent it as the arm's bias
    and sends later setpoints that much the other way (:attr:`bias`); a reach ends when the
    tip it sees is within the tolerance. Off: the tip is taken to be where it was sent (the
    exact robot; the shipped references)."""

    def __init__(self, sim, motor: Motor, T_camera_task: np.ndarray, arms,
                 sees_tips: bool = False) -> None:  # fmt: skip
        self.sim, self.motor, self.T = sim, motor, np.asarray(T_camera_task, float)
        self.goal: dict[str, np.ndarray] = {}
        for n in arms:  # the current setpoint, task frame
            self.goal[n] = np.linalg.inv(self.T) @ sim.arms[n].setpoint_cp().T
        self.sees_tips = bool(sees_tips)
        self.bias = {n: np.zeros(3) for n in arms}
        """Per arm: where its tip is seen minus where it was sent, task frame, m."""

    #: Whether a reach looks at the tip only after the visuomotor delay (the tool still
    #: moving behind a hand on the MTM) rather than as soon as its setpoint arrives.
    LOOKS_AFTER_DELAY = False

    def set_jaw(self, arm: str, angle: float) -> None:
        """``arm``'s jaw to ``angle``, rad (``servo_jp``)."""
        self.sim.arms[arm].jaw.servo_jp(angle)

    def _send(self) -> None:
        t = self.sim.time
        for n, G in self.goal.items():
            H = G.copy()
            H[:3, 3] += self.motor.tremor_at(t)
            if self.sees_tips:
                H[:3, 3] -= self.bias[n]
            self.sim.arms[n].servo_cp(self.T @ H)

    def seen_tip(self, arm: str) -> np.ndarray:
        """Where ``arm``'s tool tip is (its MuJoCo site, as the endoscope shows it), task
        frame, m."""
        sim = self.sim
        p_world = sim.data.site_xpos[sim.model.site(f"{arm}/tip").id]
        T_task_world = np.linalg.inv(self.T) @ np.linalg.inv(sim.T_cart_camera())
        return T_task_world[:3, :3] @ p_world + T_task_world[:3, 3]

    def wait(self, seconds: float, until=None) -> bool:
        """Hold the setpoints (with tremor) for ``seconds`` or until ``until()``."""
        end = self.sim.time + seconds
        while self.sim.time < end:
            if until is not None and until():
                return True
            self._send()
            self.sim.tick()
        return until is not None and until()

    def glide(self, goals: dict, duration: float, until=None) -> bool:
        """Minimum-jerk moves of the arms in ``goals`` (name → 4x4 or (3,) position, task
        frame) over ``duration`` s; stops early (True) when ``until()``."""
        start = {n: self.goal[n].copy() for n in goals}
        ends = {}
        for n, g in goals.items():
            g = np.asarray(g, float)
            if g.shape == (3,):
                e = start[n].copy()
                e[:3, 3] = g
                g = e
            ends[n] = g
        t0 = self.sim.time
        while True:
            s = min_jerk((self.sim.time - t0 + self.sim.dt) / duration)
            for n in goals:
                G = ends[n].copy()
                G[:3, 3] = start[n][:3, 3] + s * (ends[n][:3, 3] - start[n][:3, 3])
                G[:3, :3] = slerp(start[n][:3, :3], ends[n][:3, :3], s)
                self.goal[n] = G
            self._send()
            self.sim.tick()
            if until is not None and until():
                return True
            if s >= 1.0:
                return False

    def reach(self, arm: str, goal, tolerance: float, R_goal=None, until=None,
              undershoot: bool = False) -> bool:  # fmt: skip
        """A reach of ``arm`` towards ``goal`` (3,) (and orientation ``R_goal``), corrected
        until its aim is within ``tolerance`` m (see :class:`Motor`). ``undershoot``: each
        sub-movement aims short of the goal by twice its endpoint SD (at most half the way),
        as primary movements to a target do (Elliott, Helsen & Chua 2001, Psychol. Bull.
        127:342): the tip does not pass through a target it must not leave."""
        m = self.motor
        goal = np.asarray(goal, float)
        for _ in range(1 + MAX_CORRECTIONS):
            if self.wait(m.reaction, until):
                return True
            G0 = self.goal[arm]
            aim_at = goal
            if undershoot:
                delta = goal - G0[:3, 3]
                dist = float(np.linalg.norm(delta))
                if dist > tolerance:
                    short = min(2.0 * m.endpoint_sd(dist, m.reach_speed), 0.5 * dist)
                    aim_at = goal - short * delta / dist
            p = m.aim(G0[:3, 3], aim_at)
            H = G0.copy()
            H[:3, 3] = p
            angle = 0.0
            if R_goal is not None:
                H[:3, :3] = m.aim_rotation(G0[:3, :3], R_goal)
                angle = float(np.linalg.norm(rotation_vector(G0[:3, :3].T @ R_goal)))
            if self.glide({arm: H}, m.duration(float(np.linalg.norm(p - G0[:3, 3])), angle),
                          until):  # fmt: skip
                return True
            if self.LOOKS_AFTER_DELAY and self.wait(m.delay, until):
                return True
            if self.sees_tips:  # (the tip as seen: the next setpoints corrected by its offset)
                seen = self.seen_tip(arm)
                self.bias[arm] = self.bias[arm] + (seen - p)
                if np.linalg.norm(seen - goal) <= tolerance:
                    return False
            elif np.linalg.norm(p - goal) <= tolerance:
                return False
            if not self.LOOKS_AFTER_DELAY and self.wait(m.delay, until):  # looks, corrects
                return True
        return False


# ---------------------------------------------------------------- the exercises
def pointing(R: np.ndarray, direction) -> np.ndarray:
    """``R`` turned the least so that its z axis points along ``direction``."""
    from davinci_sim.tasks.check import _pointing

    return _pointing(R, direction)


def do_needle(stream: Streamer, session, task, done) -> None:
    arm = task.teleop.psm
    tol = 0.6 * task.target_radius  # (inside, with a margin for the tremor)
    for p, d in zip(task.targets, task.directions, strict=True):
        R_goal = pointing(stream.goal[arm][:3, :3], d)
        if stream.reach(arm, p, tol, R_goal, until=done, undershoot=True):
            return
        if stream.wait(task.dwell + 0.05, until=done):
            return


def do_ring_walk(stream: Streamer, session, task, done) -> None:
    arm, m = task.teleop.psm, stream.motor
    path = task.path
    stream.wait(m.reaction)
    sd = m.endpoint_sd(m.speed * m.delay, m.speed)
    offset = np.zeros(3)
    a = math.exp(-stream.sim.dt / m.delay)
    s = 0.0
    while not done() and s < path.length + 0.01:
        offset = a * offset + math.sqrt(1 - a * a) * m.rng.normal(0.0, sd, 3)
        G = stream.goal[arm].copy()
        G[:3, 3] = path.point_at(min(s, path.length)) + offset
        stream.goal[arm] = G
        stream._send()
        stream.sim.tick()
        s += m.speed * stream.sim.dt


def do_camera(sim, motor: Motor, session, task, done) -> None:
    ecm = sim.arms["ECM"]
    T_task_camera0 = task.T_task_camera(sim.T_cart_camera())
    T_world_task = sim.T_cart_camera() @ np.linalg.inv(T_task_camera0)
    rcm = ecm.base_frame()[0][:3, 3]
    for i, p_task in enumerate(task.targets):
        p = (T_world_task @ np.append(p_task, 1.0))[:3]
        axis = (p - rcm) / np.linalg.norm(p - rcm)
        view = p - task.depth * axis
        for _ in range(1 + MAX_CORRECTIONS):
            sim.run_for(motor.reaction)
            here = ecm.measured_cp().T[:3, 3]
            goal = ecm.measured_cp().T.copy()
            goal[:3, 3] = motor.aim(here, view)
            if not ecm.move_cp(goal):
                break
            sim.run_until(lambda: not ecm.is_busy(), 10.0)
            if _acquired(session, i) or done():
                break
            sim.run_for(task.dwell + 0.05)
            if _acquired(session, i) or done():
                break
            sim.run_for(motor.delay)
        if done():
            return
        sim.run_until(lambda i=i: _acquired(session, i) or done(), task.dwell + 0.1)


def _acquired(session, i: int) -> bool:
    return int(session.monitor.state.target[0]) > i


#: Jaw angles of the peg script, rad: open (46°, in the dVRK's −40°…80° range) and the
#: dVRK's close (−20°: the jaw effort saturates on the ring).
JAW_OPEN, JAW_CLOSED = 0.8, -0.35
#: The jaw opening for a ring around its peg, rad (34°): the jaw inside the ring's hole
#: stays clear of the peg (at 46° its tip and 2.2 mm thickness reached 6.3 mm into the
#: 6 mm between the ring's wall and the peg, and the arm stalled against the peg), and the
#: jaws still clear the 3 mm tube by 0.9 mm a side 8 mm along them.
JAW_OPEN_AT_PEG = 0.6
#: A ring whose centre is less than this above the board lies on it (on its peg or
#: fallen); a grasp of it starts this far above its approach, m.
ON_BOARD = 0.012


def do_peg(stream: Streamer, session, task, done) -> None:
    """Every ring: PSM2 picks it off its start peg, PSM1 takes it over the board's middle
    (a hand-off, over the wall if any), PSM1 drops it on its target peg."""
    sim = stream.sim
    m, d = sim.model, sim.data
    bodies = [m.body(f"task/ring{i + 1}").id for i in range(task.n_rings)]

    def ring(i):
        return d.xpos[bodies[i]].copy(), d.xmat[bodies[i]].reshape(3, 3).copy()

    def tip(n):
        return stream.goal[n][:3, 3].copy()

    def pivot(n, i, far_from=None, depth=0.008):
        # On the ring's circle where the jaws close radially, the tube `depth` along them.
        c, Rr = ring(i)
        R = stream.goal[n][:3, :3]
        a, y, normal = R[:, 2], R[:, 1], Rr[:, 2]
        radial = y - normal * np.dot(y, normal)
        radial /= np.linalg.norm(radial)
        pts = [c + s * task.ring_radius * radial - depth * a for s in (1.0, -1.0)]
        return pts[0] if far_from is None else max(pts, key=lambda p: np.linalg.norm(p - far_from))

    def jaw(n, angle):
        stream.set_jaw(n, angle)
        return stream.wait(0.1, until=done)

    probe = task.probe(m)

    def held(n, i) -> bool:  # both of n's jaws touch ring i (the expert looks)
        a = task.instruments.index(n)
        return (int(probe.measure(d)[1][i]) >> (2 * a)) & 3 == 3

    def grasp(n, i, far_from=None, opening=JAW_OPEN) -> bool | None:
        """Reach ring i's wall with n's open jaws and close them, again (from the
        ring's pose now) while the jaws do not both hold it: True if held, None if the
        attempt ended."""
        for _ in range(3):
            p = pivot(n, i, far_from)
            a = stream.goal[n][:3, 2]
            # A ring on the board is reached from above, the jaws opened there: on a
            # straight glide from afar the open jaws struck the board.
            approach = p - 0.006 * a
            above = approach + [0.0, 0.0, ON_BOARD]
            on_board = ring(i)[0][2] < task.board_top + ON_BOARD
            if on_board and np.linalg.norm(tip(n)[:2] - above[:2]) > 0.005:
                if stream.reach(n, above, 0.003, until=done):
                    return None
            if jaw(n, opening) or stream.reach(n, approach, 0.002, until=done):
                return None
            if stream.reach(n, p, 0.0007, until=done) or jaw(n, JAW_CLOSED):
                return None
            if held(n, i):
                return True
            if stream.reach(n, tip(n) - 0.006 * a, 0.002, until=done):
                return None
        return False

    cx, cy = task.board_center
    lift = task.board_top + max(task.peg_height, task.wall_height if task.wall else 0.0)
    hand_off = np.array([cx + 0.007, cy, lift + 0.01])
    for i, peg in enumerate(task.target_pegs[: task.n_rings]):
        if jaw("PSM1", JAW_OPEN):
            return
        if stream.reach("PSM1", hand_off + [-0.01, 0, 0.02], 0.003, until=done):
            return
        if not grasp("PSM2", i, opening=JAW_OPEN_AT_PEG):
            return
        steps = [
            lambda: stream.reach("PSM2", tip("PSM2") + [0, 0, 0.02], 0.003, until=done),
            lambda i=i: stream.reach(
                "PSM2", tip("PSM2") + hand_off - ring(i)[0], 0.002, until=done
            ),  # fmt: skip
            lambda i=i: not grasp("PSM1", i, far_from=tip("PSM2")),
            lambda: stream.wait(0.3, until=done),
            lambda: jaw("PSM2", JAW_OPEN),
            # (back out along its own jaws first: open jaws dragged sideways around the
            # ring's tube pulled it out of PSM1's grasp)
            lambda: stream.reach(
                "PSM2", tip("PSM2") - 0.012 * stream.goal["PSM2"][:3, 2], 0.003, until=done
            ),  # fmt: skip
            lambda: stream.reach("PSM2", tip("PSM2") + [0.015, 0, 0.01], 0.003, until=done),
        ]
        for step in steps:
            if step():
                return
        if not held("PSM1", i):  # it fell at the hand-off: PSM1 picks it up where it lies
            if stream.wait(0.5, until=done) or not grasp("PSM1", i):
                return
            if stream.reach("PSM1", tip("PSM1") + [0, 0, 0.02], 0.003, until=done):
                return
        x, y = task.pegs[peg]
        top = task.board_top + task.peg_height
        # Across at the hand-off's height (clear of the wall), down over the peg, down until
        # the peg is 4 mm into the ring's hole, then let go.
        for z in (hand_off[2] + 0.005, top + 0.006, top - 0.004):
            goal = tip("PSM1") + np.array([x, y, z]) - ring(i)[0]
            if stream.reach("PSM1", goal, 0.0015, until=done):
                return
        if jaw("PSM1", JAW_OPEN) or stream.wait(0.3, until=done):
            return
        if stream.reach("PSM1", tip("PSM1") + [0, 0, 0.02], 0.003, until=done):
            return
    stream.wait(0.5, until=done)


def do_needle_pickup(stream: Streamer, session, task, done) -> None:
    """The first instrument (PSM2) picks the needle out of its park a third of the way
    from the swage and lifts it 2 cm, the second (PSM1) grasps it near its point, the first
    lets go and moves away; the second holds it (the session finishes the attempt after the
    task's hold time). The grasps are half the needle apart: closer, the two instruments'
    jaws touched at the hand-off (counted as collisions). Each grasp looks at the needle
    again from 12 mm back before going in (the other hand may have moved it); a grasp that
    does not hold (a jaw off the wire, or the jaws closed wider than :data:`JAW_HELD`: the
    wire at their tips) is tried again from the needle's pose then."""
    from davinci_sim.tasks.needle_scene import grasp_pose

    sim = stream.sim
    probe = task.probe(sim.model)
    giver, taker = task.instruments

    def jaw(n, angle):
        stream.set_jaw(n, angle)
        return stream.wait(0.1, until=done)

    def grasp(n, s, depth) -> bool | None:
        """n's open jaws to the needle at fraction s, the wire ``depth`` m into them,
        closed: True if held, None if the attempt ended."""
        for _ in range(3):
            T = probe.frame(sim.data)
            R, pivot = grasp_pose(T, task.needle, stream.goal[n][:3, :3], s, depth)
            if jaw(n, JAW_OPEN):
                return None
            if stream.reach(n, pivot - 0.012 * R[:, 2], 0.002, R_goal=R, until=done):
                return None
            # (a look again before going in: the needle may have moved since)
            pivot = grasp_pose(probe.frame(sim.data), task.needle, R, s, depth)[1]
            if stream.reach(n, pivot, 0.0007, until=done) or jaw(n, JAW_CLOSED):
                return None
            if gripped(sim, probe, task.instruments, n):
                return True
            if stream.reach(n, stream.goal[n][:3, 3] - 0.012 * R[:, 2], 0.002, until=done):
                return None
        return False

    # (8 mm into the jaws a third of the way along: their tips clear the park's foam)
    if not grasp(giver, 0.35, 0.008):
        return
    if stream.reach(giver, stream.goal[giver][:3, 3] + [0, 0, 0.02], 0.003, until=done):
        return
    if not grasp(taker, 0.85, 0.006):
        return
    if stream.wait(0.2, until=done) or jaw(giver, JAW_OPEN):
        return
    away = stream.goal[giver][:3, 3] - 0.012 * stream.goal[giver][:3, 2] + [0, 0, 0.01]
    if stream.reach(giver, away, 0.003, until=done):
        return
    stream.wait(task.hold_time + 1.0, until=done)


#: The drive (the needle's plane tilted 45° towards the instruments, turned about its
#: centre from DRIVE_START to DRIVE_OUT, held near its swage: the task's guidance follows
#: the same, :data:`~davinci_sim.tasks.needle_drive.DRIVE_TILT`). DRIVE_START puts the
#: point 32° of the turn before the entry mark (3 mm above the skin: at 10° before, 1.1 mm
#: above, an expert's 0.5 mm aim and a few degrees of grip carried the point into the
#: skin 3 mm from the mark on the way down), DRIVE_OUT 15° past level after the exit (the
#: needle driver's grasp near the swage still clear of the skin); at DRIVE_THROUGH (rad)
#: the whole needle is out.
DRIVE_THROUGH = math.radians(370.0)
#: Where PSM2 hands the needle back to PSM1 between pairs (rad, a drive pose's angle, in
#: the air over the next pair): as at the drive's exit, so that each arm's grip is where it
#: was when PSM2 took the point (the needle as it comes through has the point on PSM1's side
#: and the swage on PSM2's: the arms crossed, their wrists touching, and PSM1's roll would
#: have to turn past its limit to take it there).
HAND_BACK = DRIVE_OUT
#: A grip of the needle's 1 mm wire 3 mm or more down the jaws closes them to less than this
#: (rad; measured: 0.07-0.23 rad for the scripts' grips): wider, the wire is at their tips or
#: something else is between them, and the grip is taken again.
JAW_HELD = 0.35
#: The jaws opened wide (rad; the dVRK's jaw opens to 80°, dvrk.md §1.2): PSM2 letting go of
#: the point that PSM1's grip also holds.
JAW_WIDE = math.radians(75.0)
#: How far PSM2 moves out of the way after a hand-back (m, away from PSM1's tip and up):
#: 12 mm back along its jaws leaves it in reach of PSM1's turn of the needle in the air
#: (the needle sweeps a circle 16.6 mm across about its centre).
RETREAT = 0.02
#: Straight down (world): the point that came out is taken from above.
DOWN = np.array([0.0, 0.0, -1.0])


def touching(sim, probe, instruments, n) -> bool:
    """Whether both of instrument ``n``'s jaws touch the needle now (``probe``: the task's
    :class:`~davinci_sim.tasks.needle_scene.NeedleProbe`; ``instruments``: its order of the
    jaw bits): what the expert sees."""
    return (probe.grasp(sim.data) >> (2 * instruments.index(n))) & 3 == 3


def gripped(sim, probe, instruments, n) -> bool:
    """Whether ``n`` holds the needle in a grip that holds: both jaws on it, closed to less
    than :data:`JAW_HELD` (wider, the wire is at their tips: a grip that lets go)."""
    return touching(sim, probe, instruments, n) and (
        sim.arms[n].jaw.measured_js().position[0] < JAW_HELD
    )


def do_needle_drive(stream: Streamer, session, task, done) -> None:
    """PSM2 lifts the needle out of its park and tilts its plane (:data:`DRIVE_TILT`);
    PSM1 takes it in a needle driver's grip near the swage (the jaws across the needle,
    :func:`~davinci_sim.tasks.needle_scene.driver_grasp`) and PSM2 lets go. For each pair
    of marks: PSM1 brings the point above the entry mark and turns the needle about its
    centre through the tissue until the point is well out past the exit
    (:func:`~davinci_sim.tasks.suture_pad.drive_pose`); PSM2 takes the point deep in its
    jaws, PSM1 lets go, and PSM2 pulls the needle through along its curve; before the next
    pair PSM2 lifts it and hands it back to PSM1's driver grip. The tissue does not hold
    the needle, so neither hand lets go of it while it is in the tissue."""
    from davinci_sim.tasks.needle_scene import driver_grasp, grasp_pose
    from davinci_sim.tasks.suture_pad import drive_pose

    sim = stream.sim
    m, d = sim.model, sim.data
    probe = task.probe(m)
    second, first = task.instruments  # (PSM2 lifts it, PSM1 drives it)
    sites = {n: m.site(f"{n}/tip").id for n in task.instruments}

    def frame() -> np.ndarray:
        return probe.frame(d)

    def tip(n) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = d.site_xmat[sites[n]].reshape(3, 3), d.site_xpos[sites[n]]
        return T

    def jaw(n, angle) -> bool:
        stream.set_jaw(n, angle)
        return stream.wait(0.1, until=done)

    def take(n, grip) -> bool | None:
        """n's open jaws to ``grip`` ((R, pivot) from the needle now), closed: True if
        held, None if the attempt ended; a grasp that does not hold is tried again (from
        12 mm back, the grip from the needle's pose then), three times at most."""
        for _ in range(3):
            R, pivot = grip()
            if jaw(n, JAW_OPEN) or stream.reach(n, pivot - 0.012 * R[:, 2], 0.002, R_goal=R,
                                                until=done):  # fmt: skip
                return None
            if stream.reach(n, pivot, 0.0007, until=done) or jaw(n, JAW_CLOSED):
                return None
            if gripped(sim, probe, task.instruments, n):
                return True
            if jaw(n, JAW_OPEN) or stream.reach(n, pivot - 0.012 * R[:, 2], 0.002, until=done):
                return None
        return False

    def let_go(n, opening=JAW_OPEN) -> bool:
        """n's jaws opened to ``opening`` (rad) and moved 12 mm back along themselves."""
        back = stream.goal[n][:3, 3] - 0.012 * stream.goal[n][:3, 2]
        return jaw(n, opening) or stream.reach(n, back, 0.003, until=done)

    def clear_of(n, other) -> np.ndarray:
        """Where n's tip goes out of the way of ``other``'s turn of the needle in the air
        (m): :data:`RETREAT` away from ``other``'s tip across the table and up."""
        away = tip(n)[:3, 3] - tip(other)[:3, 3]
        away[2] = 0.0
        away /= max(float(np.linalg.norm(away)), 1e-9)
        return stream.goal[n][:3, 3] + RETREAT * (away + [0.0, 0.0, 1.0]) / math.sqrt(2.0)

    def carry(n, T_goal, tolerance) -> bool:
        """n, holding the needle, reaches for the pose that puts it at ``T_goal``."""
        G = T_goal @ np.linalg.inv(frame()) @ tip(n)
        return stream.reach(n, G[:3, 3], tolerance, R_goal=G[:3, :3], until=done)

    def turn(n, pair, a_from, a_to, above=None) -> bool:
        """The needle turned about its centre from ``a_from`` to ``a_to`` (rad) in ``pair``'s
        drive poses (moved by ``above``, 4x4: in the air), 5° a glide at the expert's angular
        speed, each from where the needle is in the jaws then (the expert watches it: a
        needle that turned in the grip is turned back)."""
        angles = np.linspace(a_from, a_to, max(2, int(abs(a_to - a_from) / math.radians(5))))
        for a in angles[1:]:
            if not touching(sim, probe, task.instruments, n):  # (dropped: it cannot go on)
                return True
            T_needle_tip = np.linalg.inv(frame()) @ tip(n)
            G = drive_pose(task.pad, pair, task.needle, float(a), DRIVE_TILT) @ T_needle_tip
            if above is not None:
                G = above @ G
            step = abs(angles[1] - angles[0])
            if stream.glide({n: G}, stream.motor.duration(task.needle.radius * step, step),
                            until=done):  # fmt: skip
                return True
        return False

    def tilted(T) -> np.ndarray:
        c, s = math.cos(DRIVE_TILT), math.sin(DRIVE_TILT)
        out = T.copy()
        out[:3, :3] = np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]]) @ T[:3, :3]
        return out

    up = np.eye(4)
    up[2, 3] = 0.012
    if not take(second, lambda: grasp_pose(frame(), task.needle, stream.goal[second][:3, :3],
                                           0.6, 0.008)):  # fmt: skip
        return
    lifted = tilted(frame())
    lifted[2, 3] += 0.02
    for _ in range(1 + MAX_CORRECTIONS):  # (the expert looks at the needle's tilt, corrects)
        if carry(second, lifted, 0.002):
            return
        if frame()[:3, 2] @ lifted[:3, 2] > math.cos(math.radians(8.0)):
            break
    for k in range(len(task.pairs)):
        if k > 0:  # (PSM2 lifts the needle over the next pair and turns it back in the air)
            if carry(second, up @ frame(), 0.003) or carry(
                    second, up @ drive_pose(task.pad, k, task.needle, DRIVE_THROUGH, DRIVE_TILT),
                    0.003) or turn(second, k, DRIVE_THROUGH, HAND_BACK, up):  # fmt: skip
                return
        if not take(first, lambda: driver_grasp(frame(), task.needle, tip(first)[:3, 2], DRIVE_GRIP,
                                                DRIVE_GRIP_DEPTH)):  # fmt: skip
            return
        if let_go(second, JAW_OPEN if k == 0 else JAW_WIDE):
            return
        if k > 0 and stream.reach(second, clear_of(second, first), 0.003, until=done):
            return
        if k > 0 and turn(first, k, HAND_BACK, DRIVE_START, up):
            return
        start = drive_pose(task.pad, k, task.needle, DRIVE_START, DRIVE_TILT)
        if carry(first, up @ start, 0.002) or carry(first, start, 0.0007):
            return
        if turn(first, k, DRIVE_START, DRIVE_OUT):
            return
        # (the point out, 1-2 mm above the skin: deep in the jaws, their tips clear of it)
        if not take(second, lambda: driver_grasp(frame(), task.needle, DOWN, 0.92, 0.0085)):
            return
        if let_go(first) or turn(second, k, DRIVE_OUT, DRIVE_THROUGH):
            return
    stream.wait(1.0, until=done)


# ---------------------------------------------------------------- attempts
@dataclass
class Stage:
    """A simulation at the start of an exercise's attempt, its session and the state to
    restore before each attempt (built once per exercise)."""

    sim: object
    session: object
    state: object
    arms: tuple[str, ...]


def build_stage(task, joint_errors=()) -> Stage:
    """The stage of ``task``: the study's set-up (the task's PSM at the start, its
    teleoperation clutched) and a session, the ECM homed for camera targeting; for the
    two-handed kinds the console's system with both PSMs homed and their objects drawn.
    ``joint_errors``: the robot's inaccuracy (:attr:`SceneConfig.joint_errors
    <davinci_sim.model.config.SceneConfig.joint_errors>`; the experts then correct by what
    they see, :class:`Streamer`)."""
    from davinci_sim.tasks import install_task

    if task.kind in TWO_HANDED:
        from davinci_sim.model import SceneConfig
        from davinci_sim.system import ConsoleDescription, SystemDescription
        from davinci_sim.system.build import install, new_simulation
        from davinci_sim.system.description import TaskDescription

        scene = SceneConfig(arms=("PSM1", "PSM2", "ECM", task.teleop.mtm), include_patient=False,
                            joint_errors=joint_errors)  # fmt: skip
        console = ConsoleDescription(operator_present=True, teleop_enabled=True)
        description = SystemDescription(scene, console=console, runner="none",
                                        task=TaskDescription(task.name))  # fmt: skip
        # (the task itself, not its name: a task file of the user's is not a shipped name)
        sim = new_simulation(description, task)
        install(sim, description, task)
        session = sim.components["task"]
        arms = ("PSM1", "PSM2")
        for n in (*arms, "ECM"):
            sim.arms[n].state_command("enable")
            sim.arms[n].state_command("home")
        ready = lambda: all(sim.arms[n].is_homed() and not sim.arms[n].is_busy()  # noqa: E731
                            for n in (*arms, "ECM"))  # fmt: skip
        if not sim.run_until(ready, 20.0):
            raise RuntimeError(f"{task.name}: the arms did not home")
        session.teleop.clutch(True)
    else:
        from davinci_sim.study.trial import build_setup

        # (its own: not the trials' cached set-up, it is closed)
        setup = build_setup(task, joint_errors=joint_errors)
        sim = setup.sim
        setup.teleop.clutch(True)
        session = install_task(sim, task)
        arms = (task.teleop.psm,)
        if task.kind == "camera_targeting":
            ecm = sim.arms["ECM"]
            ecm.state_command("enable")
            ecm.state_command("home")
            if not sim.run_until(lambda: ecm.is_homed() and not ecm.is_busy(), 10.0):
                raise RuntimeError(f"{task.name}: the ECM did not home")
    sim.run_for(0.3)  # (objects at rest: READY)
    return Stage(sim, session, sim.get_state(), arms)


def _time_budget(task, motor: Motor) -> float:
    """Simulated time an attempt may take before it counts as unfinished, s."""
    if task.kind == "ring_walk":
        return 3.0 * task.path.length / motor.speed + 10.0
    if task.kind == "peg_transfer":
        return 40.0 * task.n_rings
    if task.kind == "needle_pickup":
        return 30.0
    if task.kind == "needle_drive":
        return 30.0 + 30.0 * len(task.pairs)
    return 15.0 * len(task.targets) + 5.0


def attempt(stage: Stage, task, motor: Motor) -> dict:
    """One attempt of ``task`` by ``motor``'s expert from the stage's start: the session's
    row with ``finished`` True, or ``{"finished": False}`` if it did not finish in time."""
    sim, session = stage.sim, stage.session
    sim.set_state(stage.state)
    before = len(session.results)
    end = sim.time + _time_budget(task, motor)

    def done():
        # (an arm in FAULT, e.g. a tracking error pressing on the board, ends it too)
        return (
            len(session.results) > before
            or sim.time > end
            or any(sim.arms[n].operating_state().state == "FAULT" for n in stage.arms)
        )

    T_camera_task = np.linalg.inv(task.T_task_camera(sim.T_cart_camera()))
    if task.kind == "camera_targeting":
        do_camera(sim, motor, session, task, done)
    else:
        stream = Streamer(sim, motor, T_camera_task, stage.arms,
                          sees_tips=bool(sim.config.joint_errors))  # fmt: skip
        script = {"needle_targeting": do_needle, "ring_walk": do_ring_walk,
                  "peg_transfer": do_peg, "needle_pickup": do_needle_pickup,
                  "needle_drive": do_needle_drive}[task.kind]  # fmt: skip
        script(stream, session, task, done)
    sim.run_until(done, 2.0)
    if len(session.results) > before:
        return {**session.results[-1], "finished": True}
    return {"finished": False}


def expert_attempts(task, *, subjects: int, repetitions: int, seed: int, progress=None,
                    joint_errors=()):  # fmt: skip
    """The attempts of ``subjects`` experts (:func:`sample_experts` of ``seed``) x
    ``repetitions`` at ``task`` (rows, subject-major); each attempt's randomness is keyed
    by (seed, subject, repetition); ``joint_errors``: on an inaccurate robot
    (:func:`build_stage`)."""
    from davinci_sim.operators.params import sample_experts

    if task.kind not in EXERCISES:
        raise ValueError(f"no scripted expert for a {task.kind} task; kinds: {list(EXERCISES)}")
    params = sample_experts(subjects, seed=seed)
    stage = build_stage(task, joint_errors)
    rows = []
    try:
        for s in range(subjects):
            for r in range(1, repetitions + 1):
                rng = np.random.default_rng([int(seed), s, r, 0xE8])
                motor = Motor.of(params, s, r, task.teleop.scale, rng)
                row = attempt(stage, task, motor)
                rows.append({**row, "subject": s, "repetition": r})
                if progress is not None:
                    progress(s, r, row)
    finally:
        stage.sim.close()
    return rows
