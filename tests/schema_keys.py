"""Every key a scene file can hold, read from the schema itself (so a new key is covered without a list to keep):
dotted --set names with index 0 for arrays of tables, and each key's annotated type."""

from __future__ import annotations

import dataclasses
import types
import typing

from sandbox.config.scene_tables import _SceneFile


def scene_keys(cls: type = _SceneFile, prefix: str = "") -> list[tuple[str, object]]:
    """(dotted key, type annotation) for every leaf key under `cls`."""
    keys = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        hint, key = hints[f.name], f"{prefix}{f.name}"
        origin = typing.get_origin(hint)
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if dataclasses.is_dataclass(hint):
            keys += scene_keys(hint, f"{key}.")
        elif origin in (typing.Union, types.UnionType) and len(args) == 1 and dataclasses.is_dataclass(args[0]):
            keys += scene_keys(args[0], f"{key}.")
        elif origin is list and dataclasses.is_dataclass(args[0]):
            keys += scene_keys(args[0], f"{key}.0.")
        elif hint is not dict and not (origin in (typing.Union, types.UnionType) and dict in args):
            keys.append((key, hint))
    return keys


def is_numeric(hint) -> bool:
    """A number, a vector of numbers, or a union holding one."""
    if hint in (int, float):
        return True
    origin = typing.get_origin(hint)
    if origin is tuple:
        return True
    return origin in (typing.Union, types.UnionType) and any(is_numeric(a) for a in typing.get_args(hint))
