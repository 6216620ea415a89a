"""A PyKDL subset for davinci-sim scripts, used only when the real PyKDL is not installed.

The implementation and what it covers: :mod:`davinci_sim.compat.kdl`.
"""

from davinci_sim.compat.kdl import *  # noqa: F403
from davinci_sim.compat.kdl import __all__  # noqa: F401
