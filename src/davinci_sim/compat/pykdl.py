"""Where the real PyKDL is, for ``davinci-sim run`` and the tests.

PyKDL is not on PyPI: platforms ship it as a compiled module, Debian and Ubuntu as
``python3-pykdl`` in the system interpreter's ``dist-packages``, ROS in its
``site-packages``. A virtual environment does not see those folders, so :func:`find` also
looks in them for a module built for *this* interpreter (its exact extension suffix, e.g.
``.cpython-311-x86_64-linux-gnu.so``: same Python minor version and platform) and
:func:`load` imports that file alone (not the folder: the rest of the system's packages stay
out of the environment). Where none fits, :mod:`davinci_sim.compat.kdl` stands in.

``$DAVINCI_SIM_PYKDL`` chooses: ``subset`` (always ours), or the path of a PyKDL module.
"""

from __future__ import annotations

import glob
import importlib.machinery
import importlib.util
import os
import pathlib
import sys
import sysconfig
from types import ModuleType

ENV = "DAVINCI_SIM_PYKDL"

SYSTEM_DIRS = (
    "/usr/lib/python3/dist-packages",  # Debian, Ubuntu: python3-pykdl
    "/usr/lib/python{ver}/site-packages",  # Fedora, Arch
    "/usr/lib64/python{ver}/site-packages",
    "/opt/ros/*/lib/python{ver}/site-packages",  # ROS 2
    "/opt/ros/*/lib/python3/dist-packages",  # ROS 1 (Noetic)
)
"""Folders of the system's Python packages searched, ``{ver}`` the running minor version."""

_cache: dict[str, ModuleType] = {}


def suffix() -> str:
    """The extension-module suffix of this interpreter (version and platform tagged)."""
    return sysconfig.get_config_var("EXT_SUFFIX") or importlib.machinery.EXTENSION_SUFFIXES[0]


def find() -> pathlib.Path | None:
    """The real PyKDL this interpreter can load: the importable one, else one in the
    system's folders built for this interpreter; None if there is none (or
    ``$DAVINCI_SIM_PYKDL=subset``)."""
    chosen = os.environ.get(ENV, "")
    if chosen == "subset":
        return None
    if chosen:
        path = pathlib.Path(chosen)
        if not path.is_file():
            raise FileNotFoundError(f"${ENV}={chosen}: no such file")
        return path
    spec = importlib.util.find_spec("PyKDL") if "PyKDL" not in sys.modules else None
    if spec is not None and spec.origin and spec.origin.endswith(tuple(
            importlib.machinery.EXTENSION_SUFFIXES)):  # fmt: skip
        return pathlib.Path(spec.origin)
    ver = f"{sys.version_info.major}.{sys.version_info.minor}"
    for pattern in SYSTEM_DIRS:
        for folder in sorted(glob.glob(pattern.format(ver=ver))):
            candidate = pathlib.Path(folder) / f"PyKDL{suffix()}"
            if candidate.is_file():
                return candidate
    return None


def load(path: pathlib.Path | None = None) -> ModuleType | None:
    """The real PyKDL module (from ``path``, or :func:`find`'s), or None. It is not put in
    ``sys.modules``: the caller decides whether it is *the* ``PyKDL``."""
    path = path or find()
    if path is None:
        return None
    key = str(path)
    if key not in _cache:
        spec = importlib.util.spec_from_file_location("PyKDL", path)
        if spec is None or spec.loader is None:
            raise ImportError(f"{path} is not a Python module")
        before = sys.modules.get("PyKDL")
        try:
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
        finally:  # loading a compiled module registers it: undo that
            if before is None:
                sys.modules.pop("PyKDL", None)
            else:
                sys.modules["PyKDL"] = before
        _cache[key] = module
    return _cache[key]
