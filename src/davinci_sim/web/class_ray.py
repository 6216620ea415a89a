"""A class that outgrows one machine: each trainee's system a Ray actor on a Ray cluster.

:class:`RaySystems` is the class's systems' side (``davinci-sim class --ray ADDRESS``): one
actor per trainee, placed by Ray over the cluster's nodes (``SPREAD``, ``cpus_per_trainee``
CPUs reserved each, so a node holds only the systems its cores can run), each starting the
trainee's ``serve`` process on its node as :mod:`~davinci_sim.web.classroom` does on one
machine. The lobby (:class:`~davinci_sim.web.classroom.Classroom`) stays where it was
started and links each trainee to their console at their node's address; a system waiting
for a node to have room says so in the lobby.

Ray is the engine already used for studies and environments that outgrow one machine; it
is optional here too (``pip install davinci-sim[ray]``). The nodes need the same
installation (Ray's own rule); the token reaches each system through Ray's task arguments
and then the system's environment, never its command line.
"""

from __future__ import annotations

import os

from davinci_sim.web.classroom import (
    ClassOptions,
    TraineeSystem,
    interrupt,
    start_system,
    wait_stopped,
)
from davinci_sim.web.hosts import binds_everywhere

#: How long the lobby waits for an actor's status before showing it as not yet placed, s.
STATUS_WAIT_S = 5.0


class TraineeActor:
    """One trainee's system on the Ray node this actor was placed on (a Ray actor class)."""

    def __init__(self, options: ClassOptions, k: int, token: str | None) -> None:
        import ray

        env = dict(os.environ)  # (the node's own environment, not the lobby machine's)
        if token is not None:
            env["DAVINCI_SIM_TOKEN"] = token
        # Bound to every interface, the console is reached at the node's address.
        shown = ray.util.get_node_ip_address() if binds_everywhere(options.host) else None
        self.system: TraineeSystem = start_system(options, k, env, shown_host=shown)
        self.system.node = ray.get_runtime_context().get_node_id()

    def status(self) -> dict:
        return self.system.status()

    def stop(self, timeout: float) -> dict:
        interrupt([self.system])
        wait_stopped([self.system], timeout)
        return self.system.status()


class RaySystems:
    """The class's systems as Ray actors (the ``systems`` of a ``Classroom``)."""

    def __init__(self, options: ClassOptions) -> None:
        if options.ray_address is None:
            raise ValueError("RaySystems needs options.ray_address")
        self.options = options
        self.actors: list = []
        self._final: list[dict] | None = None
        self._connected = False

    def start(self) -> None:
        import ray

        if not ray.is_initialized():
            ray.init(address=self.options.ray_address, log_to_driver=False)
            self._connected = True
        actor = ray.remote(
            num_cpus=self.options.cpus_per_trainee, scheduling_strategy="SPREAD", max_restarts=0
        )(TraineeActor)
        token = self.options.token
        self.actors = [actor.remote(self.options, k, token)
                       for k in range(len(self.options.trainees))]  # fmt: skip

    def status(self) -> list[dict]:
        if self._final is not None:
            return self._final
        import ray

        refs = [a.status.remote() for a in self.actors]
        done, _ = ray.wait(refs, num_returns=len(refs), timeout=STATUS_WAIT_S)
        return [self._answer(k, ref, ref in done) for k, ref in enumerate(refs)]

    def _answer(self, k: int, ref, done: bool) -> dict:
        import ray

        name, port = self.options.trainees[k], self.options.port + 1 + k
        blank = {"name": name, "port": port, "url": None, "notes": [], "node": None}
        if not done:
            return {**blank, "state": "waiting for a Ray node with room"}
        try:
            return ray.get(ref)
        except ray.exceptions.RayError as e:  # (its actor or node is gone)
            return {**blank, "state": "exited (lost)", "notes": [str(e).splitlines()[0]]}

    def stop(self, timeout: float) -> None:
        import ray

        # (an actor never placed runs no system: nothing to wait for, it is killed at close)
        placed = [s["node"] is not None for s in self.status()]
        refs = [a.stop.remote(timeout) if up else a.status.remote()
                for a, up in zip(self.actors, placed, strict=True)]  # fmt: skip
        waited = [r for r, up in zip(refs, placed, strict=True) if up]
        done, _ = ray.wait(waited, num_returns=len(waited), timeout=timeout + 10)
        self._final = [self._answer(k, ref, ref in done) for k, ref in enumerate(refs)]

    def close(self) -> None:
        """End the actors (after :meth:`stop`) and this process's connection to Ray."""
        import ray

        for a in self.actors:
            ray.kill(a)
        self.actors = []
        if self._connected:
            ray.shutdown()
            self._connected = False
