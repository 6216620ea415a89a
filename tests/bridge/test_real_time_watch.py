"""``serve`` says once when the simulation cannot keep real time (issue 11, 2)."""

from davinci_sim.bridge.app import RealTimeWatch


def feed(watch, factor, seconds, start=(0.0, 0.0), step=0.1):
    """Observe ``seconds`` of wall time at ``factor`` x real time; the warnings said."""
    said = []
    wall, sim = start
    for _ in range(int(round(seconds / step))):
        wall += step
        sim += factor * step
        text = watch.observe(wall, sim)
        if text is not None:
            said.append(text)
    return said, (wall, sim)


def test_a_slow_simulation_is_reported_once_with_its_factor():
    watch = RealTimeWatch(window=5.0)
    said, at = feed(watch, 0.7, 30.0)
    assert len(said) == 1 and "0.70x real time" in said[0]
    said, _ = feed(watch, 0.5, 30.0, start=at)
    assert said == []  # once


def test_real_time_and_a_slow_start_up_say_nothing():
    watch = RealTimeWatch(window=5.0)
    said, at = feed(watch, 0.3, 5.2)  # start-up (models, render process) is not judged
    said2, _ = feed(watch, 0.99, 30.0, start=at)
    assert said == [] and said2 == []
