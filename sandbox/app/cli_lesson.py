"""`sandbox check --lesson SCENE`: run a scene for as long as its lesson's claims need and say, a line each, whether
each claim holds (config/lesson.py, measure/lesson_claims.py); the sentences no run can check are listed with why.
Exit 0 when every claim holds, 1 when one fails."""

from __future__ import annotations

import sys

from ..measure.lesson_claims import check_measures, evaluate
from ..simulation import Simulation

EXIT_CLAIM_FAILS = 1


def check_lesson(sim: Simulation, progress: bool = True) -> int:
    """Run `sim` for the frames its lesson's claims need, print each verdict; the exit status."""
    scene, lesson = sim.scene, sim.scene.lesson
    if not lesson.claims:
        print(f"{scene.name}: its lesson makes no claim to check ({len(lesson.unchecked)} sentences marked unchecked)")
        return 0
    check_measures(lesson.claims)
    frames = lesson.frames(scene.render.frames)
    print(
        f"{scene.name}: {len(lesson.claims)} claims over {frames} frames ({frames * sim.frame_seconds:g} s simulated)"
    )
    table = sim.run(frames, progress=progress)
    verdicts = evaluate(lesson.claims, table, sim.frame_seconds, scene.render.frames)
    for verdict in verdicts:
        print(f"  {verdict.line()}")
    for sentence in lesson.unchecked:
        print(f'  unchecked  "{sentence.says}": {sentence.why}')
    failed = sum(not v.holds for v in verdicts)
    print(f"{scene.name}: {len(verdicts) - failed} of {len(verdicts)} claims hold", file=sys.stderr)
    return EXIT_CLAIM_FAILS if failed else 0
