"""Every plot the project writes, to a textbook's standard (issue 43): axis labels in words with units, legends
beside the data rather than over it, categories drawn as categories, a caveat on fits that rest on two points.
The figures are caught where they would be saved and their matplotlib artists inspected."""

import re

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from sandbox.app import sweep  # noqa: E402
from sandbox.research import figures, phase_study, study_report  # noqa: E402
from sandbox.research.study_runs import Run, StudyResult  # noqa: E402


@pytest.fixture
def caught(monkeypatch):
    """The figures the plotting code saves, drawn but not written or closed."""
    kept = []

    def keep(fig, path, dpi=110):
        fig.canvas.draw()
        kept.append(fig)
        return path

    for module in (sweep, study_report, phase_study):
        monkeypatch.setattr(module, "save", keep)
    yield kept
    import matplotlib.pyplot as plt

    for fig in kept:
        plt.close(fig)


def check_axes(ax) -> None:
    """Labels in words (no raw keys: no underscores or dotted paths) and, where a legend is shown, the legend beside
    the axes: its box shares no pixel with the data area."""
    for label in (ax.get_xlabel(), ax.get_ylabel()):
        assert label and "_" not in label and not re.search(r"\w\.\w", label), label
    legend = ax.get_legend()
    if legend is not None:
        box, data = legend.get_window_extent(), ax.get_window_extent()
        assert box.x0 >= data.x1 or box.x1 <= data.x0 or box.y0 >= data.y1 or box.y1 <= data.y0


def test_a_sweeps_plot_names_its_axes_with_units_and_draws_words_as_categories(tmp_path, caught):
    table = {"heat": {"sources": [{"name": "hot plate", "temperature": 200.0}]}, "bodies": [{"material": "wax"}]}
    records = []
    for temperature in (100.0, 150.0, 200.0):
        for material in ("wax", "chocolate"):
            records.append(
                {
                    "outcome": "done",
                    "overrides": {"heat.sources.0.temperature": temperature, "bodies.0.material": material},
                    "final_molten_fraction": temperature / 400 + (0.2 if material == "chocolate" else 0.0),
                }
            )
    keys = ["heat.sources.0.temperature", "bodies.0.material"]
    sweep.plot_sweep(tmp_path, records, keys, "final_molten_fraction", table)
    (fig,) = caught
    by_temperature, by_material = fig.axes[:2]
    assert by_temperature.get_xlabel() == "hot plate temperature (°C)"
    assert by_temperature.get_ylabel() == "melted at the end (%)"
    assert by_material.get_xlabel() == "material"
    for ax in (by_temperature, by_material):
        check_axes(ax)
    assert [t.get_text() for t in by_material.get_xticklabels()] == ["wax", "chocolate"]  # categories, not numbers
    assert not by_material.lines and len(by_material.patches) == 6  # bars, no line joining the categories
    heights = sorted(p.get_height() for p in by_material.patches)
    assert heights[-1] == pytest.approx(100 * (200 / 400 + 0.2))  # in percent
    assert by_temperature.get_legend().get_title().get_text() == "material"


def test_the_studys_plots_label_units_and_caveat_two_point_fits(tmp_path, caught):
    runs = []
    for name, order in (("velocity_verlet", 2), ("forward_euler", 1)):
        dts = (0.01, 0.005) if name == "forward_euler" else (0.01, 0.005, 0.0025)
        for dt in dts:
            runs.append(Run("harmonic", name, dt, round(1 / dt), dt**order, 0.0, 0.1 / dt, 1e6, True))
    names = study_report.make_plots(tmp_path, StudyResult(runs=runs))
    assert names == ["harmonic.png"]
    (fig,) = caught
    cost, convergence = fig.axes
    assert cost.get_xlabel() == "run time (s)" and convergence.get_xlabel() == "time step dt (s)"
    check_axes(convergence)
    labels = [t.get_text() for t in convergence.get_legend().get_texts()]
    assert labels[0].startswith("velocity_verlet: order 2.00,") and "rough" not in labels[0]
    assert labels[1].startswith("forward_euler: order 1.00 (2 points: a rough estimate)")


def test_the_phase_plots_label_units_and_keep_legends_off_the_data(tmp_path, caught):
    t = np.linspace(0.0, 4.0, 200)
    front = phase_study.StefanResult(1.0, 100, t, 1.2 * np.sqrt(t), 1.2 * np.sqrt(t), 0.6)
    molten = np.clip((t - 1.0) / 2.0, 0.0, 1.0)
    curve = phase_study.HeatingCurve(t, np.where(molten > 0, 0.0, -20 + 20 * t), molten, 1.0, 1.0, 2.0, 334.0, 0.0)
    phase_study._plot(tmp_path, [front], curve)
    stefan, heating = caught
    ax = stefan.axes[0]
    check_axes(ax)
    assert ax.get_xlabel() == "time (s)" and ax.get_ylabel() == "melt front position (mm)"
    temperature_axis, melt_axis = heating.axes
    assert temperature_axis.get_ylabel() == "mean temperature (°C)" and melt_axis.get_ylabel() == "melted (%)"
    legend = melt_axis.get_legend().get_window_extent()
    assert legend.x0 >= temperature_axis.get_window_extent().x1  # beside the axes, not over the curves


def test_labels_in_words():
    assert figures.key_label("world.dt") == "time step (s)"
    assert figures.key_label("bodies.0.material", {"bodies": [{"material": "wax"}]}) == "material"
    assert figures.key_label("bodies.0.temperature", {"bodies": [{"name": "block"}]}) == "block temperature (°C)"
    assert figures.metric_label("time_to_half_molten") == ("time until half melted (s)", 1.0)
