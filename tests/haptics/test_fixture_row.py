"""The seed's viscous fixture as one compiled row (``haptics/fixture_row.py``) against the
fixture field's Python path, its oracle: the same bits, tick after tick, filter included."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.geometry import so3
from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.field import HapticState
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.kinematics import jit

ARC = Polyline(
    np.stack([[0.03 * np.cos(a), 0.03 * np.sin(a), 0.002 * a] for a in np.linspace(0, 3, 40)])
)


def _states(n: int, seed: int):
    """n haptic states of a tip wandering near the arc, seen from a tilted camera."""
    rng = np.random.default_rng(seed)
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = so3.rotation_from_vector([0.3, -0.2, 0.5])
    T_world_camera[:3, 3] = [0.01, -0.02, 0.1]
    p_world = np.array([0.03, 0.0, 0.0])
    for _ in range(n):
        p_world = p_world + rng.normal(0.0, 2e-4, 3)
        T = np.eye(4)
        T[:3, 3] = T_world_camera[:3, :3].T @ (p_world - T_world_camera[:3, 3])
        yield HapticState.from_values(
            T_camera_tip=T, twist_camera_tip=np.zeros(6), T_world_camera=T_world_camera
        )


@pytest.mark.parametrize("summed", [False, True])
def test_the_compiled_field_is_the_python_field_bit_for_bit(summed):
    law = ViscousGuidance(ARC, B=40.0, G_max=3.0)
    fixture = combine(law) if summed else law
    compiled, python = FixtureField(fixture), FixtureField(fixture)
    python._row = None  # (the Python path)
    for k, state in enumerate(_states(300, seed=1)):
        f_c, f_p = compiled(state), python(state)
        np.testing.assert_array_equal(f_c, f_p)
        if k == 150:  # a restored filter goes on the same
            compiled.set_state(python.get_state())
    assert (compiled._row is not None) == jit.ENABLED
    assert np.abs(f_p).max() > 0.1  # the fixture pushed


def test_fixtures_with_no_compiled_form_keep_the_python_path():
    two = combine(ViscousGuidance(ARC, B=40.0, G_max=3.0), SpringGuidance(ARC, stiffness=100.0))
    for field in (
        FixtureField(two),
        FixtureField(ViscousGuidance(ARC, B=40.0, G_max=3.0), frame="camera"),
        FixtureField(ViscousGuidance(ARC, B=40.0, G_max=3.0), velocity="measured"),
    ):
        field(next(_states(1, seed=2)))
        assert field._row is None
