"""The molecular model's scene tables ([molecular], its [[molecular.walls]], [molecular.lid] and [molecular.heater]):
typed, immutable dataclasses, each key with its default, meaning and check (config/scene_tables.py holds the rest)."""

from __future__ import annotations

from dataclasses import dataclass

from .schema import at_least, between, non_negative, one_of, positive, spec

# The walls of the box a thermal wall can be, by axis and end: (axis, +1 for the upper end)
WALL_SIDES = {"left": (0, -1), "right": (0, 1), "bottom": (1, -1), "top": (1, 1), "back": (2, -1), "front": (2, 1)}


@dataclass(frozen=True, kw_only=True)
class ThermalWall:
    name: str = spec("heater", doc="label of the wall's temperature slider and readout")
    side: str = spec(
        doc="which wall of the box: left, right, bottom, top (and back, front in 3D)", check=one_of(*WALL_SIDES)
    )
    temperature: float = spec(
        doc="the wall's temperature as kT (energy units: eps in reduced units); an atom that hits it leaves with a "
        "velocity drawn from the Maxwell distribution at this temperature",
        check=positive,
    )


@dataclass(frozen=True, kw_only=True)
class Lid:
    pressure: float = spec(
        doc="the pressure that weighs on the lid from outside (energy per length^dim: eps / sigma^2 in 2D, "
        "eps / sigma^3 in 3D): the atoms below must push it up with as much",
        check=non_negative,
    )
    mass: float = spec(100.0, doc="the lid's mass (in atoms' masses): heavier, slower to follow", check=positive)
    height: float = spec(doc="the lid's starting height along y (length)", check=positive)
    schedule_times: tuple[float, ...] = spec((), doc="times (increasing, from 0) at which the pressure changes")
    schedule_values: tuple[float, ...] = spec((), doc="the pressure from each of schedule_times on")
    schedule_period: float = spec(
        0.0, doc="repeat the schedule with this period (0: hold the last value)", check=non_negative
    )


@dataclass(frozen=True, kw_only=True)
class Heater:
    power: float = spec(
        0.0,
        doc="energy per time shared evenly among the atoms by scaling their motion about their centre of mass "
        "(momentum kept); negative cools, down to rest at most",
    )
    schedule_times: tuple[float, ...] = spec((), doc="times (increasing, from 0) at which the power changes")
    schedule_values: tuple[float, ...] = spec((), doc="the power from each of schedule_times on")
    schedule_period: float = spec(
        0.0, doc="repeat the schedule with this period (0: hold the last value)", check=non_negative
    )


@dataclass(frozen=True, kw_only=True)
class Molecular:
    phase_radius: float = spec(
        1.5,
        doc="neighbours nearer than this (length) count toward an atom's coordination and bond order",
        check=positive,
    )
    gas_below: int = spec(0, doc="an atom with fewer neighbours than this is counted as gas (0: 3)", check=at_least(0))
    solid_bonds: int = spec(
        0,
        doc="an atom with at least this many ordered bonds (neighbours whose bond order matches its own) is counted "
        "as solid (0: 4 in 2D, 7 in 3D)",
        check=at_least(0),
    )
    phase_every: int = spec(
        1,
        doc="steps between classifications of the atoms' phases at most (1: whenever they are read after a step; "
        "more: a large scene's window spends less on it, its phase readouts and colours up to this many steps old)",
        check=between(1, 1000),
    )
    walls: list[ThermalWall] = spec(doc="thermal walls: heaters and coolers that keep momentum", factory=list)
    lid: Lid | None = spec(
        None, doc="a lid across the box that moves up and down under a set outside pressure (a piston)"
    )
    heater: Heater | None = spec(None, doc="heat shared evenly among the atoms at a set power (a stove under the pot)")
