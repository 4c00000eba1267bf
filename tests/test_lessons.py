"""Lessons speak of the front-end that shows them (issue 56, item 5): the page's "Try" names the page's own controls
(no keys, no command-line options), and a tool a lesson says is picked at the start is the one the window and the
page start with (window_state.first_tool)."""

from __future__ import annotations

import re

import pytest

import sandbox
from sandbox.app.serve_session import page_lesson
from sandbox.app.window_state import first_tool
from sandbox.config.resources import shipped_scenes
from sandbox.config.scene import load_scene

SCENES = {p.stem: load_scene(p) for p in shipped_scenes()}
LESSONS = {name: scene.lesson for name, scene in SCENES.items() if scene.lesson.happens}
WINDOW_ONLY = re.compile(r"--[a-z]|\bTab\b|Shift|right button|\b[Pp]ress (?:space|[a-z]\b)|\bkeys?\b|\borbit")
PICKED = re.compile(r"\b(add particles|[a-z]+) tool(?: \(|, )picked at the start", re.IGNORECASE)
PAGE_NAMES = {"add particles": "spawn"}  # the page's words for a tool, where they are not its name


def test_every_shipped_lesson_is_checked():
    assert len(LESSONS) >= 13


@pytest.mark.parametrize("name", sorted(LESSONS))
def test_the_pages_lesson_names_only_the_pages_controls(name):
    text = page_lesson(LESSONS[name])["explore"]
    assert text and not WINDOW_ONLY.search(text), f"{name}: {WINDOW_ONLY.search(text).group(0)!r} in {text!r}"


@pytest.mark.parametrize(
    "name",
    sorted(n for n, lesson in LESSONS.items() if PICKED.search(lesson.explore + " " + page_lesson(lesson)["explore"])),
)
def test_the_tool_a_lesson_says_is_picked_is_the_one_picked(name):
    scene = SCENES[name]
    lesson = LESSONS[name]
    for text in (lesson.explore, page_lesson(lesson)["explore"]):
        for said in PICKED.findall(text):
            assert PAGE_NAMES.get(said.lower(), said.lower()) == first_tool(scene), (name, text)


def test_first_tool_is_the_windows_and_the_simulations_own():
    """The scene-level rule agrees with what a built simulation offers (its tools, its particles)."""
    from sandbox.app.window_state import tools_for

    sim = sandbox.load("sandbox", arch="cpu")
    assert sim.model.built.count == 0 and first_tool(sim.scene) == "spawn" and "spawn" in tools_for(sim)


def test_the_summarys_trend_follows_a_climbing_temperature():
    """The trend compared the temperature with a reference reset to the current value every 2 s, so right after
    each reset a climbing temperature read "steady"; it now slides: every sample after the first second of a climb
    of 1 C per 0.1 s reads rising, a flat one steady, a fall falling, and a reset starts afresh."""
    from sandbox.app.panel import Trend, trend_word

    trend = Trend(2.0)
    words = [trend_word(20 + 10 * t, trend.add(t, 20 + 10 * t)) for t in [k * 0.1 for k in range(60)]]
    assert words[10:] == ["rising"] * 50, words
    flat = Trend(2.0)
    assert {trend_word(50.0, flat.add(k * 0.1, 50.0)) for k in range(40)} == {"steady"}
    falling = Trend(2.0)
    assert [trend_word(90 - 5 * k * 0.1, falling.add(k * 0.1, 90 - 5 * k * 0.1)) for k in range(40)][15:] == [
        "falling"
    ] * 25
    assert trend.add(0.0, 20.0) is None  # time went back (a reset): no trend until half a window has passed
