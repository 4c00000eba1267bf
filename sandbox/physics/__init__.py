"""The physics terms a scene can name, one per module (physics/term.py says what a term is), and what the pair terms
are evaluated over (grid.py, neighbours.py, reorder.py). Importing this package registers every term; a new term's
module is imported here."""

from . import (  # noqa: F401 - each registers its terms
    agitation,
    body_forces,
    emitters,
    fields,
    heat,
    heat_implicit,
    heater,
    kinematic,
    lid,
    lifetimes,
    pair,
    phase,
    smoke,
    springs,
    structure,
    thermal_walls,
    walls,
)
from .term import TERMS, Measure, Parts, Term, TermList, register

__all__ = ["TERMS", "Measure", "Parts", "Term", "TermList", "register"]
