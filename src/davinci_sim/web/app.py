"""The web console as a part of ``davinci-sim serve``: :func:`web_part`.

``serve`` builds and runs the system (:func:`davinci_sim.bridge.app.serve`); this module
adds the web console on the same system: the endoscope frames from the runner's render
pipeline (``System.frames()``), the 3-D bedside view, and the :class:`~davinci_sim.web.
server.WebConsole` page server, started in that order and stopped in reverse.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from typing import Any

from davinci_sim.records.db import default_path
from davinci_sim.web.server import WebConsole, WebOptions, is_loopback

_log = logging.getLogger("davinci_sim.web")


class WebPart:
    """The started web console of a system (what :func:`web_part` returns to ``serve``)."""

    def __init__(self, console: WebConsole, frames, bedside, gate=None) -> None:
        self.console = console
        self.frames = frames
        self.bedside = bedside
        self.gate = gate

    @property
    def url(self) -> str:
        return self.console.url

    def stop(self) -> None:
        for part in (self.console, self.gate, self.bedside, self.frames):
            if part is None:
                continue
            try:
                part.stop()
            except Exception:
                _log.exception("stopping %r failed", part)


def web_part(
    options: WebOptions,
    *,
    bedside: bool = True,
    records=None,
    exercises: tuple[str, ...] = (),
    on_exercise: Callable[[str], str | None] | None = None,
) -> Callable[[Any, dict], WebPart]:
    """A ``serve`` part that starts the web console on the running system: the page at
    ``options.host:options.port``, the 3-D view on the next free port if ``bedside``. Adds
    ``info["web"]`` (the page's URL) and ``info["bedside"]`` (the 3-D view's). ``records``:
    the trainee records' part (:class:`~davinci_sim.records.console.RecordsPart`) the page's
    trainee field sets the trainee of. ``exercises`` and ``on_exercise``: what the page may
    switch to and the call that switches (:class:`~davinci_sim.web.server.WebConsole`)."""

    def make(system, info: dict) -> WebPart:
        from davinci_sim.model import resolve_scene
        from davinci_sim.system.build import load_description_task

        description = system.description
        task = load_description_task(description)
        console_description = description.console_description
        hands = () if console_description is None else console_description.hand_inputs
        frames = system.frames(options.frame_rate)
        view = gate = None
        web_options = options
        if bedside:
            view, gate = start_bedside(system, options)
            if view is not None:
                port = view.port if gate is None else gate.port
                web_options = dataclasses.replace(options, bedside_port=port)
                info["bedside"] = view.url if gate is None else gate.url
        console = WebConsole(
            system.handle,
            web_options,
            frames=frames,
            task=task,
            camera=resolve_scene(description.scene).endoscope,
            hand_mtms=hands,
            study_task=None if description.task is None else description.task.task,
            records=records,
            model=system.model_source,
            study_root=default_path().parent / "studies",  # (beside the trainee records)
            exercises=exercises,
            on_exercise=on_exercise,
        )
        try:
            console.start()
        except BaseException:
            for part in (gate, view, frames):
                if part is not None:
                    part.stop()
            raise
        info["web"] = console.url
        return WebPart(console, frames, view, gate)

    return make


def start_bedside(system, options: WebOptions):
    """The 3-D bedside view of ``system`` started on a free loopback port, and where the page
    is served beyond loopback, the :class:`~davinci_sim.web.token_gate.TokenGate` that serves
    it there behind the page's token (viser has no authentication of its own): ``(view,
    gate)``, gate None on loopback, both None if the view cannot start (the console works
    without it)."""
    try:
        from davinci_sim.web.scene3d import BedsideView
    except ImportError as e:
        _log.warning("no 3-D view: %s", e)
        return None, None
    try:
        view = BedsideView(system.model_source, system.handle, host="127.0.0.1", port=0).start()
    except Exception:
        _log.exception("the 3-D view did not start; the console goes on without it")
        return None, None
    if is_loopback(options.host) or options.token is None:
        return view, None
    from davinci_sim.web.token_gate import TokenGate

    try:
        return view, TokenGate(view.port, options.token, options.host).start()
    except OSError:
        _log.exception("the 3-D view's gate did not start; the console goes on without it")
        view.stop()
        return None, None
