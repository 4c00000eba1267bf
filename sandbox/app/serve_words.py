"""What a classroom session tells its page in words and colours: the lesson as the page shows it, the legend of
the picture's colours, and the picture's chart words in the page's language (serve_session.py)."""

from __future__ import annotations

import functools
import json
from pathlib import Path


def page_lesson(lesson) -> dict:
    """The lesson as the page shows it: what happens, what to try with the page's own controls (`explore_page`,
    else `explore`), the physics."""
    if not lesson:
        return {}
    return {"happens": lesson.happens, "explore": lesson.explore_page or lesson.explore, "physics": lesson.physics}


def legend(overlays) -> dict:
    """What the picture's colours mean, for the page's own legend, from the scene's overlays (render/overlays.py): a
    colour bar (its range, quantity, unit and 16 colours) or swatches (label, colour); {} where the scene shows
    none."""
    if overlays.kind == "bar":
        lo, hi, quantity, unit = overlays.scale()
        return {
            "kind": "bar",
            "lo": lo,
            "hi": hi,
            "quantity": quantity,
            "unit": unit,
            "colors": hex_colors(overlays.legend_colors(16)),
        }
    if overlays.kind == "swatches":
        labels = [label for label, _ in overlays.entries]
        return {"kind": "swatches", "labels": labels, "colors": hex_colors(c for _, c in overlays.entries)}
    return {}


def hex_colors(colors) -> list[str]:
    """RGB colours in [0, 1] as CSS "#rrggbb"."""
    return ["#" + "".join(f"{round(255 * float(c)):02x}" for c in rgb) for rgb in colors]


@functools.cache  # a catalogue read once per language, not at every scene or language change
def chart_words(lang: str):
    """The picture's chart words in `lang` (render/words.py), from the page's catalogue; None for English."""
    from ..render.words import Words

    if lang == "en":
        return None
    path = Path(__file__).resolve().parent / "web" / "i18n" / f"{lang}.json"
    return Words(json.loads(path.read_text(encoding="utf-8")))
