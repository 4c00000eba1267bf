"""The words the picture's charts draw (series names, the phase diagram's regions and title), in a language other
than English where one is given: a classroom tab's picture speaks its page's language. The words come from the
page's catalogue (app/web/i18n/*.json) as a plain mapping. The picture draws other letters than ASCII in DejaVu Sans
where one is found (render/text.py): accents and Arabic as they are. Without it, accented letters are drawn without
their accents ("temperature moyenne") and a word in another script stays in English (the page's own chart and
legend carry the language)."""

from __future__ import annotations

import unicodedata

from .text import has_glyph


class Words:
    """Chart and phase-diagram words from `catalogue` (key -> text; empty: English)."""

    def __init__(self, catalogue: dict | None = None) -> None:
        drawn = {k: drawable(v) for k, v in (catalogue or {}).items() if isinstance(v, str)}
        self.catalogue = {k: v for k, v in drawn.items() if v is not None}

    def series(self, name: str, english: str) -> str:
        """A chart series' words (the catalogue's `chart_<name>`)."""
        return self.catalogue.get(f"chart_{name}", english)

    def rule_mark(self) -> str:
        """What follows a chart series set by the model's rule, not measured (the catalogue's `mark_rule`)."""
        return self.catalogue.get("mark_rule", "(rule)")

    def phase(self, name: str) -> str:
        """A region of the phase diagram: "solid", "liquid", "gas" (the catalogue's `phase_<name>`)."""
        return self.catalogue.get(f"phase_{name}", name)

    def material(self, name: str) -> str:
        """A material's name (the catalogue's `material_<name>`)."""
        return self.catalogue.get(f"material_{name}", name)

    def phase_title(self, material: str, unit: str, short: bool = False) -> str:
        """The phase diagram's title: "phase diagram of wax: pressure (unit, log) against temperature", or its
        short form "wax: pressure (unit)"."""
        key = "phase_plot_short" if short else "phase_plot_title"
        english = (
            "{material}: pressure ({unit})"
            if short
            else ("phase diagram of {material}: pressure ({unit}, log) against temperature")
        )
        template = self.catalogue.get(key, english)
        return template.replace("{material}", self.material(material)).replace("{unit}", unit)


def drawable(text: str) -> str | None:
    """`text` as the picture's font can draw it: accented letters without their accents; None where a character
    has no glyph even so (another script)."""
    out = []
    for c in text:
        if not has_glyph(c):
            c = "".join(b for b in unicodedata.normalize("NFKD", c) if not unicodedata.combining(b))
            c = {"–": "-", "—": "-", "’": "'", "«": '"', "»": '"', "\u00a0": " ", "\u202f": " "}.get(c, c)
            if not c or not all(has_glyph(b) for b in c):
                return None
        out.append(c)
    return "".join(out)
