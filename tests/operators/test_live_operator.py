"""Watching a synthetic trainee on the live console: one of the study's trainees takes the
MTM, does a repetition of the task through the console, and lets go."""

from pathlib import Path

import numpy as np
import pytest

from davinci_sim.geometry.so3 import rotation_vector
from davinci_sim.system import ConsoleDescription, SystemDescription, TaskDescription
from davinci_sim.system.build import build_simulation

#: A 3-cm path near where PSM1 homes (the seed's path would take ~4x the simulated time);
#: the same carrying a torus, the wrist turning along it.
SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")
CARRY_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_carry.yaml")


@pytest.fixture(scope="module", params=[SHORT_TASK, CARRY_TASK], ids=["plain", "carried"])
def live(request):
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        home=True,
        runner="none",
        task=TaskDescription(request.param),
        console=ConsoleDescription(
            hand_inputs=("MTMR",), operator_present=True, teleop_enabled=True
        ),
    )
    sim = build_simulation(description)
    yield sim
    sim.close()


def test_a_synthetic_trainee_does_one_repetition_and_lets_go(live):
    sim = live
    operator, session = sim.components["synthetic"], sim.components["task"]
    device = sim.components["MTMR/device"]
    own = device.hand
    assert operator.start(subject=3, practice=5)
    assert operator.snapshot()["running"] and device.hand != own  # the subject's impedance
    phases = set()
    end = sim.time + 40.0
    turned, R0 = 0.0, None
    while operator.running and sim.time < end:
        sim.run_for(0.05)
        phases.add(session.snapshot().phase)
        target = device.hand_target()
        if target is not None:  # the hand's target orientation, from when it took the handle
            R0 = target[:3, :3].copy() if R0 is None else R0
            turned = max(turned, np.linalg.norm(rotation_vector(target[:3, :3] @ R0.T)))
    assert not operator.running, "the trainee did not finish within 40 s"
    assert {"READY", "RUNNING"} <= phases
    assert len(session.results) == 1
    row = session.results[0]
    assert row["condition"] == session.condition
    assert 0 < row["deviation_error"] < 0.005
    assert device.hand == own and device.hand_target() is None  # let go, own hand back
    # a carried object's task: the hand turned the handle (0.5 rad over the whole path)
    carried = getattr(session.task, "carry", None) is not None
    assert (turned > 0.3) == carried and turned < 0.55


@pytest.mark.parametrize(
    "kwargs, words",
    [({"subject": -1}, "subject"), ({"subject": 10_000}, "subject"),
     ({"subject": 1.5}, "integer"), ({"practice": 0}, "practice")],
)  # fmt: skip
def test_bad_trainee_requests_are_refused(live, kwargs, words):
    operator = live.components["synthetic"]
    result = operator.start(**kwargs)
    assert not result and words in result.message and not operator.running


def test_the_synthetic_operator_is_installed_before_the_device(live):
    names = list(live.components)
    assert names.index("synthetic") < names.index("MTMR/device")
    assert np.isfinite(live.time)
