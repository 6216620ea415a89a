"""A user's own guidance law compiled (``haptics/compiled_law.py``): the fixture row calls it
through its C callback; the same function run by Python on each row is its oracle."""

from __future__ import annotations

import numpy as np
import pytest
from haptic_states import ARC, states

from davinci_sim.haptics import fixture_row
from davinci_sim.haptics.compiled_law import UserLawGuidance, compiled_law
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.kinematics import jit

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="numba is off")


def pull(v, phi, params, out):
    """k·φ − c·v, N (a spring to the path and a damper on every motion)."""
    for i in range(3):
        out[i] = params[0] * phi[i] - params[1] * v[i]


PULL = compiled_law(pull)


def test_the_compiled_user_law_is_its_python_function():
    fixture = UserLawGuidance(ARC, PULL, (300.0, 2.0))
    compiled, python = FixtureField(fixture), FixtureField(fixture)
    python._row = None  # (the law run by Python, row by row)
    assert compiled.compiled_row()[6] == fixture_row.USER
    forces = []
    for state in states(300, seed=5, spread=4e-4):
        f_c, f_p = compiled(state), python(state)
        np.testing.assert_allclose(f_c, f_p, rtol=0, atol=1e-12)
        forces.append(np.linalg.norm(f_p))
    assert max(forces) > 0.1  # it pulled


def test_a_law_numba_cannot_compile_is_refused_with_the_reason():
    def bad(v, phi, params, out):
        out[0] = {"k": params[0]}["k"] * object()

    with pytest.raises(TypeError, match="numba cannot compile bad"):
        compiled_law(bad)


def test_parameters_are_checked():
    arc = ARC
    with pytest.raises(ValueError, match="at most 6"):
        UserLawGuidance(arc, PULL, tuple(range(7)))
    with pytest.raises(ValueError, match="finite"):
        UserLawGuidance(arc, PULL, (float("nan"),))
    with pytest.raises(TypeError, match="compiled_law"):
        UserLawGuidance(arc, pull, ())  # type: ignore[arg-type]
    assert list(UserLawGuidance(arc, PULL, (1.0, 2.0)).parameters) == [1, 2, 0, 0, 0, 0]
