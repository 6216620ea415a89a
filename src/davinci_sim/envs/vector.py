"""N environments stepped together as arrays: a ``gymnasium.vector.VectorEnv`` on the
study's batch laws.

The single environment (:class:`~davinci_sim.envs.base.DavinciEnv`) spends its time in
Python calls that each handle one arm of one environment. :class:`DavinciVectorEnv` runs N
rows as arrays instead, composing the same laws the live objects apply to one row (as the
study's :class:`~davinci_sim.study.batch.TrialBatch` does; no formula of its own): the
control ramp of :mod:`davinci_sim.envs.control`; the ``servo_cp`` path of the arm — the
batched closed-form PSM IK (:func:`~davinci_sim.kinematics.psm_ik.psm_ik_closed_form_batch`),
the joint limits, the twist feed-forward (:func:`~davinci_sim.sim.arm_laws.joint_velocity`)
— or ``servo_jp``; the jaw's finger setpoints (:func:`~davinci_sim.sim.jaw.finger_setpoints`);
the tracking fault (:mod:`davinci_sim.sim.arm_laws`); the joint servo
(:func:`~davinci_sim.sim.servo.servo_ctrl`, ``JointServo.bias_of``); the tip's pose and
Jacobian (``tip_kinematics``); the task's sample, state machine and metrics
(:mod:`davinci_sim.envs.problems`).

**One compiled call per action.** With numba (the default) a whole control period runs in
compiled code, row by row (:class:`~davinci_sim.sim.rows_chunk.ArmChunk`): the ramp, the
IK and feed-forward, the tracking watch, the servo, ``mj_step`` (MuJoCo's C, called from the
compiled loop) and the tip's kinematics, K ticks without returning to Python; the task's
per-tick samples are then taken from the period's record. A tick the kernel has no compiled
form of (an IK answer to polish, a singular Jacobian) runs in Python for that row. The
Python ticks (:meth:`DavinciVectorEnv._python_tick`, the batch laws of the list above, one
numpy call per law per tick with ``mj_step`` of the rows in one compiled call,
:class:`~davinci_sim.sim.rows_step.RowStepper`) are the fallback without numba and the
tests' oracle: the same results to 1e-12 (``tests/envs/test_vector_compiled.py``).
``threads=k`` runs the rows on k threads (the compiled loop and ``mj_step`` release the GIL;
the rows are independent, so the results are the same bits).

Like the study's batch it holds the camera and the PSM's base frame as they are at the
start (the ECM does not move; the live simulation follows the setup joints' µm-level yield
exactly), so a row equals a single environment to machine precision when the live
simulation holds them too (``simulation.BASE_FRAME_TOLERANCE = inf``, as
``tests/envs`` checks), and within µm otherwise. It runs the Reach and path-following
environments (PSM tasks whose samples need no scene objects).

**Autoreset** is Gymnasium 1.x's default, ``NEXT_STEP``: the step after a row terminates
or truncates resets that row (its action is ignored) and returns its first observation
with reward 0, ``terminated`` and ``truncated`` False. ``autoreset_mode="SameStep"``
(``AutoresetMode.SAME_STEP``, what Stable-Baselines3's vector environments expect) resets
the row within the step that ended it: the returned observation is the new episode's
first, the last one is in ``info["final_obs"]`` (and the step's info in
``info["final_info"]``). ``reset(seed=s)`` seeds row i with
``s + i`` (as ``SyncVectorEnv`` does), so row i is the single environment reset with seed
``s + i``. ``info`` holds arrays with Gymnasium's ``_<key>`` masks.

**Physics** (``physics=``, :data:`PHYSICS`): ``"full"`` steps the scene of the single
environment; ``"psm"`` a reduced model without the ECM's branch (welded at the start, as the
rows hold the camera anyway; exact), ``"arm"`` one with only the PSM's own joints (its setup
joints welded too; close, not exact): :mod:`davinci_sim.envs.reduced`.
"""

from __future__ import annotations

import copy
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from davinci_sim.envs import control
from davinci_sim.envs.base import action_space, joint_steps, make_problem, observation_space
from davinci_sim.envs.control import orientation_features
from davinci_sim.envs.setup import EnvConfig, build_start
from davinci_sim.geometry.so3 import rotate_pairs
from davinci_sim.kinematics.psm_ik import psm_ik_closed_form_batch
from davinci_sim.sim import arm_laws as laws
from davinci_sim.sim import rows_chunk
from davinci_sim.sim.jaw import finger_setpoints
from davinci_sim.sim.rows_chunk import ArmChunk, Ramp
from davinci_sim.sim.rows_step import RowStepper
from davinci_sim.sim.servo import servo_ctrl

#: ``physics=``: ``full`` — every row steps the whole scene (24 joints: PSM, ECM, setup
#: joints); ``psm`` — the PSM and its setup joints (14; the ECM's branch welded: exact);
#: ``arm`` — the PSM's own 8 joints (its setup joints welded too: within ~0.3 mm).
#: See :mod:`davinci_sim.envs.reduced`.
PHYSICS = ("full", "psm", "arm")

_NO_TWIST, _NO_ROTATION = np.zeros((0, 6)), np.zeros((0, 3, 3))
"""Stand for the Cartesian ramp's arrays in a joint ramp (one compiled signature)."""


class DavinciVectorEnv(VectorEnv):
    """``num_envs`` environments of one :class:`~davinci_sim.envs.setup.EnvConfig`
    (``**kwargs``) as arrays (see the module docstring)."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self, num_envs: int, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        threads: int = 1, physics: str = "full", **kwargs,
    ) -> None:  # fmt: skip
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if not (isinstance(threads, int) and threads >= 1):
            raise ValueError(f"threads must be an int >= 1, got {threads!r}")
        if physics not in PHYSICS:
            raise ValueError(f"physics must be one of {PHYSICS}, got {physics!r}")
        modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            mode = None
        if mode not in modes:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in modes]}, "
                             f"got {autoreset_mode!r}")  # fmt: skip
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.config = config = EnvConfig(**kwargs)
        if config.images:
            raise ValueError("the vector environment has no image observations (images=False)")
        self.num_envs = n = num_envs
        self.K = control.ticks_per_action(config.control_hz)
        start = self._start = build_start(config)
        if start.arm != start.psm or (start.task is not None and start.task.kind != "path"):
            start.sim.close()
            raise ValueError("the vector environment runs Reach and path-following tasks only")
        sim = start.sim
        sim.set_state(start.state)
        self.problem = make_problem(start, config, n)
        self.single_observation_space = observation_space(start, config, self.problem)
        self.single_action_space = action_space(start, config)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.render_mode = None
        psm = sim.arms[start.psm]
        self.model = sim.model
        self._gravcomp = self.model.ngravcomp > 0  # (else qfrc_gravcomp stays 0: not copied)
        self.threads = threads
        self._pool = ThreadPoolExecutor(threads) if threads > 1 else None
        self.dt = sim.dt
        self._data0 = copy.copy(sim.data)
        self.physics = physics
        self._map = None  # (reduced physics: its qpos, dof and actuator addresses in the full)
        if physics != "full":
            from davinci_sim.envs.reduced import kept_joints, reduce_to

            try:
                keep = kept_joints(physics, start.psm)
                r = reduce_to(sim.config, sim.model, self._data0, keep)
            except ValueError:
                sim.close()
                raise
            self.model, self._data0, self._map = r.model, r.data, (r.qpos, r.dof, r.actuator)
        self.datas = [copy.copy(self._data0) for _ in range(n)]
        self._stepper = RowStepper([self.model] * n, self.datas)
        servo = self._servo = sim.servo
        self._servo0 = servo.get_state()
        self.effort_mode = servo.effort_mode.copy()
        self.gravity = servo.gravity_compensation.copy()
        self.chain = psm.chain
        self.psm_act, self.psm_q, self.psm_v = (
            psm.actuator_indices, psm.qpos_addresses, psm.dof_addresses,
        )  # fmt: skip
        self.jaw_act, self.jaw_q, self.jaw_v = (
            psm.jaw.actuator_indices, psm.jaw.qpos_addresses, psm.jaw.dof_addresses,
        )  # fmt: skip
        self.jaw_spec = psm.jaw.spec
        self.tolerance = psm.tracking_tolerance
        self.T_camera_rcm = psm.base_frame()[0].copy()
        self.T_rcm_camera = np.linalg.inv(self.T_camera_rcm)
        self._joint_step = joint_steps(self.chain, config.max_joint_step)
        self._lo, self._hi = start.workspace
        d = sim.data
        self.Q, self.V = np.tile(d.qpos, (n, 1)), np.tile(d.qvel, (n, 1))
        self._qfrc = np.tile(d.qfrc_bias, (n, 1)), np.tile(d.qfrc_gravcomp, (n, 1))
        self.bias = np.tile(servo.bias(d), (n, 1))
        self.q_ref = np.tile(servo.q_ref, (n, 1))
        self.qd_ref = np.tile(servo.qd_ref, (n, 1))
        self.tau_ff = np.tile(servo.tau_ff, (n, 1))
        self.time = np.full(n, sim.time)
        self._bad_since = np.full(n, np.nan)
        self.goal = np.tile(start.p_start_camera, (n, 1))
        self.q_goal = self.q_ref[:, self.psm_act].copy()
        self.steps = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=bool)
        self._rngs = [seeding.np_random(None)[0] for _ in range(n)]
        self._chunk = None  # (the compiled period; None: the Python ticks)
        if rows_chunk.COMPILED:
            self._chunk = ArmChunk(
                self._stepper, servo, self.chain, self.psm_act, self.psm_q, self.tolerance,
                self.T_camera_rcm, layout=self._map, copy_gravcomp=self._gravcomp,
                timestep=self.model.opt.timestep,
            )  # fmt: skip
        self._kinematics()
        self._row0 = {
            "Q": self.Q[0].copy(), "V": self.V[0].copy(), "bias": self.bias[0].copy(),
            "qfrc_bias": self._qfrc[0][0].copy(), "qfrc_gravcomp": self._qfrc[1][0].copy(),
            "time": float(sim.time),
        }  # fmt: skip

    # ------------------------------------------------------------ gymnasium
    def reset(self, *, seed=None, options=None):
        """Reset every row; ``seed`` an int (row i: ``seed + i``) or one per row."""
        if seed is not None:
            seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else seed
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} environments")
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        rows = np.arange(self.num_envs)
        self._reset_rows(rows)
        self._autoreset[:] = False
        feats = self.problem.features(self.T_psm)
        self.problem.outcome(self.T_psm, features=feats)  # (the reward's baselines)
        return self._observation(feats), {}

    def step(self, actions):
        a = np.asarray(actions, dtype=float).reshape(self.action_space.shape)
        if not np.all(np.isfinite(a)):
            raise ValueError("the actions must be finite")
        resetting = self._autoreset.copy()
        if resetting.any():
            self._reset_rows(np.flatnonzero(resetting))
        active = ~resetting
        fault = self._control_period(a, active)
        feats = self.problem.features(self.T_psm)  # (the outcome's and the observation's)
        reward, done, terms = self.problem.outcome(self.T_psm, features=feats)
        self.steps += active
        terminated = (done | fault) & active
        truncated = ~terminated & active & (self.steps >= self.config.max_episode_steps)
        reward = np.where(active, reward, 0.0)
        ended = terminated | truncated
        info = {}
        for k, v in terms.items():
            info[k], info[f"_{k}"] = np.where(active, v, 0.0), active.copy()
        info["is_success"], info["_is_success"] = done & active, active.copy()
        info["fault"], info["_fault"] = fault & active, active.copy()
        if ended.any():
            for k, v in self.problem.info().items():
                info[k], info[f"_{k}"] = np.where(ended, v, np.nan), ended.copy()
        obs = self._observation(feats)
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP and ended.any():
            # The ended rows reset now: their last observation goes to info["final_obs"].
            rows = np.flatnonzero(ended)
            final = np.full(self.num_envs, None, dtype=object)
            for i in rows.tolist():
                final[i] = {k: v[i].copy() for k, v in obs.items()}
            info["final_obs"], info["_final_obs"] = final, ended.copy()
            info["final_info"] = {
                k: v for k, v in info.items() if k not in ("final_obs", "_final_obs")
            }
            info["_final_info"] = ended.copy()
            self._reset_rows(rows)
            feats = self.problem.features(self.T_psm)
            self.problem.outcome(self.T_psm, features=feats)  # (the new episodes' baselines)
            fresh = self._observation(feats)
            for k in obs:
                obs[k][rows] = fresh[k][rows]
            ended = np.zeros_like(ended)
        self._autoreset = ended
        return obs, reward, terminated, truncated, info

    def close_extras(self, **kwargs) -> None:
        if getattr(self, "_pool", None) is not None:
            self._pool.shutdown()
        self._start.sim.close()

    # ------------------------------------------------------------ rows
    def _reset_rows(self, rows: np.ndarray) -> None:
        r0 = self._row0
        for i in rows.tolist():
            mujoco.mj_copyData(self.datas[i], self.model, self._data0)
        self.Q[rows], self.V[rows], self.bias[rows] = r0["Q"], r0["V"], r0["bias"]
        self._qfrc[0][rows], self._qfrc[1][rows] = r0["qfrc_bias"], r0["qfrc_gravcomp"]
        s = self._servo0
        self.q_ref[rows], self.qd_ref[rows], self.tau_ff[rows] = (
            s["q_ref"],
            s["qd_ref"],
            s["tau_ff"],
        )
        self.time[rows] = r0["time"]
        self._bad_since[rows] = np.nan
        self.goal[rows] = self._start.p_start_camera
        self.q_goal[rows] = s["q_ref"][self.psm_act]
        self.steps[rows] = 0
        self.problem.reset(rows.tolist(), self._rngs)
        self._kinematics()

    def _kinematics(self) -> None:
        """The tip's pose (camera frame) and Jacobian (RCM frame) of every row."""
        T, self.J_psm = laws.tip_kinematics(self.chain, self.Q[:, self.psm_q])
        self.T_psm = laws.pose_in_reference(self.T_camera_rcm, T)

    def _control_period(self, a: np.ndarray, active: np.ndarray) -> np.ndarray:
        """K ticks of the rows ``active`` under actions ``a``; returns the rows that faulted."""
        K, cfg = self.K, self.config
        cartesian = cfg.action_space == "cartesian"
        if cartesian:
            start = self.goal.copy()
            delta = control.cartesian_delta(a[:, :3], start, cfg.max_step, self._lo, self._hi)
        else:
            start = self.q_goal.copy()
            ch = self.chain
            delta = control.joint_delta(a[:, :6], start, self._joint_step, ch.qmin, ch.qmax)
        delta[~active] = 0.0
        velocity = control.feedforward(delta, K)
        jaw = control.jaw_angle(a[:, -1], self.jaw_spec.qmin, self.jaw_spec.qmax)
        rows = np.flatnonzero(active)
        self.q_ref[np.ix_(rows, self.jaw_act)] = finger_setpoints(jaw[rows, None])
        self.qd_ref[np.ix_(rows, self.jaw_act)] = 0.0
        if cartesian:
            T_goal = np.zeros((self.num_envs, 4, 4))
            T_goal[:, :3, :3] = self._start.R_goal
            T_goal[:, 3, 3] = 1.0
            twist = np.concatenate([velocity, np.zeros_like(velocity)], axis=1)
            local = rotate_pairs(self.T_rcm_camera[:3, :3], twist)
            R_base_goal = np.ascontiguousarray((self.T_rcm_camera @ T_goal)[:, :3, :3])
        else:
            T_goal, local, R_base_goal = None, _NO_TWIST, _NO_ROTATION
        ramp = Ramp(cartesian, start, delta, velocity, R_base_goal, local)
        fault = np.zeros(self.num_envs, dtype=bool)
        running = active.copy()
        if self._chunk is not None:
            self._compiled_period(ramp, running, fault, T_goal)
        else:
            for k in range(1, K + 1):
                self._python_tick(ramp, k, running, fault, T_goal)
                self.problem.after_tick(self.time, self.T_psm, running)
        if cartesian:
            self.goal[active] = (start + delta)[active]
        else:
            self.q_goal[active] = (start + delta)[active]
        return fault

    def _python_tick(self, ramp: Ramp, k: int, running, fault, T_goal) -> None:
        """Tick ``k`` of the period's ``ramp`` for the rows ``running`` with the batch laws
        (the compiled period's oracle and fallback): setpoints, tracking, servo and step."""
        g = control.ramp(ramp.start, ramp.delta, k, self.K)
        live = np.flatnonzero(running)
        if ramp.cartesian:
            T_goal[:, :3, 3] = g
            q_now = self.Q[:, self.psm_q]
            ik = psm_ik_closed_form_batch(self.chain, self.T_rcm_camera @ T_goal, q_now)
            ok = ik.success & laws.within_limits(ik.q, self.chain.qmin, self.chain.qmax)
            ok &= ~laws.other_branch_rows(ik.q, q_now)  # (the live servo_cp refuses it: held)
            qd = laws.joint_velocity(self.J_psm, ramp.twist_base)
            set_rows = np.flatnonzero(ok & running)
            self.q_ref[np.ix_(set_rows, self.psm_act)] = ik.q[set_rows]
            self.qd_ref[np.ix_(set_rows, self.psm_act)] = qd[set_rows]
        else:
            self.q_ref[np.ix_(live, self.psm_act)] = g[live]
            self.qd_ref[np.ix_(live, self.psm_act)] = ramp.velocity[live]
        self._tracking(running, fault)
        self._tick(running)

    def _compiled_period(self, ramp: Ramp, running, fault, T_goal) -> None:
        """The period in compiled calls (:class:`~davinci_sim.sim.rows_chunk.ArmChunk`): a
        row the kernel stops before a tick it has no compiled form of runs that tick in
        :meth:`_python_tick`, then goes on compiled; the task's per-tick samples are taken
        from the record afterwards, tick by tick as the Python path takes them (the task
        does not act on the arm within a period)."""
        K, n = self.K, self.num_envs
        first = np.where(running, 1, K + 1).astype(np.intp)
        stop = np.full(n, rows_chunk.DONE, dtype=np.intp)
        record = rows_chunk.Record.empty(n, K) if self.problem.samples_ticks else None
        T0, t0 = self.T_psm.copy(), self.time.copy()
        while True:
            rows = np.flatnonzero(first <= K)
            if not len(rows):
                break
            self._run_chunk(rows, first, stop, ramp, record)
            first[rows] = K + 1
            fault[rows[stop[rows] == rows_chunk.FAULT]] = True
            fallback = rows[stop[rows] > 0]
            for k in np.unique(stop[fallback]).tolist():
                these = np.zeros(n, dtype=bool)
                these[fallback[stop[fallback] == k]] = True
                self._python_tick(ramp, k, these, fault, T_goal)
                if record is not None:
                    record.T[these, k - 1] = self.T_psm[these]
                    record.t[these, k - 1] = self.time[these]
                    record.ran[these, k - 1] = True
                first[these] = k + 1  # (a row that faulted in it stays at K + 1)
        running &= ~fault
        if record is None:
            return
        T, t = T0, t0
        for k in range(K):
            on = record.ran[:, k]
            T = np.where(on[:, None, None], record.T[:, k], T)
            t = np.where(on, record.t[:, k], t)
            self.problem.after_tick(t, T, on)

    def _run_chunk(self, rows, first, stop, ramp: Ramp, record) -> None:
        """:meth:`ArmChunk.run` of ``rows``, split over the thread pool if there is one."""
        T_psm, J_psm = self.T_psm, self.J_psm
        qfrc_bias, qfrc_gravcomp = self._qfrc

        def run(rs: np.ndarray) -> None:
            self._chunk.run(
                rs, first, self.K, stop, self.effort_mode, self.gravity, self.Q, self.V,
                qfrc_bias, qfrc_gravcomp, self.bias, self.q_ref, self.qd_ref, self.tau_ff,
                self.time, self._bad_since, ramp, T_psm, J_psm, record,
            )  # fmt: skip

        if self._pool is None or len(rows) < 2 * self.threads:
            run(rows)
        else:  # (the kernel releases the GIL: the rows on several cores)
            list(self._pool.map(run, np.array_split(rows, self.threads)))

    def _tracking(self, running: np.ndarray, fault: np.ndarray) -> None:
        """The PSM's tracking watch (the arm's law): a faulted row stops stepping (its
        episode terminates)."""
        bad = laws.tracking_bad(
            self.Q[:, self.psm_q], self.q_ref[:, self.psm_act], self.tolerance,
            self.effort_mode[self.psm_act],
        ).any(axis=1)  # fmt: skip
        since, now = laws.tracking_fault(bad, self._bad_since, self.time)
        self._bad_since[:] = np.where(running, since, self._bad_since)
        now &= running
        fault |= now
        running &= ~now

    def _tick(self, running: np.ndarray) -> None:
        """One 1 ms tick of the rows ``running``: the servo's law, then ``mj_step`` per row."""
        servo = self._servo
        ctrl = servo_ctrl(
            self.Q[:, servo.qposadr], self.V[:, servo.dofadr], self.bias, self.q_ref,
            self.qd_ref, self.tau_ff, self.effort_mode, self.gravity, servo.kp, servo.kv,
        )  # fmt: skip
        rows = np.flatnonzero(running)
        if self._pool is None or len(rows) < 2 * self.threads:
            self._physics(rows, ctrl)
        else:  # (mj_step releases the GIL: the rows' physics on several cores)
            chunks = np.array_split(rows, self.threads)
            list(self._pool.map(lambda c: self._physics(c, ctrl), chunks))
        qfrc_bias, qfrc_gravcomp = self._qfrc
        self.bias[rows] = servo.bias_of(qfrc_bias[rows], qfrc_gravcomp[rows])
        self._kinematics()

    def _physics(self, rows: np.ndarray, ctrl: np.ndarray) -> None:
        """``mj_step`` of ``rows`` with their actuator controls (one compiled call,
        :class:`~davinci_sim.sim.rows_step.RowStepper`); their state read back."""
        if self._map is not None:
            self._physics_reduced(rows, ctrl)
            return
        qfrc_bias, qfrc_gravcomp = self._qfrc
        gravcomp = self._gravcomp
        grav = qfrc_gravcomp if gravcomp else None
        self._stepper.step(rows, ctrl, None, self.Q, self.V, qfrc_bias, grav, None,
                           gravcomp=gravcomp)  # fmt: skip
        self._advance_time(rows)

    def _advance_time(self, rows: np.ndarray) -> None:
        """The rows' time after their step: MuJoCo's own ``time += opt.timestep``, the same
        sum on the same operands, without reading 256 ``MjData.time`` from Python a tick."""
        self.time[rows] += self.model.opt.timestep

    def _physics_reduced(self, rows: np.ndarray, ctrl: np.ndarray) -> None:
        """:meth:`_physics` on the reduced model (``physics="psm"``/``"arm"``): the rows'
        state gathered in the reduced layout, then written into the full model's at once
        (the welded joints keep their start values)."""
        qadr, dadr, act = self._map
        nq, nv = len(qadr), len(dadr)
        q = np.empty((len(rows), nq))
        v, fb, fg = np.empty((len(rows), nv)), np.empty((len(rows), nv)), np.zeros((len(rows), nv))
        gravcomp = self._gravcomp
        self._stepper.step(rows, np.ascontiguousarray(ctrl[:, act]), None, q, v, fb, fg, None,
                           out=np.arange(len(rows)), gravcomp=gravcomp)  # fmt: skip
        self._advance_time(rows)
        r = rows[:, None]
        self.Q[r, qadr], self.V[r, dadr] = q, v
        self._qfrc[0][r, dadr] = fb
        if gravcomp:
            self._qfrc[1][r, dadr] = fg

    def _observation(self, feats: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The rows' observations, with the problem's features ``feats`` of the same state."""
        T = self.T_psm
        cartesian = self.config.action_space == "cartesian"
        obs = {
            "joint_position": self.Q[:, self.psm_q].copy(),
            "joint_velocity": self.V[:, self.psm_v].copy(),
            "jaw": self.Q[:, self.jaw_q].sum(axis=1, keepdims=True),
            "tip_position": T[:, :3, 3].copy(),
            "tip_orientation": orientation_features(T[:, :3, :3]),
            "setpoint": (self.goal if cartesian else self.q_goal).copy(),
        }
        obs.update(feats)
        return obs
