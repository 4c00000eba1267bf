"""Every shipped lesson against its scene's own run (issue 75): `sandbox check --lesson SCENE` runs the scene as
shipped for as long as its claims need and every claim holds (crystal_3d, condensation, boiling_pot and
pressure_cooker were changed until they did). Long: the runs take minutes (states_of_matter_atoms and
pressure_cooker, whole heat-and-cool cycles, most of them)."""

from __future__ import annotations

import pytest

from sandbox.app.cli import main
from sandbox.config.resources import shipped_scenes
from sandbox.config.scene import load_scene

pytestmark = pytest.mark.long


# the two whole heat-and-cool cycles (minutes each) run on workers of their own, beside the other lessons
OWN_WORKER = ("pressure_cooker", "states_of_matter_atoms")


def lessons_with_claims() -> list:
    scenes = []
    for path in shipped_scenes():
        if load_scene(path).lesson.claims:
            marks = pytest.mark.xdist_group(f"lesson_{path.stem}") if path.stem in OWN_WORKER else ()
            scenes.append(pytest.param(path.stem, marks=marks))
    return scenes


@pytest.mark.parametrize("scene", lessons_with_claims())
def test_every_claim_of_the_lesson_holds_on_its_scene(scene, capsys):
    code = main(["check", scene, "--lesson", "--quiet", "--arch", "cpu"])
    out = capsys.readouterr().out
    verdicts = [line.strip() for line in out.splitlines() if line.strip().startswith(("holds", "FAILS"))]
    assert verdicts, out
    assert code == 0 and all(v.startswith("holds") for v in verdicts), "\n".join(verdicts)


def test_a_claim_the_run_does_not_bear_out_makes_the_check_exit_1(capsys):
    """The checker is no formality: melting_block on a plate at room temperature does not slump into a puddle, and
    `sandbox check --lesson` says which claims fail and exits 1."""
    code = main(
        ["check", "melting_block", "--lesson", "--quiet", "--arch", "cpu", "--set", "heat.sources.0.temperature=20"]
    )
    out = capsys.readouterr().out
    assert code == 1
    assert 'FAILS  "the block slumps into a puddle": change of centre_of_mass_height' in out
