"""Batched FK and frames equal the single-configuration path and a plain 4x4-product oracle."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.fk import (
    fk_tuple,
    forward_kinematics,
    forward_kinematics_matmul,
    joint_frames,
    link_transforms,
)

CHAINS = {name: load_arm(name).chain for name in ("PSM1", "ECM", "MTML", "MTMR")}
CHAINS |= {f"SUJ/{k}": v.chain for k, v in load_suj().items()}


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_batched_equals_oracle_and_single(name, rng):
    chain = CHAINS[name]
    Q = rng.uniform(chain.qmin, chain.qmax, size=(20_000, chain.dof))  # > 1 chunk
    T = forward_kinematics(chain, Q)
    np.testing.assert_allclose(T, forward_kinematics_matmul(chain, Q), rtol=0, atol=1e-12)
    single = np.array([forward_kinematics(chain, q) for q in Q[:100]])
    np.testing.assert_allclose(single, T[:100], rtol=0, atol=1e-12)
    f = fk_tuple(chain, Q[0].tolist())
    np.testing.assert_allclose(np.reshape(f[:9], (3, 3)), T[0, :3, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(f[9:], T[0, :3, 3], rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", ["PSM1", "MTMR", "ECM"])
def test_truncated_chains_and_frames(name, rng):
    chain = CHAINS[name]
    Q = rng.uniform(chain.qmin, chain.qmax, size=(50, chain.dof))
    F = joint_frames(chain, Q)
    np.testing.assert_allclose(F, [joint_frames(chain, q) for q in Q], rtol=0, atol=1e-12)
    for n in range(chain.dof + 1):
        sub = chain.truncated(n)
        np.testing.assert_allclose(forward_kinematics(sub, Q[:, :n]), F[:, n], rtol=0, atol=1e-12)
        np.testing.assert_allclose(forward_kinematics(sub, Q[0, :n]), F[0, n], atol=1e-12)


def test_batch_shapes_and_validation():
    chain = CHAINS["PSM1"]
    assert forward_kinematics(chain, np.zeros((2, 3, 6))).shape == (2, 3, 4, 4)
    assert forward_kinematics(chain, np.zeros((0, 6))).shape == (0, 4, 4)
    assert link_transforms(chain, np.zeros((5, 6))).shape == (5, 6, 4, 4)
    with pytest.raises(ValueError, match="last dimension 6"):
        forward_kinematics(chain, np.zeros(5))
    with pytest.raises(ValueError, match="last dimension 6"):
        forward_kinematics(chain, 0.0)


@settings(max_examples=50, deadline=None)
@given(
    name=st.sampled_from(sorted(CHAINS)),
    q=arrays(float, 7, elements=st.floats(-10.0, 10.0, allow_nan=False)),
)
def test_any_joint_values_agree(name, q):
    """Outside the limits too: the fast paths are pure algebra, not limit-dependent."""
    chain = CHAINS[name]
    q = q[: chain.dof]
    oracle = forward_kinematics_matmul(chain, q)
    np.testing.assert_allclose(forward_kinematics(chain, q), oracle, rtol=0, atol=1e-12)
    np.testing.assert_allclose(forward_kinematics(chain, q[None])[0], oracle, atol=1e-12)
