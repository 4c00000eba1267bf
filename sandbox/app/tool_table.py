"""The tools, declared once: each tool's name, whether it needs the scene's heat, and what it
does to the simulation while the mouse holds it (`use`, through the brush kernels of tools.py). The window's keys
and help, the classroom's message check and page, the controller and `sandbox check` all read this table; it
imports no Taichi, so the classroom server checks tool names without starting a runtime.

A new tool is one `Tool(...)` here (or `register(Tool(...))` from a plugin or a test), using the brushes of
tools.Tools or a kernel of its own; the page shows its name through the catalogue key `tool_<name>`, falling back
to the name itself. docs/architecture.md, "Adding a tool", walks through one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

# use(tools, centre, radius, dt, strength, material): one frame of `dt` seconds of the tool held at `centre`
Use = Callable[..., object]


@dataclass(frozen=True)
class Tool:
    """A tool: its `name`, what it does while held (`use`), whether it is offered only in scenes with heat, and
    whether it changes the particle count (not offered in a simulation of several worlds: each keeps its count)."""

    name: str
    use: Use
    needs_heat: bool = False
    counts: bool = False


TOOL_TABLE: list[Tool] = [
    Tool("heat", lambda t, c, r, dt, k, m: t.heat(c, r, 400.0 * k, dt), True),
    Tool("cool", lambda t, c, r, dt, k, m: t.heat(c, r, -400.0 * k, dt), True),
    Tool("drag", lambda t, c, r, dt, k, m: t.drag(c, r, 400.0 * k, dt)),
    Tool("attract", lambda t, c, r, dt, k, m: t.push(c, r, 60.0 * k, dt)),
    Tool("repel", lambda t, c, r, dt, k, m: t.push(c, r, -60.0 * k, dt)),
    Tool("impulse", lambda t, c, r, dt, k, m: t.impulse(c, r, 30.0 * k)),
    Tool("erase", lambda t, c, r, dt, k, m: t.erase(c, r), counts=True),
    Tool("spawn", lambda t, c, r, dt, k, m: t.spawn(m, c, r), counts=True),
]


def register(tool: Tool) -> Tool:
    """Add `tool` to the table (after the shipped ones); ValueError for a name already taken."""
    if tool.name in names():
        raise ValueError(f"a tool named {tool.name!r} exists already; expected a new name")
    TOOL_TABLE.append(tool)
    return tool


def unregister(name: str) -> None:
    """Take the tool `name` out of the table (a test's clean-up)."""
    TOOL_TABLE[:] = [t for t in TOOL_TABLE if t.name != name]


def names() -> tuple[str, ...]:
    """Every tool's name, in the table's order (the window's Tab cycles through them in it)."""
    return tuple(t.name for t in TOOL_TABLE)


def by_name(name: str) -> Tool:
    """The tool `name`; KeyError for none."""
    for tool in TOOL_TABLE:
        if tool.name == name:
            return tool
    raise KeyError(name)


def offered(has_heat: bool, worlds: int = 1) -> list[str]:
    """The tools a scene offers: all, less those that need heat where it has none, and those that change the
    particle count where it runs as several `worlds`."""
    return [t.name for t in TOOL_TABLE if (has_heat or not t.needs_heat) and (worlds == 1 or not t.counts)]
