import pytest

from davinci_sim.sim.simulation import Simulation


def home(sim, arms=None, timeout=20.0):
    names = arms or list(sim.arms)
    for n in names:
        assert sim.arms[n].state_command("enable")
        assert sim.arms[n].state_command("home")
    ok = sim.run_until(
        lambda: all(sim.arms[n].is_homed() and not sim.arms[n].is_busy() for n in names), timeout
    )
    assert ok, "homing did not finish"
    return sim


@pytest.fixture
def psm_sim():
    """PSM1 + ECM (+ their SUJ arms), enabled and homed."""
    sim = Simulation("psm1")
    home(sim)
    yield sim
    sim.close()
