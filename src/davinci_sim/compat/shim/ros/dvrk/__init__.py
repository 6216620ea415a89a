"""dvrk_python's ``dvrk`` API for scripts run against davinci-sim (``davinci-sim run``).

The implementation is :mod:`davinci_sim.compat.dvrk_api`; see there.
"""

from davinci_sim.compat.dvrk_api import arm, console, ecm, mtm, psm, suj, system, teleop_psm

__all__ = ["arm", "console", "ecm", "mtm", "psm", "suj", "system", "teleop_psm"]
