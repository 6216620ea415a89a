"""dVRK-exact kinematics: DH chains, FK, Jacobians, IK and the SUJ frame chain (pure numpy)."""
