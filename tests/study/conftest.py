from pathlib import Path

import pytest

#: A short task (tests/study/short_path.yaml): a trial takes ~3 s instead of the seed
#: task's ~30 s, so that a 16-trial study fits in the suite.
SHORT_TASK = str(Path(__file__).with_name("short_path.yaml"))


@pytest.fixture(scope="session")
def short_task() -> str:
    return SHORT_TASK
