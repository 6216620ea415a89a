"""Helpers shared by the simulation tests."""


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
