"""The fixtures' compiled rows (``haptics/fixture_row.py``) against the fixture field's Python
path, their oracle: the seed's viscous law the same bits, tick after tick, filter included;
Rota's viscous-elastic law within 1e-12 N (its ``exp`` is libm's, numpy's differs in the last
bit)."""

from __future__ import annotations

import numpy as np
import pytest
from haptic_states import ARC, states

from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.haptics.viscous_elastic import ViscousElasticGuidance, viscous_elastic_guidance
from davinci_sim.kinematics import jit


@pytest.mark.parametrize("summed", [False, True])
def test_the_compiled_field_is_the_python_field_bit_for_bit(summed):
    law = ViscousGuidance(ARC, B=40.0, G_max=3.0)
    fixture = combine(law) if summed else law
    compiled, python = FixtureField(fixture), FixtureField(fixture)
    python._row = None  # (the Python path)
    for k, state in enumerate(states(300, seed=1)):
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
        field(next(states(1, seed=2)))
        assert field._row is None


@pytest.mark.parametrize("summed", [False, True])
def test_rotas_viscous_elastic_field_compiled_is_its_numpy_law(summed):
    """Rota's fixture (viscous uncapped, the logistic elastic pull, the sum capped at 3 N,
    then scaled) as the compiled row against its numpy law, the oracle: within 1e-12 N over
    a tip wandering up to ~8 mm off the path (the pull from nothing to nearly its gain),
    filter included; the elastic part and the cap both act."""
    law = ViscousElasticGuidance(ARC, B=15.0, elastic_gain=0.8, threshold=0.002, half=0.002,
                                 slope=500.0, max_force=3.0, assistance=0.5)  # fmt: skip
    fixture = combine(law) if summed else law
    compiled, python = FixtureField(fixture), FixtureField(fixture)
    python._row = None  # (the numpy path)
    forces = []
    for k, state in enumerate(states(400, seed=3, spread=4e-4)):
        f_c, f_p = compiled(state), python(state)
        np.testing.assert_allclose(f_c, f_p, rtol=0, atol=1e-12)
        forces.append(np.linalg.norm(f_p))
        if k == 200:  # a restored filter goes on the same
            compiled.set_state(python.get_state())
    assert (compiled._row is not None) == jit.ENABLED
    assert max(forces) > 0.3  # the elastic pull (0.8 N x 0.5 far off the path)


def test_rotas_law_caps_the_sum_then_scales_it():
    """The cap on the sum, then the assistance: a fast tip far off the path gets exactly
    max_force x assistance, in both forms."""
    from davinci_sim.haptics import fixture_row

    elastic = np.array([0.8, 0.002, 0.002, 500.0, 3.0, 0.25])
    out = np.empty(3)
    v, phi = np.array([2.0, 0.0, 0.0]), np.array([0.0, 0.02, 0.0])
    fixture_row._viscous_elastic_into(v, phi, 40.0, elastic, out)  # (a helper: plain Python)
    assert np.linalg.norm(out) == pytest.approx(3.0 * 0.25, rel=1e-12)
    numpy_law = viscous_elastic_guidance(v, phi, B=40.0, elastic_gain=0.8, threshold=0.002,
                                         half=0.002, slope=500.0, max_force=3.0,
                                         assistance=0.25)  # fmt: skip
    np.testing.assert_allclose(out, numpy_law, rtol=0, atol=1e-12)


def test_a_spring_field_compiled_is_its_numpy_law():
    """The spring (pull k·φ, damping across the path, capped) as the compiled row against
    its numpy law within 1e-12 N, a sum of one too; the cap acts."""
    spring = SpringGuidance(ARC, stiffness=300.0, damping=2.0, max_force=1.0)
    for fixture in (spring, combine(spring)):
        compiled, python = FixtureField(fixture), FixtureField(fixture)
        python._row = None
        forces = []
        for state in states(300, seed=4, spread=4e-4):
            f_c, f_p = compiled(state), python(state)
            np.testing.assert_allclose(f_c, f_p, rtol=0, atol=1e-12)
            forces.append(np.linalg.norm(f_p))
        assert (compiled._row is not None) == jit.ENABLED
        assert max(forces) == pytest.approx(1.0, abs=1e-9)  # capped
