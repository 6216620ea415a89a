"""The package layering of ``docs/architecture.md`` holds in the code.

Imports flow one way: a package imports only packages of a lower layer (or itself). The table
here is the document's; a new package gets a layer in both. Modules over 500 lines state why
at their top (a ``Size:`` paragraph in the module docstring).
"""

from __future__ import annotations

import ast
import pathlib

import pytest

import davinci_sim

PACKAGE_ROOT = pathlib.Path(davinci_sim.__file__).parent

#: Layer of each top-level package or module of ``davinci_sim`` (docs/architecture.md,
#: "Layering rule"). Lower layers never import higher ones; packages of one layer do not
#: import each other.
LAYERS: dict[str, int] = {
    "geometry": 0,
    "kinematics": 1,
    "model": 2,
    "sim": 3,
    "devices": 4,
    "haptics": 4,
    "console": 5,
    "tasks": 6,
    "operators": 7,
    "system": 8,
    "records": 9,
    "study": 10,
    "envs": 10,
    "bridge": 10,
    "web": 11,
    "compat": 11,
    "cli": 12,
    "warm_up": 12,
}
MAX_MODULE_LINES = 500


def _modules() -> list[pathlib.Path]:
    return sorted(PACKAGE_ROOT.rglob("*.py"))


def _package_of(path: pathlib.Path) -> str | None:
    parts = path.relative_to(PACKAGE_ROOT).parts
    if len(parts) == 1:
        name = parts[0].removesuffix(".py")
        return None if name == "__init__" else name
    return parts[0]


def _imported_packages(path: pathlib.Path) -> set[str]:
    """Top-level ``davinci_sim`` packages imported anywhere in the module (also lazily)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            parts = node.module.split(".")
            if parts[0] != "davinci_sim":
                continue
            if len(parts) > 1:
                found.add(parts[1])
            else:
                found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "davinci_sim" and len(parts) > 1:
                    found.add(parts[1])
    return found


def test_every_package_has_a_layer():
    packages = {_package_of(p) for p in _modules()} - {None}
    assert packages <= set(LAYERS), f"give these a layer: {sorted(packages - set(LAYERS))}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE_ROOT)))
def test_imports_flow_down(path):
    package = _package_of(path)
    if package is None:
        return
    wrong = sorted(
        other
        for other in _imported_packages(path) - {package}
        if other in LAYERS and LAYERS[other] >= LAYERS[package]
    )
    assert not wrong, (
        f"{package} (layer {LAYERS[package]}) imports {wrong} "
        f"(layers {[LAYERS[w] for w in wrong]}): imports must flow to lower layers"
    )


def test_the_checker_sees_an_upward_import(tmp_path):
    source = tmp_path / "m.py"
    source.write_text("def f():\n    from davinci_sim.console import haptic_loop\n")
    assert _imported_packages(source) == {"console"}


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE_ROOT)))
def test_large_modules_say_why(path):
    text = path.read_text(encoding="utf-8")
    if text.count("\n") <= MAX_MODULE_LINES:
        return
    docstring = ast.get_docstring(ast.parse(text)) or ""
    assert "Size:" in docstring, (
        f"{path.name} has {text.count(chr(10))} lines: split it, or say why it is one module "
        "in a 'Size:' paragraph of its docstring"
    )
