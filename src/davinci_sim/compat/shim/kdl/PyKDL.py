"""``import PyKDL`` for davinci-sim scripts when the real PyKDL is not on the import path.

If the system has a real PyKDL this interpreter can load (:mod:`davinci_sim.compat.pykdl`:
Debian's ``python3-pykdl``, a ROS installation), this module *becomes* it; otherwise it is
the subset :mod:`davinci_sim.compat.kdl`, which behaves the same for what it covers.
"""

import sys

from davinci_sim.compat import pykdl as _pykdl

_real = _pykdl.load()
if _real is not None:
    sys.modules[__name__] = _real
else:
    from davinci_sim.compat.kdl import *  # noqa: F403
    from davinci_sim.compat.kdl import __all__  # noqa: F401
