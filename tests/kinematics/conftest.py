"""Shared fixtures of the kinematics tests."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.kinematics.arms import ArmKinematics, load_arm


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240611)


@pytest.fixture(scope="session")
def psm() -> ArmKinematics:
    return load_arm("PSM1")


@pytest.fixture(scope="session")
def ecm() -> ArmKinematics:
    return load_arm("ECM")
