"""The component contract: explicit tick order, unique names, a read-only registry."""

from __future__ import annotations

import pytest

from davinci_sim.sim.component import Component
from davinci_sim.sim.simulation import Simulation


class Probe:
    """Records the order in which components run."""

    def __init__(self, name: str, log: list) -> None:
        self.name, self.log = name, log
        self.value = 0

    def pre_step(self, t: float) -> None:
        self.log.append(("pre", self.name))

    def post_step(self, t: float) -> None:
        self.log.append(("post", self.name))

    def snapshot(self) -> int:
        return self.value

    def get_state(self) -> int:
        return self.value

    def set_state(self, state: int) -> None:
        self.value = state


@pytest.fixture(scope="module")
def sim():
    return Simulation("psm1")


def _fresh(sim):
    for name in list(sim.components):
        sim.remove_component(name)
    return sim


def test_components_tick_in_the_order_placed(sim):
    sim, log = _fresh(sim), []
    a, b, c, d = (Probe(n, log) for n in "abcd")
    sim.add_component(a)
    sim.add_component(c)
    sim.add_component(b, before="c")
    sim.add_component(d, after="a")
    assert list(sim.components) == ["a", "d", "b", "c"]
    assert isinstance(a, Component)
    sim.tick()
    assert log == [("pre", n) for n in "adbc"] + [("post", n) for n in "adbc"]
    assert sim.remove_component("d") is d
    log.clear()
    sim.tick()
    assert [n for _, n in log] == ["a", "b", "c"] * 2


def test_names_are_unique_and_places_must_exist(sim):
    sim, log = _fresh(sim), []
    sim.add_component(Probe("a", log))
    with pytest.raises(ValueError, match="'a' is already registered"):
        sim.add_component(Probe("a", log))
    with pytest.raises(KeyError, match="no component 'x' to go before"):
        sim.add_component(Probe("b", log), before="x")
    with pytest.raises(ValueError, match="not both"):
        sim.add_component(Probe("b", log), before="a", after="a")
    with pytest.raises(KeyError, match="no component 'b'"):
        sim.remove_component("b")
    assert list(sim.components) == ["a"]


def test_what_every_tick_needs_is_checked(sim):
    sim = _fresh(sim)

    class NoSnapshot:
        name = "n"

        def pre_step(self, t):
            pass

    with pytest.raises(TypeError, match="no snapshot"):
        sim.add_component(NoSnapshot())
    with pytest.raises(TypeError, match="non-empty str name"):
        sim.add_component(object())


def test_the_registry_is_read_only(sim):
    sim = _fresh(sim)
    with pytest.raises(TypeError):
        sim.components["a"] = Probe("a", [])  # type: ignore[index]
    with pytest.raises(AttributeError):
        sim.components = {}  # type: ignore[misc]


def test_component_state_is_saved_and_restored_and_needed(sim):
    sim, log = _fresh(sim), []
    probe = Probe("a", log)
    sim.add_component(probe)
    probe.value = 7
    state = sim.get_state()
    probe.value = 9
    sim.set_state(state)
    assert probe.value == 7

    class Stateless(Probe):
        get_state = None  # type: ignore[assignment]

    sim.add_component(Stateless("s", log))
    with pytest.raises(TypeError, match="'s' .* has no get_state"):
        sim.get_state()
