import pytest
from sim_helpers import home

from davinci_sim.sim.simulation import Simulation


@pytest.fixture
def psm_sim():
    """PSM1 + ECM (+ their SUJ arms), enabled and homed."""
    sim = Simulation("psm1")
    home(sim)
    yield sim
    sim.close()
