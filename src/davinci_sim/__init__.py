"""davinci-sim: a Python simulator of the da Vinci Research Kit (dVRK).

Packages, one concept each (see ``docs/architecture.md``):

* :mod:`davinci_sim.kinematics`: dVRK-exact DH kinematics, pure numpy.
* :mod:`davinci_sim.model`: procedural MuJoCo model of the whole system.
* :mod:`davinci_sim.sim`: physics, joint servos and the dVRK/CRTK arm API.
"""

import os

# Headless by default: MuJoCo renders offscreen through EGL (Mesa's llvmpipe on a machine
# with no GPU). A user who has set MUJOCO_GL keeps their choice.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
