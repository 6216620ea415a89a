"""A synthetic trainee on the live console, on demand: "watch a synthetic trainee".

:class:`SyntheticOperator` is a simulation component of a training session
(:class:`~davinci_sim.tasks.session.TaskSession`) that, when told to :meth:`~SyntheticOperator.
start`, puts one of the study's synthetic trainees (:class:`~davinci_sim.operators.
SyntheticTrainee`, subject ``subject`` of the study's population for ``seed``, at practice
count ``practice``) at the session's MTM: the trainee's hand takes the handle and does the
task (reach for point 1, then follow the path) through the same device → console →
teleoperation path and the same fixture as a person, so a visitor sees the guidance act
without any hardware. The trainee lets go when done or told to :meth:`~SyntheticOperator.stop`;
the device's own hand impedance comes back.
"""

from __future__ import annotations

import copy

import numpy as np

from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.operators.console import TraineeHand, hand_impedance
from davinci_sim.operators.params import sample_subjects
from davinci_sim.operators.trainee import SyntheticTrainee, TraineePhase
from davinci_sim.operators.wrist import WristTurns
from davinci_sim.sim.types import ACCEPTED, CommandResult

#: How long a trainee whose plan has ended waits for the session's row before letting go, s.
DONE_WAIT = 3.0
#: Names of the trainee's phases (TraineePhase's values).
PHASES = {TraineePhase.WAITING: "WAITING", TraineePhase.TO_START: "TO_START",
          TraineePhase.FOLLOWING: "FOLLOWING", TraineePhase.DONE: "DONE"}  # fmt: skip
#: Largest subject index a page may ask for (the population is sampled up to it).
MAX_SUBJECT = 999


class SyntheticOperator:
    """Runs a synthetic trainee on ``session``'s MTM on demand; see the module docstring.

    Args:
        session: the training session (its task, teleoperation and simulation).
        device: the simulated MTM of the session's teleoperation.
        seed: the study seed the trainees are sampled with.
        name: component name.
    """

    def __init__(self, session, device: SimulatedMTM, *, seed: int = 0, name: str = "synthetic"):
        self.session = session
        self.device = device
        self.seed = int(seed)
        self.name = name
        self._hand: TraineeHand | None = None
        self._own_hand = device.hand
        self.subject = 0
        self.practice = 1
        self._rows = 0
        self._done_at: float | None = None

    # ------------------------------------------------------------ commands
    def start(self, subject: int = 0, practice: int = 1) -> CommandResult:
        """Subject ``subject`` (0 … 999) takes the handle, at practice count ``practice``
        (≥ 1; 1: a first attempt)."""
        if isinstance(subject, bool) or not isinstance(subject, int):
            return CommandResult(False, f"{self.name}: subject must be an integer")
        if not 0 <= subject <= MAX_SUBJECT:
            return CommandResult(False, f"{self.name}: subject must be in 0..{MAX_SUBJECT}")
        if isinstance(practice, bool) or not isinstance(practice, int) or practice < 1:
            return CommandResult(False, f"{self.name}: practice must be an integer >= 1")
        task, sim = self.session.task, self.session.sim
        if not hasattr(task, "path_in_camera"):  # the trainee model follows a path
            return CommandResult(False, f"{self.name}: a synthetic trainee follows a path; "
                                        f"the {task.kind} exercise has none")  # fmt: skip
        params = sample_subjects(subject + 1, seed=self.seed).take([subject])
        trainee = SyntheticTrainee(
            params,
            repetition=[practice],
            path=task.path_in_camera(sim.T_cart_camera()),
            knots=task.marker_arc_lengths,
            hand_start=np.zeros((1, 3)),
            scale=task.teleop.scale,
            start_tolerance=task.start_tolerance,
            noise_keys=[(self.seed, subject, 1000, practice)],  # not a study trial's key
            wrist=WristTurns.of(
                getattr(task, "carry", None), task.T_task_camera(sim.T_cart_camera())
            ),  # fmt: skip
        )
        if self._hand is not None:
            self.stop()
        self.device.release()
        self.device.hand = hand_impedance(params)
        self._hand = TraineeHand(trainee, self.device, self.session.teleop.psm,
                                 when=self.session.teleop.is_following)  # fmt: skip
        self.subject, self.practice = subject, practice
        self._rows = len(self.session.results)
        self._done_at = None
        self.session.reset()
        return ACCEPTED

    def stop(self) -> CommandResult:
        """The trainee lets go (nothing happens if none runs)."""
        if self._hand is not None:
            self._hand = None
            self.device.release()
            self.device.hand = self._own_hand
        return ACCEPTED

    @property
    def running(self) -> bool:
        return self._hand is not None

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        hand = self._hand
        if hand is None:
            return
        hand.pre_step(t)
        # Done when the session has the repetition's row, or the plan ended DONE_WAIT ago
        # (a trainee who did not get there gives up).
        if len(self.session.results) > self._rows:
            self.stop()
        elif hand.started and int(hand.trainee.phase[0]) == TraineePhase.DONE:
            self._done_at = t if self._done_at is None else self._done_at
            if t - self._done_at > DONE_WAIT:
                self.stop()

    def chunk_part(self):
        """Idle for the console's compiled ticks (:mod:`davinci_sim.console.chunk`) while
        no trainee's hand moves; None (Python's ticks) while one does."""
        from davinci_sim.console.chunk import IDLE

        return IDLE if self._hand is None else None

    def snapshot(self) -> dict:
        hand = self._hand
        phase = None
        if hand is not None and hand.started:
            phase = PHASES[int(hand.trainee.phase[0])]
        return {
            "running": hand is not None,
            "subject": self.subject,
            "practice": self.practice,
            "phase": phase,
        }

    def get_state(self) -> dict:
        """Which trainee runs (deep-copied with its trainee's state) and its subject."""
        hand = self._hand
        return {
            "hand": None if hand is None else {**hand.get_state(), "psm": hand.psm.name},
            "subject": self.subject,
            "practice": self.practice,
            "rows": self._rows,
            "done_at": self._done_at,
            "device_hand": self.device.hand,
        }

    def set_state(self, state: dict) -> None:
        self.subject, self.practice = state["subject"], state["practice"]
        self._rows, self._done_at = state["rows"], state["done_at"]
        saved = state["hand"]
        if saved is None:
            self._hand = None
        else:
            trainee = copy.deepcopy(saved["trainee"])
            self._hand = TraineeHand(trainee, self.device, self.session.teleop.psm,
                                     when=self.session.teleop.is_following)  # fmt: skip
            self._hand.set_state({k: saved[k] for k in ("started", "trainee")})
        self.device.hand = state["device_hand"]
