"""What the studies share: one run's record, a study's result, and the path that names their generated scenes."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..config.resources import SCENES_DIR

STUDY_PATH = SCENES_DIR / "study.toml"  # names the generated scenes (in errors); no such file is read


@dataclass
class Run:
    """One integrator on one problem at one step: its error against the reference, and what it cost."""

    problem: str
    integrator: str
    dt: float
    steps: int
    error: float
    energy_error: float
    wall_seconds: float
    particle_steps_per_second: float
    stable: bool
    note: str = ""


@dataclass
class StudyResult:
    """What a study found: its runs, the stability and stiffness tables, and notes for the report."""

    runs: list[Run] = field(default_factory=list)
    stability: list[dict] = field(default_factory=list)
    stiff: list[dict] = field(default_factory=list)
    notes: dict = field(default_factory=dict)
