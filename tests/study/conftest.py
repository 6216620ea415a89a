from pathlib import Path

import pytest

#: A short task (tests/study/short_path.yaml): a trial takes ~3 s instead of the seed
#: task's ~30 s, so that a 16-trial study fits in the suite.
SHORT_TASK = str(Path(__file__).with_name("short_path.yaml"))


@pytest.fixture(scope="session")
def short_task() -> str:
    return SHORT_TASK


#: The short task with a carried torus and the wrist turning along it (short_carry.yaml).
CARRY_TASK = str(Path(__file__).with_name("short_carry.yaml"))


@pytest.fixture(scope="session")
def carry_task() -> str:
    return CARRY_TASK
