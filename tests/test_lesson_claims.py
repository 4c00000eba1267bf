"""Lesson claims as data (issue 75, item 1): each claim quotes the lesson's own words and bounds one measurement of
the scene's run; a claim the lesson does not say, or that cannot be checked, is refused when the scene loads; the
checker reduces a run's table as each claim asks; every translation carries every claim in its own words. The
shipped lessons are held against their scenes' runs in tests/test_lessons.py (the long tier)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from sandbox.config.lesson import LessonClaim
from sandbox.config.resources import shipped_scenes
from sandbox.config.scene import load_scene
from sandbox.errors import SandboxError, SceneError
from sandbox.measure.lesson_claims import evaluate
from tests.conftest import make_scene, scene_dict

LESSON = {"happens": "The gas share falls below a half, then the crystal grows.", "physics": "Atoms attract."}
I18N = Path(__file__).parents[1] / "sandbox" / "app" / "web" / "i18n"


def with_claims(*claims: dict, unchecked=()) -> dict:
    return scene_dict(scene={"lesson": {**LESSON, "claims": list(claims), "unchecked": list(unchecked)}})


GAS = {"says": "The gas share falls below a half", "measure": "structure_gas", "stat": "last", "below": 0.5}


@pytest.mark.parametrize(
    "claim, says",
    [
        ({**GAS, "says": "The gas boils"}, "scene.lesson.claims[0].says': 'The gas boils' is not in the lesson"),
        ({**GAS, "below": None}, "expected a bound"),
        ({**GAS, "above": 0.6}, "above 0.6 is not below below 0.5"),
        ({**GAS, "stat": "duration"}, "between: expected [lo, hi] with stat = duration"),
        ({**GAS, "window": [3.0, 1.0]}, "window [3.0, 1.0]: expected [t0, t1] with t0 < t1"),
        ({**GAS, "over": "melting"}, "claims[0].over': 'melting': expected the name of an earlier claim"),
        ({**GAS, "stat": "median"}, "expected one of 'first', 'last'"),
    ],
)
def test_a_claim_the_lesson_does_not_make_or_cannot_check_is_refused(claim, says):
    claim = {k: v for k, v in claim.items() if v is not None}
    with pytest.raises(SceneError, match=None) as caught:
        make_scene(with_claims(claim))
    assert says in str(caught.value), str(caught.value)


def test_an_unchecked_sentence_must_be_the_lessons_own_words():
    make_scene(with_claims(GAS, unchecked=[{"says": "Atoms attract.", "why": "a fact of the model's law"}]))
    with pytest.raises(SceneError, match=r"unchecked\[0\]\.says': 'Atoms repel.' is not in the lesson"):
        make_scene(with_claims(GAS, unchecked=[{"says": "Atoms repel.", "why": "..."}]))


def table(gas: list[float], frame_time: float = 0.5) -> dict:
    n = len(gas)
    return {"frame": np.arange(1, n + 1), "time": frame_time * np.arange(1, n + 1), "structure_gas": np.array(gas)}


def claim(**fields) -> LessonClaim:
    return LessonClaim(**{"says": "x", "measure": "structure_gas", **fields})


@pytest.mark.parametrize(
    "fields, value",
    [
        ({"stat": "first", "above": 0}, 1.0),
        ({"stat": "last", "above": 0}, 0.2),
        ({"stat": "min", "above": 0}, 0.1),
        ({"stat": "max", "above": 0}, 1.0),
        ({"stat": "mean", "above": 0}, 0.54),
        ({"stat": "change", "below": 0}, -0.8),
        ({"stat": "min", "window": [1.0, 1.5], "above": 0}, 0.6),  # t = 1.0 and 1.5: 0.8, 0.6
        ({"stat": "duration", "between": [0.0, 0.5], "above": 0}, 1.0),  # two frames of 0.5 s at or below a half
        ({"stat": "time_of_first", "between": [0.0, 0.5], "above": 0}, 2.0),
        ({"stat": "time_of_first", "between": [2.0, 3.0], "above": 0}, math.inf),
    ],
)
def test_each_stat_reduces_the_window_as_it_says(fields, value):
    (verdict,) = evaluate([claim(**fields)], table([1.0, 0.8, 0.6, 0.1, 0.2]), 0.5, 5)
    assert verdict.value == pytest.approx(value)


def test_bounds_are_strict_and_a_missing_value_fails():
    run = table([1.0, 0.8, 0.6, 0.1, 0.2])
    holds = [v.holds for v in evaluate([claim(below=0.2), claim(below=0.21), claim(above=0.19)], run, 0.5, 5)]
    assert holds == [False, True, True]
    (missing,) = evaluate([claim(above=0)], table([1.0, math.nan]), 0.5, 2)
    assert not missing.holds and math.isnan(missing.value)
    (never,) = evaluate([claim(stat="time_of_first", between=[2.0, 3.0], below=10)], run, 0.5, 5)
    assert not never.holds  # never reached: not "before t = 10"


def test_a_claim_over_another_divides_by_it_and_a_shorter_claim_sees_its_own_frames():
    run = table([1.0, 0.8, 0.6, 0.1, 0.2])
    first = claim(stat="duration", between=[0.5, 1.0], above=0, name="high")  # 1.5 s
    ratio = claim(stat="duration", between=[0.0, 0.5], over="high", below=1.0)  # 1.0 s / 1.5 s
    short = claim(stat="last", frames=2, above=0.7)  # frames 1 and 2 only: last 0.8
    verdicts = evaluate([first, ratio, short], run, 0.5, 5)
    assert [v.value for v in verdicts] == pytest.approx([1.5, 1.0 / 1.5, 0.8])
    assert all(v.holds for v in verdicts)


def test_where_keeps_only_the_frames_where_another_measurement_is_in_its_range():
    """The boiling point as a claim sees it: the temperature while a fifth to four fifths of the atoms are gas."""
    run = {**table([0.0, 0.1, 0.3, 0.6, 0.9]), "motion_temperature": np.array([0.5, 0.6, 0.7, 0.72, 1.0])}
    boiling = claim(measure="motion_temperature", stat="mean", where="structure_gas", where_between=[0.2, 0.8])
    (verdict,) = evaluate([LessonClaim(**{**boiling.__dict__, "above": 0.0})], run, 0.5, 5)
    assert verdict.value == pytest.approx(0.71)
    assert "while structure_gas is 0.2..0.8" in verdict.line()
    with pytest.raises(SceneError, match="where and where_between: expected both"):
        make_scene(with_claims({**GAS, "where": "structure_solid"}))
    with pytest.raises(SandboxError, match=r"claims\[0\]\.where 'gas_share'"):
        evaluate([claim(above=0, where="gas_share", where_between=[0, 1])], run, 0.5, 5)


def test_an_unknown_measure_is_one_line():
    with pytest.raises(SandboxError, match=r"claims\[0\]\.measure 'gas_share': expected a column of the stats table"):
        evaluate([claim(measure="gas_share", above=0)], table([1.0]), 0.5, 1)


def shipped_lessons():
    return [(path.stem, load_scene(path).lesson) for path in shipped_scenes()]


@pytest.mark.parametrize("language", ["fr", "ar"])
def test_every_translation_carries_every_claim_in_its_own_words(language):
    """Each translated lesson lists its claims' words in its language, one for each of the English claims, and each is
    found in the translated text (so a student reading French knows which sentences the run checks)."""
    translated = json.loads((I18N / f"lessons.{language}.json").read_text())
    for name, lesson in shipped_lessons():
        if not lesson.claims:
            continue
        entry = translated[name]
        text = " ".join(entry.get(part, "") for part in ("happens", "explore", "explore_page", "physics"))
        words = entry.get("claims", [])
        assert len(words) == len(lesson.claims), (
            f"{language} {name}: {len(words)} claims, English has {len(lesson.claims)}"
        )
        for said in words:
            assert said and said in text, f"{language} {name}: {said!r} is not in its lesson"


def test_every_shipped_lesson_sentence_is_claimed_or_marked_unchecked():
    """Every sentence of every shipped lesson is covered: some claim or unchecked entry quotes part of it."""
    for name, lesson in shipped_lessons():
        quoted = [c.says for c in lesson.claims] + [u.says for u in lesson.unchecked]
        for _, text in lesson.parts():
            for sentence in split_sentences(text):
                assert any(q in sentence or sentence in q for q in quoted), f"{name}: {sentence!r}"


def split_sentences(text: str) -> list[str]:
    """The sentences of a lesson's part (split after a full stop, a colon or a semicolon and a space)."""
    out, start = [], 0
    for k, ch in enumerate(text):
        if ch in ".:;" and (k + 1 == len(text) or text[k + 1] == " "):
            out.append(text[start : k + 1].strip())
            start = k + 1
    if text[start:].strip():
        out.append(text[start:].strip())
    return [s.rstrip(".:;") for s in out if len(s) > 3]
