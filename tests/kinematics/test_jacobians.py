"""Spatial and body Jacobians against central finite differences of the FK."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.fk import forward_kinematics, jacobian_body, jacobian_spatial

CHAINS = {name: load_arm(name).chain for name in ("PSM1", "ECM", "MTML", "MTMR")}
CHAINS |= {f"SUJ/{k}": v.chain for k, v in load_suj().items()}
H = 1e-6  # central differences: truncation ~H², rounding ~1e-16/H; both < 1e-9


def _log(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_rotvec()


def _finite_difference(chain, q):
    """(spatial, body) 6xn Jacobians by central differences of position and rotation."""
    Js, Jb = np.zeros((6, chain.dof)), np.zeros((6, chain.dof))
    R = forward_kinematics(chain, q)[:3, :3]
    for i in range(chain.dof):
        dq = np.zeros(chain.dof)
        dq[i] = H
        Tp, Tm = forward_kinematics(chain, q + dq), forward_kinematics(chain, q - dq)
        v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * H)
        Js[:3, i] = v
        Js[3:, i] = _log(Tp[:3, :3] @ Tm[:3, :3].T) / (2 * H)  # base-frame angular velocity
        Jb[:3, i] = R.T @ v
        Jb[3:, i] = _log(Tm[:3, :3].T @ Tp[:3, :3]) / (2 * H)  # tip-frame angular velocity
    return Js, Jb


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_jacobians_match_finite_differences(name, rng):
    chain = CHAINS[name]
    for q in rng.uniform(chain.qmin, chain.qmax, size=(10, chain.dof)):
        Js_fd, Jb_fd = _finite_difference(chain, q)
        np.testing.assert_allclose(jacobian_spatial(chain, q), Js_fd, rtol=0, atol=1e-8)
        np.testing.assert_allclose(jacobian_body(chain, q), Jb_fd, rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_batched_jacobians_equal_single(name, rng):
    chain = CHAINS[name]
    Q = rng.uniform(chain.qmin, chain.qmax, size=(4, 5, chain.dof))
    Js, Jb = jacobian_spatial(chain, Q), jacobian_body(chain, Q)
    assert Js.shape == Jb.shape == (4, 5, 6, chain.dof)
    for idx in np.ndindex(4, 5):
        np.testing.assert_allclose(Js[idx], jacobian_spatial(chain, Q[idx]), atol=1e-14)
        np.testing.assert_allclose(Jb[idx], jacobian_body(chain, Q[idx]), atol=1e-14)
