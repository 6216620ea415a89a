"""The declared schema of task files, checked with the field's path and the file's line.

A task file is checked against its kind's schema before any task is built, so a mistake is
one line naming the field and where it is — ``bad.yaml, line 21: waypoints[2]: must be 3
numbers [x, y, z], got [0.08, 1.2]`` — never a numpy traceback from deep inside. The
schema gives each field's type and shape, which fields are required, which are optional
(any other is refused), and the fixture types with their parameters.

* Fields common to every kind: :data:`COMMON_FIELDS`; a kind adds its own as the class
  attribute ``FILE_FIELDS`` (:class:`~davinci_sim.tasks.task.PathTask` declares the path's),
  and ``FILE_REQUIRED`` for the required ones.
* Fixture entries (``fixture``, each of ``conditions``) come from the kind's
  ``FIXTURE_TYPES`` (fixture ``type`` → its parameter names): a parameter is a number unless
  ``FIXTURE_PARAMETERS`` (name → schema) says otherwise, so a new parameter or fixture type
  added there is checked here without touching this module.
* Walls (``walls``): :data:`WALL_TYPES`.

Line numbers come from PyYAML's composed node tree (each node keeps its start mark), read
alongside the loaded values: :func:`line_map` maps each field's path to its line. JSON task
files are read by the same composer when they can be (JSON is YAML flow style), else the
message has no line.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import yaml

Path = tuple[str | int, ...]


class SchemaError(ValueError):
    """A task file that does not fit its schema: ``field`` (a path like ``waypoints[2]``),
    ``line`` (1-based, None if unknown) and what is wrong."""

    def __init__(self, path: Path, problem: str, line: int | None = None, source: str = ""):
        self.path, self.problem, self.line, self.source = path, problem, line, source
        where = ", ".join(p for p in (source, f"line {line}" if line else "") if p)
        super().__init__(f"{where + ': ' if where else ''}{format_path(path)}: {problem}")


def format_path(path: Path) -> str:
    """``("conditions", 1, "B")`` → ``conditions[1].B``; ``()`` → ``(the file)``."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out or "(the file)"


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


# ================================================================== the schema's types
class Schema:
    """A field's schema: :meth:`check` raises :class:`SchemaError` (without the line; the
    caller adds it from the path)."""

    def check(self, value: Any, path: Path) -> None:
        raise NotImplementedError


@dataclass(frozen=True)
class Number(Schema):
    """A finite number (not a boolean) in [minimum, maximum]; ``above``: strictly > it."""

    minimum: float | None = None
    maximum: float | None = None
    above: float | None = None

    def check(self, value, path):
        if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
            hint = ""
            if isinstance(value, str):
                try:
                    float(value)
                    hint = " (a string to YAML: write it with a decimal point, e.g. 1.0e-3)"
                except ValueError:
                    pass
            raise SchemaError(path, f"must be a number{self._range()}, got {_show(value)}{hint}")
        x = float(value)
        bad = not math.isfinite(x)
        bad |= self.minimum is not None and x < self.minimum
        bad |= self.maximum is not None and x > self.maximum
        bad |= self.above is not None and x <= self.above
        if bad:
            raise SchemaError(path, f"must be a finite number{self._range()}, got {_show(value)}")

    def _range(self) -> str:
        parts = [f"> {self.above:g}"] if self.above is not None else []
        parts += [f">= {self.minimum:g}"] if self.minimum is not None else []
        parts += [f"<= {self.maximum:g}"] if self.maximum is not None else []
        return f" {' and '.join(parts)}" if parts else ""


@dataclass(frozen=True)
class Text(Schema):
    """A string, one of ``choices`` if given."""

    choices: tuple[str, ...] | None = None

    def check(self, value, path):
        if not isinstance(value, str):
            raise SchemaError(path, f"must be a string, got {_show(value)}")
        if self.choices is not None and value not in self.choices:
            raise SchemaError(path, f"must be one of {list(self.choices)}, got {value!r}")


@dataclass(frozen=True)
class Flag(Schema):
    """true or false."""

    def check(self, value, path):
        if not isinstance(value, bool):
            raise SchemaError(path, f"must be true or false, got {_show(value)}")


@dataclass(frozen=True)
class Vector(Schema):
    """A list of ``n`` numbers (``names`` says what they are, e.g. ``x, y, z``)."""

    n: int
    names: str = ""
    item: Number = field(default_factory=Number)

    def check(self, value, path):
        what = f"{self.n} numbers" + (f" [{self.names}]" if self.names else "")
        if not isinstance(value, list | tuple) or len(value) != self.n:
            raise SchemaError(path, f"must be {what}, got {_show(value)}")
        for i, x in enumerate(value):
            self.item.check(x, (*path, i))


@dataclass(frozen=True)
class ListOf(Schema):
    """A list of at least ``min_items`` items of one schema."""

    item: Schema
    min_items: int = 0
    what: str = "items"

    def check(self, value, path):
        if not isinstance(value, list | tuple):
            raise SchemaError(path, f"must be a list of {self.what}, got {_show(value)}")
        if len(value) < self.min_items:
            raise SchemaError(
                path, f"must have at least {self.min_items} {self.what}, got {len(value)}"
            )
        for i, x in enumerate(value):
            self.item.check(x, (*path, i))


@dataclass(frozen=True)
class Record(Schema):
    """A mapping with these fields: ``required`` ones must be there, no others may be."""

    fields: Mapping[str, Schema]
    required: tuple[str, ...] = ()
    what: str = "a mapping"

    def check(self, value, path):
        if not isinstance(value, Mapping):
            raise SchemaError(path, f"must be {self.what}, got {_show(value)}")
        for key in value:
            if key not in self.fields:
                raise SchemaError(
                    (*path, str(key)),
                    f"unknown field; {format_path(path) if path else 'a task'} has "
                    f"{', '.join(sorted(self.fields))}",
                )
        for key in self.required:
            if key not in value:
                raise SchemaError((*path, key), "required, but missing")
        for key, x in value.items():
            self.fields[key].check(x, (*path, key))


@dataclass(frozen=True)
class Tagged(Schema):
    """A mapping whose ``tag`` field (default ``default``) selects one of ``variants``."""

    variants: Mapping[str, Record]
    tag: str = "type"
    default: str | None = None
    what: str = "entry"

    def check(self, value, path):
        if not isinstance(value, Mapping):
            raise SchemaError(path, f"a {self.what} must be a mapping, got {_show(value)}")
        kind = value.get(self.tag, self.default)
        if kind is None:
            raise SchemaError((*path, self.tag), "required, but missing")
        if kind not in self.variants:
            raise SchemaError(
                (*path, self.tag),
                f"unknown {self.what} {self.tag} {kind!r}; {self.tag}s: {list(self.variants)}",
            )
        self.variants[kind].check(value, path)


# ================================================================== the task schema
NONNEGATIVE = Number(minimum=0.0)
POINT = Vector(3, "x, y, z")

#: Walls (:mod:`davinci_sim.haptics.wall`): type → fields.
WALL_TYPES: dict[str, Record] = {
    "plane": Record(
        {
            "type": Text(),
            "point": POINT,
            "normal": POINT,
            "stiffness": NONNEGATIVE,
            "damping": NONNEGATIVE,
            "damping_depth": NONNEGATIVE,
            "max_force": NONNEGATIVE,
        },
        required=("point", "normal"),
    ),  # fmt: skip
    "sphere": Record(
        {
            "type": Text(),
            "center": POINT,
            "radius": NONNEGATIVE,
            "keep_out": Flag(),
            "stiffness": NONNEGATIVE,
            "damping": NONNEGATIVE,
            "damping_depth": NONNEGATIVE,
            "max_force": NONNEGATIVE,
            "fallback_normal": POINT,
        },
        required=("center", "radius"),
    ),  # fmt: skip
}

#: Fields every kind of task has (:func:`davinci_sim.tasks.base.common_fields`); the
#: fixture fields are added per kind by :func:`task_schema`.
COMMON_FIELDS: dict[str, Schema] = {
    "kind": Text(),
    "name": Text(),
    "description": Text(),
    "frame": Text(choices=("world", "camera")),
    "teleop": Record(
        {"psm": Text(), "mtm": Text(), "scale": Number(above=0.0, maximum=1.0), "keyframe": Text()}
    ),  # fmt: skip
    "walls": ListOf(Tagged(WALL_TYPES, what="wall"), what="walls"),
}


def fixture_schema(task_class: type, *, condition: bool = False) -> Tagged:
    """The schema of a fixture entry of ``task_class``: its ``FIXTURE_TYPES`` (type → the
    parameter names), each parameter a finite number unless the class's
    ``FIXTURE_PARAMETERS`` (name → :class:`Schema`) says otherwise; a condition needs a
    ``name``."""
    special = getattr(task_class, "FIXTURE_PARAMETERS", {})
    variants = {}
    for kind, params in task_class.FIXTURE_TYPES.items():
        fields: dict[str, Schema] = {"type": Text(), "name": Text()}
        fields.update({p: special.get(p, Number()) for p in params})
        variants[kind] = Record(fields, required=("name",) if condition else ())
    return Tagged(variants, default="none", what="fixture")


def task_schema(task_class: type) -> Record:
    """The schema of a task file of kind ``task_class``."""
    fields = dict(COMMON_FIELDS)
    fields["fixture"] = fixture_schema(task_class)
    fields["conditions"] = ListOf(fixture_schema(task_class, condition=True), what="conditions")
    fields.update(getattr(task_class, "FILE_FIELDS", {}))
    required = ("name", *getattr(task_class, "FILE_REQUIRED", ()))
    return Record(fields, required=required, what="a mapping of a task's fields")


# ================================================================== lines
def line_map(text: str) -> dict[Path, int]:
    """Each field's path → its 1-based line in the YAML (or JSON) ``text`` (a mapping key's
    path → the key's line; a list item → its own). Empty if the text does not compose."""
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError:
        return {}
    lines: dict[Path, int] = {}

    def walk(node, path: Path) -> None:
        lines.setdefault(path, node.start_mark.line + 1)
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                sub = (*path, key.value if isinstance(key, yaml.ScalarNode) else str(key))
                lines[sub] = key.start_mark.line + 1
                walk(value, sub)
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                walk(item, (*path, i))

    if root is not None:
        walk(root, ())
    return lines


def line_of(lines: Mapping[Path, int], path: Path) -> int | None:
    """The line of ``path``, or of its nearest ancestor that has one."""
    for k in range(len(path), -1, -1):
        if path[:k] in lines:
            return lines[path[:k]]
    return None


def check_task_data(task_class: type, data: Any, text: str | None = None, source: str = "") -> None:
    """Check a task file's mapping against ``task_class``'s schema; ``text`` (the file's)
    gives the line numbers. A kind that declares no ``FILE_FIELDS`` is left to its own
    ``from_dict``.

    Raises:
        SchemaError: the first field that does not fit, with its line and ``source``.
    """
    if not hasattr(task_class, "FILE_FIELDS"):
        return
    try:
        task_schema(task_class).check(data, ())
    except SchemaError as e:
        line = line_of(line_map(text), e.path) if text is not None else None
        raise SchemaError(e.path, e.problem, line, source) from None
