"""A small typed validator: TOML tables → frozen dataclasses; errors name the file, the key and the expectation.

A dataclass field declares its type by annotation (float, int, str, bool, tuple[float, ...] for a vector,
list[SomeDataclass], SomeDataclass | None) and its constraint and one-line meaning through `spec(...)`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import types
import typing
from collections.abc import Callable
from typing import Any

from ..errors import SceneError

Check = Callable[[Any], "str | None"]

ABSOLUTE_ZERO = -273.15  # degrees Celsius: the lowest temperature a scene may name
# Every number a scene holds lies in these ranges unless its own check says more (generated for every key, so none
# is missed): the scene's units (mm, g/cm^3, simulated seconds, degrees) put every sensible value between them, and
# f32 fields hold them without overflowing or flushing to zero.
MAX_MAGNITUDE = 1e12  # the integrator study's unbounded box is +-1e12
MIN_MAGNITUDE = 1e-12  # a nonzero number smaller is refused (0 itself where the key's check allows it); the study's
# implicit_tolerance is 1e-10
MAX_INT = 2**31 - 1  # integers go to 32-bit fields and seeds


def unknown(what: str, word, choices) -> str:
    """The words of an error for a name that is not one of `choices`: the nearest one when there is one close
    ("unknown material 'wox'; did you mean 'wax'? expected one of: ..."); a key is named by the error already."""
    names = sorted(str(c) for c in choices)
    near = difflib.get_close_matches(str(word), names, n=1)
    hint = f"did you mean '{near[0]}'? " if near else ""
    named = "" if what == "key" else f" {word!r}"
    return f"unknown {what}{named}; {hint}expected one of: {', '.join(names)}"


def spec(
    default: Any = dataclasses.MISSING,
    *,
    doc: str,
    check: Check | None = None,
    factory: Any = None,
    infinite=False,
    length: int | str | None = None,
):
    """Declare a scene field: its default (omit for a required key), its one-line meaning, an optional check,
    whether a number may be infinite (`inf` in TOML: never, for ever; every other number must be finite), and for a
    vector its `length`: a number, or "dim" for the scene's dimension (checked by check_lengths once world.dim is
    known; an empty vector is a default's "none" and passes)."""
    meta = {"doc": doc, "check": check, "infinite": infinite, "length": length}
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def positive(x: float) -> str | None:
    return None if x > 0 else f"expected a number > 0, got {x}"


def non_negative(x: float) -> str | None:
    return None if x >= 0 else f"expected a number >= 0, got {x}"


def unit_interval(x: float) -> str | None:
    return None if 0 <= x <= 1 else f"expected a number in [0, 1], got {x}"


def celsius(x: float) -> str | None:
    return None if x >= ABSOLUTE_ZERO else f"expected a temperature >= {ABSOLUTE_ZERO} (absolute zero), got {x}"


def one_of(*choices: str) -> Check:
    def check(x: str) -> str | None:
        return None if x in choices else f"expected one of {', '.join(repr(c) for c in choices)}, got {x!r}"

    return check


def between(lo: float, hi: float) -> Check:
    def check(x: float) -> str | None:
        return None if lo <= x <= hi else f"expected a number from {lo:,} to {hi:,}, got {x}"

    return check


def at_least(lo: float) -> Check:
    def check(x: float) -> str | None:
        return None if x >= lo else f"expected a number >= {lo}, got {x}"

    return check


def _type_name(hint: Any) -> str:
    if hint is float:
        return "a number"
    if hint is int:
        return "an integer"
    if hint is str:
        return "a string"
    if hint is bool:
        return "true or false"
    origin = typing.get_origin(hint)
    if origin is tuple:
        return "an array of numbers"
    if origin is list:
        return "an array of strings" if typing.get_args(hint) == (str,) else "an array of tables"
    return "a table"


def _convert(hint: Any, raw: Any, file: str, key: str) -> Any:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if raw is None:
            return None
        for arg in args:
            if _accepts(arg, raw):
                return _convert(arg, raw, file, key)
        raise SceneError(file, key, f"expected {' or '.join(_type_name(a) for a in args)}, got {raw!r}")
    if hint is float:
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise SceneError(file, key, f"expected a number, got {raw!r}")
        if math.isnan(raw):
            raise SceneError(file, key, "expected a number, got nan")
        return float(raw)
    if hint is int:
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise SceneError(file, key, f"expected an integer, got {raw!r}")
        return raw
    if hint is str:
        if not isinstance(raw, str):
            raise SceneError(file, key, f"expected a string, got {raw!r}")
        return raw
    if hint is bool:
        if not isinstance(raw, bool):
            raise SceneError(file, key, f"expected true or false, got {raw!r}")
        return raw
    if origin is tuple:
        if not isinstance(raw, list) or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in raw):
            raise SceneError(file, key, f"expected an array of numbers, got {raw!r}")
        if any(math.isnan(v) or math.isinf(v) for v in raw):
            raise SceneError(file, key, f"expected finite numbers, got {raw!r}")
        return tuple(float(v) for v in raw)
    if origin is list and typing.get_args(hint) == (str,):
        if not isinstance(raw, list) or not all(isinstance(v, str) for v in raw):
            raise SceneError(file, key, f"expected an array of strings, got {raw!r}")
        return list(raw)
    if origin is list:
        (item,) = typing.get_args(hint)
        if not isinstance(raw, list):
            raise SceneError(file, key, f"expected an array of tables ([[{key}]]), got {raw!r}")
        return [parse_table(item, v, file, f"{key}[{i}]") for i, v in enumerate(raw)]
    if dataclasses.is_dataclass(hint):
        return parse_table(hint, raw, file, key)
    if hint is dict:
        if not isinstance(raw, dict):
            raise SceneError(file, key, f"expected a table, got {raw!r}")
        return raw
    raise TypeError(f"schema: unsupported annotation {hint!r}")


def _accepts(hint: Any, raw: Any) -> bool:
    if hint is float:
        return isinstance(raw, int | float) and not isinstance(raw, bool)
    if hint is int:
        return isinstance(raw, int) and not isinstance(raw, bool)
    if hint is str:
        return isinstance(raw, str)
    if hint is bool:
        return isinstance(raw, bool)
    if typing.get_origin(hint) in (tuple, list):
        return isinstance(raw, list)
    return isinstance(raw, dict)


def parse_table(cls: type, data: Any, file: str, key: str = "") -> Any:
    """Validate `data` (a TOML table) into an instance of the dataclass `cls`; raise SceneError on the first problem."""
    if not isinstance(data, dict):
        raise SceneError(file, key, f"expected a table, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    for name in data:
        if name not in fields:
            raise SceneError(file, _join(key, name), unknown("key", name, fields))
    values = {}
    for name, f in fields.items():
        sub = _join(key, name)
        if name in data:
            value = _convert(hints[name], data[name], file, sub)
            if isinstance(value, float) and math.isinf(value) and not f.metadata.get("infinite"):
                raise SceneError(file, sub, f"expected a finite number, got {value}")
            check = f.metadata.get("check")
            if check is not None and value is not None:
                problem = check(value)
                if problem:
                    raise SceneError(file, sub, problem)
            problem = out_of_range(value)  # after the key's own check, whose words say more
            if problem:
                raise SceneError(file, sub, problem)
            values[name] = value
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise SceneError(file, sub, f"missing; expected {_type_name(hints[name])}: {f.metadata.get('doc', '')}")
    return cls(**values)


def check_lengths(table: Any, dim: int, file: str, key: str = "") -> None:
    """Every vector field of `table` (a parsed dataclass, its sub-tables and lists of them) declared with a
    `length` holds that many numbers ("dim": `dim`), or none; SceneError naming the first that does not."""
    for f in dataclasses.fields(table):
        value, sub = getattr(table, f.name), _join(key, f.name)
        want = f.metadata.get("length")
        if want is not None and isinstance(value, tuple) and value:
            n = dim if want == "dim" else want
            if len(value) != n:
                said = f" (world.dim = {dim})" if want == "dim" else ""
                raise SceneError(file, sub, f"expected {n} numbers{said}, got {len(value)}")
        if dataclasses.is_dataclass(value):
            check_lengths(value, dim, file, sub)
        elif isinstance(value, list):
            for i, item in enumerate(value):
                if dataclasses.is_dataclass(item):
                    check_lengths(item, dim, file, f"{sub}[{i}]")


def key_check(table: type, name: str) -> Check:
    """The check a scene key keeps (the range every scene number keeps, then its own `spec(check=...)`), for a value
    that reaches the simulation another way (a live control set by a slider, the API or a state file)."""
    own = {f.name: f for f in dataclasses.fields(table)}[name].metadata["check"]

    def check(value: Any) -> str | None:
        return out_of_range(value) or (own(value) if own is not None else None)

    return check


def out_of_range(value: Any) -> str | None:
    """What is wrong with a number (or a vector's numbers) outside the ranges every scene number keeps, or None."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return None if abs(value) <= MAX_INT else f"expected an integer from {-MAX_INT:,} to {MAX_INT:,}, got {value}"
    if isinstance(value, float):
        if math.isinf(value) or value == 0 or MIN_MAGNITUDE <= abs(value) <= MAX_MAGNITUDE:
            return None
        return f"expected 0 or a number of magnitude {MIN_MAGNITUDE:g} to {MAX_MAGNITUDE:g}, got {value:g}"
    if isinstance(value, tuple):
        return next((problem for v in value if (problem := out_of_range(v))), None)
    return None


def _join(key: str, name: str) -> str:
    return f"{key}.{name}" if key else name


def toml_value(value: Any) -> str:
    """`value` as it is written in a scene file (TOML): true, 2.5, "text", [1.0, 2.0], inf; unset (None) as ''."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if isinstance(value, tuple | list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


def describe(cls: type, prefix: str = "") -> list[tuple[str, str, str]]:
    """(key, default, meaning) for every field of `cls`, recursively: the reference table of scene keys."""
    rows = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        key = _join(prefix, f.name)
        hint = hints[f.name]
        inner = [a for a in typing.get_args(hint) if dataclasses.is_dataclass(a)]
        if dataclasses.is_dataclass(hint) or inner:
            rows.extend(describe(inner[0] if inner else hint, key))
            continue
        if f.default is not dataclasses.MISSING:
            default = toml_value(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            default = toml_value(f.default_factory())
        else:
            default = ""  # required
        rows.append((key, default, f.metadata.get("doc", "")))
    return rows
