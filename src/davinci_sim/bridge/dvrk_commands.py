"""One path from a dVRK command message to the arm, for every ROS transport (dvrk.md §2.2).

The built-in rosbridge server (:class:`~davinci_sim.bridge.dvrk_node.DvrkNode`) and client
mode (:class:`~davinci_sim.bridge.client_mode.RosClientMode`, commands published on a remote
rosbridge) both send a command with :func:`command_sender`: the message (already validated
against its type) is converted by the table of :mod:`davinci_sim.bridge.dvrk_topics`, called
on the arm through the handle, and a refusal is described by the same :class:`Refusal`, so a
command is checked and refused identically whichever way it came.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.dvrk_topics import ArmInfo, CommandTopic

if TYPE_CHECKING:
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.bridge")


@dataclass(frozen=True)
class Refusal:
    """A command that moved nothing."""

    text: str
    """What the sender is told (the built-in server's ``status`` text)."""
    publish_error: bool
    """True when the arm did not say it on its own ``error`` channel (the message could not
    be converted, or the call raised): the transport publishes ``<arm>: <text>`` there."""


#: ``send(msg, refused)``: ``refused(Refusal)`` may be called from the simulation's thread.
Sender = Callable[[dict, Callable[[Refusal], None]], None]


def error_text(arm: str, refusal: Refusal) -> str:
    """What goes on ``/<arm>/error`` for a refusal the arm did not publish itself."""
    return f"{arm}: {refusal.text}"


def command_sender(handle: SimHandle, info: ArmInfo, spec: CommandTopic) -> Sender:
    """The sender of ``spec`` for arm ``info``: ``send(msg, refused)`` converts ``msg`` (a
    message validated against ``spec.type``), calls the arm, and calls ``refused`` if the
    conversion fails, the call raises, or the arm refuses the command."""
    target = info.name + (f"/{spec.target}" if spec.target else "")
    topic_name = f"/{info.name}/{spec.suffix}"

    def send(msg: dict, refused: Callable[[Refusal], None]) -> None:
        try:
            args = spec.convert(msg, info)
        except m.CommandError as e:
            refused(Refusal(f"{spec.suffix}: {e}", True))
            return

        def done(future) -> None:
            exc = future.exception()
            if exc is not None:
                _log.error("%s: %s", topic_name, exc)
                refused(Refusal(f"{topic_name}: {exc}", True))
                return
            result = future.result()
            if result is not None and hasattr(result, "accepted") and not result.accepted:
                refused(Refusal(result.message, False))

        handle.call(target, spec.method, *args).add_done_callback(done)

    return send
