"""An observer of the simulated arms for the tests that replay upstream examples: it samples
their measured tip positions on its own thread, so that a test checks the motion an example
commanded, not the example's exit."""

from __future__ import annotations

import threading
import time

import numpy as np


class Observer:
    """Samples the simulated ``arms``' measured tip positions (m, in their reference frames:
    HRSV for an MTM, the camera for a PSM, as their ``measured_cp``) with the sim time; with
    ``pose="setpoint_cp"`` their setpoints instead (the goals as the arm took them, whatever
    its tracking lag on a machine too busy for the simulation to keep the example's pace)."""

    def __init__(self, handle, arms=("PSM1",), pose: str = "measured_cp") -> None:
        self._handle = handle
        self._arms = tuple(arms)
        self._pose = pose
        self.samples: list[tuple[float, dict[str, np.ndarray]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            s = self._handle.snapshot()
            poses = {a: getattr(s.arms[a], self._pose).T[:3, 3].copy() for a in self._arms}
            self.samples.append((s.time, poses))
            time.sleep(0.002)

    def __enter__(self) -> Observer:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(5.0)

    def positions(self, arm: str = "PSM1") -> list[np.ndarray]:
        """Every sampled position of ``arm``, in order."""
        return [p[arm] for _, p in self.samples]

    def wait_near(self, point: np.ndarray, tolerance: float, arm: str = "PSM1",
                  timeout_s: float = 30.0) -> None:  # fmt: skip
        """Wait until ``arm``'s sampled position is within ``tolerance`` (m) of ``point``:
        an example's last goal may still be on its way when it returns (a loaded machine
        runs the simulation slower than the example's wall-clock pause), so a test waits
        for the motion, not for a time; after ``timeout_s`` of wall time it stops waiting
        (the check that follows then says what was reached)."""
        end = time.monotonic() + timeout_s
        while np.linalg.norm(self.now(arm) - point) >= tolerance:
            if time.monotonic() > end:
                return
            time.sleep(0.01)

    def now(self, arm: str) -> np.ndarray:
        while not self.samples:
            time.sleep(0.002)
        return self.samples[-1][1][arm]

    def between(self, arm: str, t0: float, t1: float) -> np.ndarray:
        """The positions of ``arm`` sampled at sim times t0 <= t <= t1, (n, 3)."""
        return np.array([p[arm] for t, p in self.samples if t0 <= t <= t1])

    def visited_in_order(self, *points: np.ndarray, tolerance: float, arm: str = "PSM1"):
        """The sample indices at which ``arm`` came within ``tolerance`` (m) of each of
        ``points`` in turn (an assertion error names the first one never reached)."""
        positions = self.positions(arm)
        found, start = [], 0
        for k, point in enumerate(points):
            distances = [np.linalg.norm(p - point) for p in positions[start:]]
            near = [i for i, d in enumerate(distances) if d < tolerance]
            closest = min(distances) if distances else float("nan")
            assert near, f"point {k} {point} never reached (closest {closest * 1e3:.1f} mm)"
            start += near[0]
            found.append(start)
        return found
