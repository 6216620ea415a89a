"""Settings of every test."""

import ast
import os
import threading

import pytest

# As ``import davinci_sim`` sets it: a test module that imports mujoco first (the fidelity
# test renders with MuJoCo's own Renderer) would otherwise get GLFW, which needs a display,
# when it runs alone.
os.environ.setdefault("MUJOCO_GL", "egl")


def _serialised(parse):
    """``ast.parse`` one thread at a time. CPython 3.11's ``ast`` keeps the depth of the tree
    it builds in state that threads share (CPython issue 106905, pytest issue 10763): two
    threads parsing at once raise ``SystemError: AST constructor recursion depth mismatch``
    (seen here as "before=147, after=99": the other thread's parse ended inside ours). pytest
    parses a failing test's source to report it while a client library's thread prints a
    traceback (3.11's tracebacks parse each line for their carets); the SystemError then
    crashed the worker and hid which test had failed."""

    lock = threading.RLock()  # re-entrant: a finalizer run inside a parse may parse

    def parse_alone(*args, **kwargs):
        with lock:
            return parse(*args, **kwargs)

    return parse_alone


ast.parse = _serialised(ast.parse)


@pytest.fixture(autouse=True, scope="session")
def _records_in_a_temporary_folder(tmp_path_factory):
    """``serve --task`` records every attempt in the trainee records: in the tests, a file of
    a temporary folder, never the user's own records (``$DAVINCI_SIM_RECORDS``, set for the
    whole session so that module fixtures and the processes tests start have it too)."""
    before = os.environ.get("DAVINCI_SIM_RECORDS")
    folder = tmp_path_factory.mktemp("records")
    os.environ["DAVINCI_SIM_RECORDS"] = str(folder / "records.sqlite3")
    yield
    if before is None:
        os.environ.pop("DAVINCI_SIM_RECORDS", None)
    else:
        os.environ["DAVINCI_SIM_RECORDS"] = before


def pytest_configure(config):
    """Under xdist, the controller compiles every kernel into numba's on-disk cache before
    the workers start, on every core (:mod:`davinci_sim.warm_up`): on a clean clone the two
    workers, and the servers, studies and Ray workers the tests start, then load the
    kernels instead of each compiling them at once on the same two cores (a Ray test took
    52 s instead of 7 that way)."""
    if getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"):
        import importlib
        import warnings

        from davinci_sim.warm_up import KERNEL_MODULES, warm_up

        try:
            warm_up()
        except (OSError, RuntimeError) as e:  # (no processes here: compile in this one)
            warnings.warn(f"the kernels compile in one process: {e}", RuntimeWarning, stacklevel=1)
            for name in KERNEL_MODULES:
                importlib.import_module(name)


#: The test modules that drive the system's Chromium (each defines ``CHROMIUM``). Under
#: pytest-xdist they are one unit of work: one worker runs them one after the other, first
#: (together the longest unit), so that two browsers never share the cores (nor with
#: :data:`AFTER_BROWSERS`).
BROWSER_MODULES = (
    "tests/web/test_endoscope_fidelity.py",
    "tests/web/test_scene3d_browser.py",
    "tests/web/test_web_browser.py",
    "tests/web/test_web_exercises.py",
    "tests/web/test_web_make_run.py",
)


#: The test modules that start a local Ray instance: one unit too, so that two Ray instances
#: (each a dozen processes) never start at once.
RAY_MODULES = (
    "tests/envs/test_ray_envs.py",
    "tests/study/test_study.py",
)


#: Modules that run first on the other worker, in a process no other module has used: the
#: dVRK's MTM examples (a teleoperation and a haptic box paced by the wall clock in threads
#: beside the simulation's) failed in three runs of three after the bridge and cli modules
#: had run in the same process (the MTM moved a fifth of what the hand asked; with the code
#: of 2026-11-30 and with an earlier commit alike), and passed every time in a fresh one.
FIRST_MODULES = ("tests/compat/test_upstream_mtm_examples.py",)


#: Browser modules of their own, each as long as a third of the browser unit (the
#: needle-driving person, ~2 min): one goes out as soon as the browser unit has finished,
#: not before. Queued in its alphabetical place it ran last and alone while the other worker
#: idled (a minute of ``make test``); started beside the browser unit, both ran at half speed
#: and the run took a minute longer (2026-11-30).
AFTER_BROWSERS = ("tests/web/test_web_needle_drive.py",)


def _unit(nodeid: str) -> str:
    """The unit of work of a test under xdist: its module, "chromium" for the browser
    tests, "ray" for the tests that start Ray."""
    module = nodeid.split("::", 1)[0]
    if module in BROWSER_MODULES:
        return "chromium"
    return "ray" if module in RAY_MODULES else module


def pytest_xdist_make_scheduler(config, log):
    """``make test`` runs ``pytest -n 2 --dist loadfile``: whole modules go to a worker, so
    that a module's fixtures (a homed system, a study's rows, a served console) are built
    once; the browser modules go together (:data:`BROWSER_MODULES`), as do the Ray ones
    (:data:`RAY_MODULES`). Units go out in the order the workers collected them (the
    browser tests first: see below)."""
    from xdist.scheduler import LoadScopeScheduling

    class ByModule(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid)

        def _assign_work_unit(self, node) -> None:
            """The next unit in order, except for :data:`AFTER_BROWSERS`: first once the
            browser unit has finished, never while it runs (unless nothing else is left)."""
            browsing = any(
                scope == "chromium" and not all(tests.values())
                for work in self.assigned_work.values()
                for scope, tests in work.items()
            )
            queued = list(self.workqueue)
            later = [s for s in queued if s in AFTER_BROWSERS]
            if browsing:
                pick = next((s for s in queued if s not in AFTER_BROWSERS), queued[0])
            else:
                pick = later[0] if later and "chromium" not in queued else queued[0]
            self.workqueue.move_to_end(pick, last=False)
            super()._assign_work_unit(node)

    config.option.loadscopereorder = False  # (xdist would order the units by test count)
    return ByModule(config, log)


def pytest_collection_modifyitems(config, items):
    """On an xdist worker: the browser tests first, then :data:`FIRST_MODULES` (a stable
    sort: every module's tests stay together, in their order). A module that drives
    Chromium must be in :data:`BROWSER_MODULES`. Without xdist the order is pytest's own."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    for item in items:
        module = getattr(item, "module", None)
        if getattr(module, "CHROMIUM", None) is not None and _unit(item.nodeid) != "chromium":
            raise pytest.UsageError(
                f"{item.nodeid.split('::')[0]} drives Chromium: add it to BROWSER_MODULES "
                "in tests/conftest.py"
            )
    items.sort(key=lambda item: (_unit(item.nodeid) != "chromium",
                                 item.nodeid.split("::", 1)[0] not in FIRST_MODULES))  # fmt: skip
