"""What every plot the project writes shares, to a textbook's standard: axis labels in words with units, legends
beside the axes (never over the data), categories drawn as categories, and a caveat on fits that rest on few points.
matplotlib is optional: `pyplot()` is None without it."""

from __future__ import annotations

from pathlib import Path

# Words and units of a scene key's last part (the parts before it name the body or source when they can).
KEY_WORDS = {
    "temperature": ("temperature", "°C"),
    "ambient": ("ambient temperature", "°C"),
    "dt": ("time step", "s"),
    "frame_time": ("time per frame", "s"),
    "lifetime": ("lifetime", "s"),
    "spacing": ("particle spacing", "mm"),
    "radius": ("radius", "mm"),
    "cutoff": ("pair force cutoff", "mm"),
    "reach": ("reach", "mm"),
    "conductance": ("conductance", "heat per s per °C"),
    "power": ("power", "heat per s"),
    "material": ("material", ""),
    "integrator": ("integrator", ""),
    "substeps": ("steps per frame", ""),
    "restitution": ("restitution", ""),
    "friction": ("wall friction", ""),
    "rate": ("emission rate", "particles per s"),
}
# The sweep's measures: words and unit, and the factor from the stored number to the plotted one.
METRIC_WORDS = {
    "final_molten_fraction": ("melted at the end", "%", 100.0),
    "time_to_half_molten": ("time until half melted", "s", 1.0),
    "peak_mean_temperature": ("peak mean temperature", "°C", 1.0),
    "final_mean_temperature": ("mean temperature at the end", "°C", 1.0),
    "energy_drift": ("energy drift", "relative", 1.0),
    "wall_seconds": ("run time", "s", 1.0),
}


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only), or None where matplotlib is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def with_unit(words: str, unit: str) -> str:
    """An axis label: "temperature (°C)", or the words alone where there is no unit."""
    return f"{words} ({unit})" if unit else words


def key_label(key: str, scene_table: dict | None = None) -> str:
    """The axis label of a scene key ("heat.sources.0.temperature" -> "hot plate temperature (°C)"): its last part
    in words with its unit, after the name of the body or source it belongs to where `scene_table` names it."""
    parts = key.split(".")
    words, unit = KEY_WORDS.get(parts[-1], (parts[-1].replace("_", " "), ""))
    node = scene_table
    for part in parts[:-1]:
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            node = None
    owner = f"{node['name']} " if isinstance(node, dict) and node.get("name") else ""
    return with_unit(f"{owner}{words}", unit)


def metric_label(metric: str) -> tuple[str, float]:
    """(axis label, factor from the stored value to the plotted one) of a sweep measure."""
    words, unit, factor = METRIC_WORDS.get(metric, (metric.replace("_", " "), "", 1.0))
    return with_unit(words, unit), factor


def legend_beside(ax, title: str | None = None) -> None:
    """The axes' legend to the right of them, outside the data area."""
    ax.legend(title=title, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8)


def fit_note(points: int) -> str:
    """What a fitted slope's label adds when it rests on few points."""
    return " (2 points: a rough estimate)" if points == 2 else ""


def save(fig, path: Path, dpi: int = 110) -> Path:
    """Write the figure (its legends beside the axes included) and close it."""
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path
