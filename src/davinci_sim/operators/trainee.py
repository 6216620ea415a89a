"""A synthetic trainee: a person holding an MTM, following the task's path by sight.

One :class:`SyntheticTrainee` object runs a batch of n trials (one trainee each, arrays of
shape (n, ...)), stepped together at the haptic rate. Each step it is given what the
endoscope shows now (the tool tip, camera frame) and the force the MTM applies to the hand
(HRSV axes = camera axes), and returns the hand's position (HRSV, m) — the MTM handle's.

The model, per trial (the parameters and their sources: :mod:`davinci_sim.operators.params`):

1. **Perception.** The trainee sees the tool tip with a visuomotor delay τ: the observation
   used at time t is the one taken at t − τ (a ring buffer of observations).
2. **Intended motion** (:mod:`davinci_sim.operators.plan`). Once the tool is first seen,
   a minimum-jerk reach brings it to point 1; when the trainee *sees* it within half the
   start tolerance, they wait a reaction time, then follow the path with minimum-jerk
   strokes between the numbered points (Flash & Hogan 1985). The plan is in the camera
   frame; the hand moves by the tool motion divided by the teleop scale (the trainee knows
   the scale and the axes: the dVRK aligns HRSV with the camera).
3. **Visual correction.** The seen error between where the tool was meant to be τ ago (an
   efference copy of the plan) and where it was seen, e = p_plan(t − τ) − y(t − τ), drives
   a hand velocity ω_c·e/scale: with the delay, the loop is the crossover model of manual
   control, ω_c·e^(−τs)/s (McRuer & Jex 1967).
4. **Command and motor noise.** The hand velocity command u = u_plan + u_correction is
   corrupted by signal-dependent noise k·‖u‖·n (Harris & Wolpert 1998,
   :mod:`davinci_sim.operators.noise`) and integrated into the limb's equilibrium point
   x_eq (the virtual trajectory of equilibrium-point control, Flash 1987).
5. **Limb impedance.** The hand is a mass-spring-damper about the equilibrium (Hogan 1985):
   ``m·ẍ = K·(x_eq − x) + D·(ẋ_eq − ẋ) + m·a_plan + F_tremor + F_mtm``. m·a_plan is the
   feed-forward force of an internal model of the limb's inertia for the planned hand
   acceleration (Shadmehr & Mussa-Ivaldi 1994; Wolpert, Miall & Kawato 1998), so that the
   unperturbed hand follows the plan instead of lagging it by m·a/K. The MTM's force F_mtm
   (the guidance) really moves the hand, by ~F/K at low frequency, until the visual
   correction takes it back. F_tremor is physiological tremor, a narrow-band force scaled
   so that the free hand trembles with the subject's rms amplitude at 8-12 Hz.
6. **Practice.** Repetition j (1 = first) scales the practised values by the power law of
   practice P(j) = 1 + E·j^(−α) (Newell & Rosenbloom 1981): speed / P, noise k · P,
   crossover ω_c / P. With reliance on guidance
   (:class:`~davinci_sim.operators.params.Mechanisms`) the crossover and the noise follow
   their own practice count ``own_practice`` (guided trials count less), the speed j.
   A trial's speed is also its own pace times the subject's (``pace``: a lognormal draw
   per trial, :func:`~davinci_sim.operators.params.trial_pace`; none in the table's
   trainees, a fitted profile sets its spread).
7. **Co-contraction** (optional, :class:`~davinci_sim.operators.params.Mechanisms`): the
   force the MTM applies to the hand above a threshold drives a co-contraction level c
   (first-order lag) that scales the limb's stiffness and damping by 1 + c.

Not modelled: depth misperception in the stereo view, grip changes under force, fatigue,
clutching (a trainee never clutches: the seed task fits in the MTM's workspace at scale
0.6), the MTM's orientation beyond a task's planned wrist turns (``wrist``:
:mod:`davinci_sim.operators.wrist`; the hand holds the handle's orientation otherwise).

Two ways to couple it to an MTM: :meth:`step` integrates the limb itself (the handle follows
the hand rigidly; put the handle's inertia into ``mass``); or call :meth:`command` each tick
and apply :meth:`hand_force` at the simulated MTM's handle (the device integrates the
dynamics, e.g. with the impedance of :class:`davinci_sim.devices.hand.HandImpedance`, whose
``mass`` puts the limb's mass on the handle: without it the hand's spring would drive a
handle of a few grams, a much lighter and livelier system than a held MTM).
"""

from __future__ import annotations

import copy
import math
from typing import NamedTuple

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.kinematics import jit
from davinci_sim.operators.noise import MotorNoise, Tremor, TrialNoise
from davinci_sim.operators.params import (
    TREMOR_BANDWIDTH_HZ,
    Mechanisms,
    SubjectParams,
    trial_pace,
)
from davinci_sim.operators.plan import path_plan, straight_plan, stroke_durations
from davinci_sim.operators.wrist import WristTurns, hand_rotation_row, plan_fraction_row

#: Shortest reach to point 1, s (a minimum-jerk reach of a few mm still takes a while).
MIN_REACH_TIME = 0.3

_ROW = None  # the compiled step (numba), else the numpy step runs
if jit.ENABLED:
    from davinci_sim.operators import trainee_row

    _ROW = trainee_row if trainee_row.READY else None
_NO_FORCE = np.zeros((0, 3))


def owned(a) -> np.ndarray:
    """``a`` as a writable C-ordered float array (itself when it is one): the compiled
    step's one signature, whatever flags a parameter array has (a subject's are read-only)."""
    if isinstance(a, np.ndarray) and a.dtype == float and a.flags.c_contiguous:
        if a.flags.writeable:
            return a
    return np.array(a, dtype=float)


class HandState(NamedTuple):
    position: np.ndarray
    """Hand (MTM handle) positions, (n, 3), m, HRSV."""
    velocity: np.ndarray
    """(n, 3), m/s."""


class TraineePhase:
    WAITING = 0
    """No observation yet (the first τ)."""
    TO_START = 1
    """Reaching for / holding at point 1."""
    FOLLOWING = 2
    """Following the path."""
    DONE = 3
    """The plan has reached the last point (the trainee holds it there)."""


class SyntheticTrainee:
    """n trainees, one per trial (see the module docstring).

    Args:
        params: one entry per trial (e.g. ``subjects.take(subject_of_trial)``).
        repetition: repetition number j ≥ 1 of each trial (n,), for the practice law.
        path: the path in the camera frame.
        knots: arc lengths of the numbered points on ``path`` (S + 1,), m
            (``PathTask.marker_arc_lengths``).
        hand_start: hand (MTM handle) positions at the start, (n, 3), m, HRSV.
        scale: teleop motion scale, tool motion / hand motion.
        start_tolerance: the task's, m.
        noise_keys: one integer key per trial (sequence), seeding its noise streams.
        dt: step, s.
        motor_noise, tremor: switch the noise sources (for tests).
        own_practice: practice count of the own correction (crossover, noise) (n,), ≥ 1;
            None: ``repetition`` (no reliance on guidance).
        mechanisms: the reactions to guidance (co-contraction; the reliance is in
            ``own_practice``); None: off.
        wrist: the hand's turns along the path (a task's carried object,
            :class:`~davinci_sim.operators.wrist.WristTurns`); None: none.
    """

    def __init__(
        self,
        params: SubjectParams,
        *,
        repetition,
        path: Polyline,
        knots,
        hand_start,
        scale: float,
        start_tolerance: float,
        noise_keys,
        dt: float = 0.001,
        motor_noise: bool = True,
        tremor: bool = True,
        own_practice=None,
        mechanisms: Mechanisms | None = None,
        wrist: WristTurns | None = None,
    ) -> None:
        n = len(params)
        self.n = n
        self.params = params
        self.dt = float(dt)
        self.path = path
        self.knots = np.asarray(knots, dtype=float)
        if self.knots.ndim != 1 or len(self.knots) < 2 or np.any(np.diff(self.knots) <= 0):
            raise ValueError(f"knots must be increasing arc lengths, got {knots!r}")
        if not 0 < scale <= 1:
            raise ValueError(f"scale must be in ]0, 1], got {scale!r}")
        self.scale = float(scale)
        self.start_tolerance = float(start_tolerance)
        self.p_start = path.point_at(self.knots[0])
        x0 = np.asarray(hand_start, dtype=float)
        if x0.shape != (n, 3):
            raise ValueError(f"hand_start must be ({n}, 3), got {x0.shape}")
        keys = list(noise_keys)
        if len(keys) != n:
            raise ValueError(f"need one noise key per trial ({n}), got {len(keys)}")
        factor = params.practice_factor(np.broadcast_to(np.asarray(repetition), (n,)))
        self.practice = factor
        self.pace = trial_pace(params.pace_spread, keys)
        """Each trial's own pace: its speed over the subject's at this practice (n,)."""
        self.speed = params.speed / factor * self.pace
        if own_practice is not None:
            own = np.broadcast_to(np.asarray(own_practice, dtype=float), (n,))
            if not np.all(np.isfinite(own) & (own >= 1.0)):
                raise ValueError(f"own_practice must be >= 1, got {own_practice!r}")
            factor = params.practice_factor(own)
        self.own_practice_factor = factor
        self.noise_k = params.noise * params.noise_factor(factor) if motor_noise else np.zeros(n)
        self.crossover = params.crossover / factor
        self.mechanisms = mechanisms or Mechanisms()
        self.wrist = wrist
        """The hand's turns along the path (:mod:`davinci_sim.operators.wrist`), None: the
        hand keeps the handle's orientation."""
        self.co_contraction = np.zeros(n)
        """Co-contraction level c of each trial (stiffness and damping × (1 + c))."""
        self.durations = stroke_durations(np.diff(self.knots), self.speed)
        # Tremor force gain: free-hand displacement rms per axis A/√3 at the tremor peak.
        w = 2 * np.pi * params.tremor_frequency
        impedance = np.abs(params.stiffness - params.mass * w**2 + 1j * params.damping * w)
        self.tremor_gain = (params.tremor_amplitude / math.sqrt(3) * impedance) if tremor else 0
        self.delay_steps = np.maximum(1, np.round(params.delay / self.dt)).astype(int)
        size = int(self.delay_steps.max()) + 1
        self._obs = np.zeros((n, size, 3))
        self._noise = TrialNoise(keys, 6)
        self._tremor = Tremor(params.tremor_frequency, bandwidth_hz=TREMOR_BANDWIDTH_HZ, dt=dt)
        self._motor = MotorNoise(n, dt=dt)
        self.k = 0
        self.x = x0.copy()
        self.v = np.zeros((n, 3))
        self.x_eq = x0.copy()
        self.v_eq = np.zeros((n, 3))
        # Event times, +inf until they happen.
        self.t_reach = np.full(n, np.inf)
        """When the reach for point 1 started (the tool first seen), s."""
        self.reach_from = np.zeros((n, 3))
        self.reach_time = np.ones(n)
        self.t_follow = np.full(n, np.inf)
        """When following the path starts, s."""
        self.last_tremor_force = np.zeros((n, 3))
        self.feedforward_force = np.zeros((n, 3))
        self._v_plan = np.zeros((n, 3))
        self._row_constants: tuple | None = None

    def set_hand_start(self, hand_start) -> None:
        """Where the hands are at the start, (n, 3), HRSV, m: only before the first step
        (e.g. the MTM handle's position when the trainee takes it)."""
        if self.k != 0:
            raise RuntimeError("the hand start can only be set before the first step")
        x0 = np.asarray(hand_start, dtype=float)
        if x0.shape != (self.n, 3):
            raise ValueError(f"hand_start must be ({self.n}, 3), got {x0.shape}")
        self.x = x0.copy()
        self.x_eq = x0.copy()

    #: Attributes with one entry per trial along their first axis (see :meth:`take`).
    _PER_TRIAL = (
        "practice", "own_practice_factor", "co_contraction", "speed", "noise_k", "crossover",
        "durations", "delay_steps", "_obs",
        "x", "v", "x_eq", "v_eq", "t_reach", "reach_from", "reach_time", "t_follow",
        "last_tremor_force", "feedforward_force", "_v_plan",
    )  # fmt: skip

    def take(self, rows) -> SyntheticTrainee:
        """The trainees of ``rows`` (indices), in their current state, as a new object
        (e.g. to keep stepping the trials that are still running)."""
        rows = np.asarray(rows, dtype=int)
        out = copy.copy(self)
        for name in self._PER_TRIAL:
            setattr(out, name, getattr(self, name)[rows])
        if np.ndim(self.tremor_gain):
            out.tremor_gain = self.tremor_gain[rows]
        out.n = len(rows)
        out.params = self.params.take(rows)
        out._noise = self._noise.take(rows)
        out._tremor = self._tremor.take(rows)
        out._motor = self._motor.take(rows)
        return out

    # ------------------------------------------------------------ plan
    @property
    def time(self) -> float:
        """Time of the next step since the start, s."""
        return self.k * self.dt

    @property
    def phase(self) -> np.ndarray:
        """:class:`TraineePhase` of each trial."""
        t = self.time
        phase = np.where(np.isinf(self.t_reach), TraineePhase.WAITING, TraineePhase.TO_START)
        following = t >= self.t_follow
        phase = np.where(following, TraineePhase.FOLLOWING, phase)
        done = following & (t - self.t_follow >= self.durations.sum(axis=1))
        return np.where(done, TraineePhase.DONE, phase)

    def hand_rotations(self, t: float, R0) -> np.ndarray:
        """(n, 3, 3) the hands' target orientations (HRSV) at time ``t`` (s): ``R0``
        (n, 3, 3), the handle's when the hand took it, turned by :attr:`wrist` at the
        plan's progress then (``R0`` itself without a wrist)."""
        R0 = np.asarray(R0, dtype=float)
        out = R0.copy()
        if self.wrist is None:
            return out
        total = self.path.length
        progress, turn = self.wrist.progress, self.wrist.turn
        for i in range(self.n):
            f = plan_fraction_row(self.knots, self.durations[i], t - self.t_follow[i], total)
            hand_rotation_row(progress, turn, f, R0[i], out[i])
        return out

    def plan(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Intended tool position and velocity (camera frame) at times ``t`` (n,), and
        whether there is a plan at all then (n,) (none before the tool was first seen)."""
        t = np.broadcast_to(np.asarray(t, dtype=float), (self.n,))
        valid = t >= self.t_reach
        goal = np.broadcast_to(self.p_start, (self.n, 3))
        p, v = straight_plan(
            self.reach_from, goal, self.reach_time, np.where(valid, t - self.t_reach, 0.0)
        )
        following = t >= self.t_follow
        if np.any(following):
            since = np.where(following, t - self.t_follow, 0.0)
            pp, vp, _ = path_plan(self.path, self.knots, self.durations, since)
            p = np.where(following[:, None], pp, p)
            v = np.where(following[:, None], vp, v)
        return p, v, valid

    # ------------------------------------------------------------ step
    @property
    def stiffness(self) -> np.ndarray:
        """The limb's stiffness now (n,), N/m: relaxed × (1 + co-contraction)."""
        return self.params.stiffness * (1.0 + self.co_contraction)

    @property
    def damping(self) -> np.ndarray:
        """The limb's damping now (n,), N·s/m: relaxed × (1 + co-contraction)."""
        return self.params.damping * (1.0 + self.co_contraction)

    def feel(self, dt: float, force_on_hand) -> None:
        """The co-contraction's step for the force the MTM applies to the hand now, (n, 3),
        N (HRSV): c ← c + (c_target(‖F‖) − c)·dt/τ. Nothing changes with stiffening off."""
        m = self.mechanisms
        if m.stiffening_gain <= 0:
            return
        norm = np.linalg.norm(np.asarray(force_on_hand, dtype=float), axis=1)
        target = m.co_contraction_target(norm)
        self.co_contraction = self.co_contraction + (target - self.co_contraction) * (
            dt / m.stiffening_time
        )

    def command(self, dt: float, observed_tip, force_on_hand=None) -> np.ndarray:
        """Perceive, plan and command for one step; returns the equilibrium point (n, 3).

        Args:
            dt: the step, s (must be the ``dt`` given at construction: the delays are
                counted in steps).
            observed_tip: the tool tip as the endoscope shows it now, (n, 3), m, camera.
            force_on_hand: the force the MTM applies to the hand now (n, 3), N, HRSV, for
                the co-contraction (:meth:`feel`); None: not felt.
        """
        if abs(dt - self.dt) > 1e-12:
            raise ValueError(f"this trainee steps every {self.dt} s, got dt={dt!r}")
        y = np.asarray(observed_tip, dtype=float)
        if y.shape != (self.n, 3):
            raise ValueError(f"observed_tip must be ({self.n}, 3), got {y.shape}")
        if _ROW is not None and dt == self.dt:
            return self._command_compiled(y, force_on_hand)
        if force_on_hand is not None:
            self.feel(dt, force_on_hand)
        k, t = self.k, self.time
        size = self._obs.shape[1]
        self._obs[:, k % size] = y
        seen = k >= self.delay_steps
        rows = np.arange(self.n)
        y_seen = self._obs[rows, (k - self.delay_steps) % size]
        t_seen = t - self.delay_steps * self.dt
        # First sight of the tool: reach for point 1 from where it is seen.
        start = seen & np.isinf(self.t_reach)
        if np.any(start):
            self.t_reach[start] = t
            self.reach_from[start] = y_seen[start]
            distance = np.linalg.norm(self.p_start - y_seen[start], axis=1)
            self.reach_time[start] = np.maximum(MIN_REACH_TIME, distance / self.speed[start])
        # Seen at point 1 after the reach: start along the path after a reaction time.
        ready = (
            seen
            & np.isinf(self.t_follow)
            & (t >= self.t_reach + self.reach_time)
            & (np.linalg.norm(y_seen - self.p_start, axis=1) <= 0.5 * self.start_tolerance)
        )
        self.t_follow[ready] = t + self.params.reaction_time[ready]
        p_now, v_now, valid_now = self.plan(t)
        v_now = np.where(valid_now[:, None], v_now, 0.0)
        # Planned hand acceleration, by differencing the planned velocity (one step back).
        a_plan = (v_now - self._v_plan) / (self.scale * dt)
        self._v_plan = v_now
        self.feedforward_force = self.params.mass[:, None] * a_plan
        p_then, _, valid_then = self.plan(t_seen)
        error = np.where((seen & valid_then)[:, None], p_then - y_seen, 0.0)
        u = (v_now + self.crossover[:, None] * error) / self.scale
        white = self._noise.next()
        n_motor = self._motor.step(white[:, 3:])
        u = u + (self.noise_k * np.linalg.norm(u, axis=1))[:, None] * n_motor
        self.last_tremor_force = np.asarray(self.tremor_gain)[..., None] * self._tremor.step(
            white[:, :3]
        )
        self.x_eq = self.x_eq + u * dt
        self.v_eq = u
        self.k += 1
        return self.x_eq.copy()

    def _command_compiled(self, y: np.ndarray, force_on_hand) -> np.ndarray:
        """:meth:`command` in one compiled call (:func:`~davinci_sim.operators.trainee_row.
        command_rows`): the same laws row by row, the same bits; the arrays it keeps are
        written in place."""
        feel = force_on_hand is not None and self.mechanisms.stiffening_gain > 0
        force = _NO_FORCE if not feel else np.array(force_on_hand, dtype=float, order="C")
        if feel and force.shape != (self.n, 3):
            raise ValueError(f"force_on_hand must be ({self.n}, 3), got {force.shape}")
        white = np.ascontiguousarray(self._noise.next())  # (a column of the drawn block)
        args = self.row_args(np.ascontiguousarray(y), force, feel, white)
        _ROW.command_rows(self.k, self.time, *args)
        self.k += 1
        return self.x_eq.copy()

    def row_args(self, y: np.ndarray, force: np.ndarray, feel: bool, white: np.ndarray) -> tuple:
        """The arguments of :func:`~davinci_sim.operators.trainee_row.command_rows` after
        ``k`` and ``t`` (:data:`~davinci_sim.operators.trainee_row.ARGS`) for the tips seen
        ``y`` and the forces ``force`` (n, 3) (felt if ``feel``) and the normals ``white``
        (n, 6): this trainee's arrays, which the kernel writes in place."""
        n = self.n
        c = self._row_constants
        if c is None:
            path, m = self.path, self.mechanisms
            c = self._row_constants = (
                self.p_start.astype(float), self.knots.copy(),
                np.array(path.cumulative_length), np.array(path.segment_lengths),
                np.array(path.starts), np.array(path.edges),
                np.array([m.stiffening_gain, m.stiffening_threshold, m.stiffening_max,
                          self.dt / m.stiffening_time if m.stiffening_gain > 0 else 0.0]),
                np.array([self._motor.a, self._motor.b]),
            )  # fmt: skip
        p = self.params
        tremor, gain = self._tremor, np.asarray(self.tremor_gain, dtype=float)
        # (the arrays the numpy step rebinds are written in place here: each is owned)
        for name in ("co_contraction", "x_eq", "v_eq", "_v_plan", "feedforward_force",
                     "last_tremor_force"):  # fmt: skip
            a = getattr(self, name)
            if not (a.flags.c_contiguous and a.flags.writeable and a.dtype == float):
                setattr(self, name, np.array(a, dtype=float))
        return (
            self.dt, self.scale, self.start_tolerance, MIN_REACH_TIME,
            c[0], c[1], c[2], c[3], c[4], c[5], y, force, feel, c[6],
            self.co_contraction, self._obs, self.delay_steps, self.t_reach, self.reach_from,
            self.reach_time, owned(self.speed), self.t_follow, owned(p.reaction_time),
            self._v_plan, owned(p.mass), self.feedforward_force, owned(self.crossover),
            self.durations, white, c[7], self._motor.state, owned(self.noise_k),
            tremor.a1.reshape(-1), tremor.a2.reshape(-1), tremor.gain.reshape(-1),
            tremor._x, tremor._y1, tremor._y2,
            gain if gain.ndim else np.full(n, float(gain)),
            self.last_tremor_force, self.x_eq, self.v_eq,
        )  # fmt: skip

    def push_force(self) -> np.ndarray:
        """The part of :meth:`hand_force` that does not depend on the handle (n, 3), HRSV,
        N: ``D·ẋ_eq`` + inertia feed-forward + tremor. On an MTM the device's hand spring
        and damper (stiffness K, damping D, target ``x_eq``) add the rest."""
        D = self.damping[:, None]
        return D * self.v_eq + self.feedforward_force + self.last_tremor_force

    def hand_force(self, position, velocity) -> np.ndarray:
        """Force the hand applies to a handle at ``position``/``velocity`` (n, 3), HRSV, N:
        the limb's spring and damper about the equilibrium, the inertia feed-forward and
        the tremor."""
        K = self.stiffness[:, None]
        D = self.damping[:, None]
        spring = K * (self.x_eq - position) + D * (self.v_eq - velocity)
        return spring + self.feedforward_force + self.last_tremor_force

    def step(self, dt: float, observed_tip, force_on_hand) -> HandState:
        """One step with the limb integrated here (semi-implicit Euler).

        Args:
            dt: s.
            observed_tip: tool tip shown by the endoscope now, (n, 3), m, camera frame.
            force_on_hand: force the MTM applies to the hand, (n, 3), N, HRSV.

        Returns:
            The hand (MTM handle) position and velocity after the step, HRSV.
        """
        self.command(dt, observed_tip, force_on_hand)
        f = self.hand_force(self.x, self.v) + np.asarray(force_on_hand, dtype=float)
        self.v = self.v + f / self.params.mass[:, None] * dt
        self.x = self.x + self.v * dt
        return HandState(self.x.copy(), self.v.copy())
