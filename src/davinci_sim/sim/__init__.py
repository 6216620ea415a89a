"""Simulation core: physics at 1 kHz, joint servos and the dVRK/CRTK arm API."""
