"""[scene.lesson]: a lesson in a teacher's words, and the claims its sentences make about the scene's own run.

Each claim quotes the words of the lesson it checks (`says`, found in the lesson's text) and states them as a bound
on one measurement of the run (a column of the stats table: `sandbox run --stats`), reduced over a window of
simulated time:

    [[scene.lesson.claims]]
    says = "drops (blue) that fall to the floor, gather into a pool and freeze"
    measure = "structure_solid"    # the share of atoms in a crystal, measured from their neighbours
    stat = "last"                  # first, last, min, max, mean, change (last - first), duration, time_of_first
    above = 0.05

`duration` is the simulated time the measure spends in `between` ([lo, hi]); `time_of_first` the time it first
enters it (never: infinite). `where` and `where_between` keep only the frames where another measurement lies in a
range ("the liquid's temperature while a fifth to four fifths of the atoms are gas": the boiling point). `over`
names an earlier claim (its `name`): the value is then this claim's divided by that one's ("boiling lasts six times
as long as melting"). A sentence no run can check is listed under [[scene.lesson.unchecked]] with the reason, so
every sentence is one or the other. `sandbox check --lesson SCENE` runs the scene and says which claims hold
(measure/lesson_claims.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import at_least, one_of, spec

RANGED = ("duration", "time_of_first")  # the stats that count frames in `between`
STATS = ("first", "last", "min", "max", "mean", "change", *RANGED)


@dataclass(frozen=True, kw_only=True)
class LessonClaim:
    says: str = spec(doc="the lesson's words this claim checks (as they appear in its text)")
    measure: str = spec(doc="the measurement: a column of the stats table (sandbox run --stats)")
    stat: str = spec("last", doc="how the window's values reduce to one: " + ", ".join(STATS), check=one_of(*STATS))
    window: tuple[float, ...] = spec((), doc="[t0, t1]: the simulated seconds looked at (default: the whole run)")
    between: tuple[float, ...] = spec((), doc="stat = duration or time_of_first: the range [lo, hi] of the measure")
    where: str = spec("", doc="another measurement: only the frames where it lies in `where_between` count")
    where_between: tuple[float, ...] = spec((), doc="with `where`: its range [lo, hi]")
    above: float | None = spec(None, doc="the value must be above this", infinite=True)
    below: float | None = spec(None, doc="the value must be below this", infinite=True)
    name: str = spec("", doc="a name for a later claim's `over`")
    over: str = spec("", doc="the name of an earlier claim: the value is this claim's divided by that one's")
    frames: int = spec(0, doc="frames the run needs for this claim (0: the scene's render.frames)", check=at_least(0))

    def problem(self) -> str | None:
        """What is wrong with the claim on its own (its bounds, window and range), or None."""
        if self.above is None and self.below is None:
            return "expected a bound: above, below or both"
        if self.above is not None and self.below is not None and not self.above < self.below:
            return f"above {self.above} is not below below {self.below}"
        if self.window and (len(self.window) != 2 or not self.window[0] < self.window[1]):
            return f"window {list(self.window)}: expected [t0, t1] with t0 < t1"
        needs_range = self.stat in RANGED
        if needs_range != bool(self.between):
            return f"between: expected [lo, hi] with stat = duration or time_of_first, and only then (stat {self.stat})"
        if self.between and (len(self.between) != 2 or not self.between[0] <= self.between[1]):
            return f"between {list(self.between)}: expected [lo, hi] with lo <= hi"
        if bool(self.where) != bool(self.where_between):
            return "where and where_between: expected both (a measurement and its range [lo, hi]) or neither"
        if self.where_between and (len(self.where_between) != 2 or not self.where_between[0] <= self.where_between[1]):
            return f"where_between {list(self.where_between)}: expected [lo, hi] with lo <= hi"
        if any(not math.isfinite(x) for x in (*self.window, *self.between, *self.where_between)):
            return "window, between and where_between: expected finite numbers"
        return None


@dataclass(frozen=True, kw_only=True)
class UncheckedSentence:
    says: str = spec(doc="the lesson's words no run of the scene can check (as they appear in its text)")
    why: str = spec(doc="why: a fact about the world the model does not compute, a suggestion to the reader, ...")


@dataclass(frozen=True, kw_only=True)
class Lesson:
    """[scene.lesson]: a short lesson in a teacher's words, shown by `sandbox list` and at the top of the window,
    and the claims its sentences make about the scene's run."""

    happens: str = spec("", doc="what happens in the scene, in a sentence or two")
    explore: str = spec("", doc="what to try in the window and from the command line: keys, tools, --set values")
    explore_page: str = spec(
        "",
        doc="what to try in the classroom's page: its buttons, Tool menu and sliders, no keys or command-line options "
        "(the page shows `explore` where this is empty)",
    )
    physics: str = spec("", doc="the physics it shows")
    claims: list[LessonClaim] = spec(doc="the lesson's checkable sentences, as bounds on the run", factory=list)
    unchecked: list[UncheckedSentence] = spec(doc="the sentences no run can check, and why", factory=list)

    def parts(self) -> list[tuple[str, str]]:
        """(label, text) for each part given: "What happens", "Try", "The physics"."""
        parts = (("What happens", self.happens), ("Try", self.explore), ("The physics", self.physics))
        return [(label, text) for label, text in parts if text]

    def text(self) -> str:
        """Every part's words, for finding what a claim says."""
        return " ".join((self.happens, self.explore, self.explore_page, self.physics))

    def problem(self) -> tuple[str, str] | None:
        """(key, what is wrong) for the first claim or unchecked sentence whose words the lesson does not say, or
        that is wrong on its own, or whose `over` names no earlier claim; None when all are right."""
        names: set[str] = set()
        text = self.text()
        for k, claim in enumerate(self.claims):
            where = f"claims[{k}]"
            if claim.says not in text:
                return f"{where}.says", f"{claim.says[:60]!r} is not in the lesson; expected its own words"
            wrong = claim.problem()
            if wrong:
                return where, wrong
            if claim.over and claim.over not in names:
                return f"{where}.over", f"{claim.over!r}: expected the name of an earlier claim"
            if claim.name:
                names.add(claim.name)
        for k, sentence in enumerate(self.unchecked):
            if sentence.says not in text:
                return f"unchecked[{k}].says", f"{sentence.says[:60]!r} is not in the lesson; expected its own words"
        return None

    def frames(self, default: int) -> int:
        """The frames a check of the claims runs: the most any claim needs (`default`: the scene's)."""
        return max([c.frames or default for c in self.claims], default=default)
