"""The triple-point study (research/triple_point.py): its starting slabs are what it says, and its constant-energy
three-phase runs settle at one temperature from either side while crystal and liquid both remain."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sandbox.research.triple_point import (
    LIQUID_DENSITY,
    ROOT2,
    ThreePhaseRun,
    fcc_positions,
    run_three_phase,
    three_phase_positions,
    triple_estimate,
    zero_pressure_spacing,
)


def nearest(x: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Each point's distance to its nearest other point in the periodic box (brute force: small N)."""
    d = x[:, None, :] - x[None, :, :]
    d -= box * np.round(d / box)
    r = np.linalg.norm(d, axis=-1)
    np.fill_diagonal(r, np.inf)
    return r.min(axis=1)


def test_the_fcc_crystal_has_four_sites_a_cell_and_its_nearest_neighbours_at_the_spacing():
    spacing = 1.15
    cell = spacing * ROOT2
    x = fcc_positions((3, 3, 3), cell)
    assert len(x) == 108 and len(np.unique(np.round(x, 9), axis=0)) == 108
    assert nearest(x, np.full(3, 3 * cell)) == pytest.approx(np.full(108, spacing), rel=1e-12)


def test_the_three_phase_start_is_a_periodic_crystal_then_a_liquid_as_dense_as_asked_then_vacuum():
    """The crystal wraps across the periodic sides without a gap, the liquid slab holds as many atoms as the crystal at
    LIQUID_DENSITY, no two atoms start closer than 0.95 sigma, and the vacuum is as thick as asked."""
    spacing, cells, layers = 1.15, 5, 4
    x, box = three_phase_positions(spacing, cells, layers, vacuum=12.0)
    crystal_atoms = 4 * cells * cells * layers
    assert len(x) == 2 * crystal_atoms
    assert box[0] == box[1] == pytest.approx(cells * spacing * ROOT2)
    crystal, liquid = x[:crystal_atoms], x[crystal_atoms:]
    assert nearest(crystal, np.array([box[0], box[1], 1e9])) == pytest.approx(np.full(crystal_atoms, spacing))
    assert nearest(x, box).min() > 0.95
    layers_z = np.unique(np.round(liquid[:, 2], 9))
    per_layer = np.count_nonzero(np.isclose(liquid[:, 2], layers_z[0]))
    assert per_layer / (box[0] * box[1] * np.diff(layers_z).mean()) == pytest.approx(LIQUID_DENSITY, rel=1e-9)
    assert box[2] - (x[:, 2].max() - x[:, 2].min()) == pytest.approx(12.0, abs=1.0)


def test_the_estimate_keeps_only_the_runs_that_kept_both_phases():
    run = lambda t, kept: ThreePhaseRun(0.5, t if kept else math.nan, 0.002, 0.5, 0.5, 0.0, kept, 10, 1, 1.0)  # noqa: E731
    assert triple_estimate([run(0.56, True), run(0.57, True), run(0.9, False)]) == pytest.approx(
        (0.565, np.std([0.56, 0.57], ddof=1))
    )
    assert all(math.isnan(v) for v in triple_estimate([run(0.9, False)]))


@pytest.mark.long
def test_three_phase_runs_settle_at_one_temperature_from_below_and_above():
    """Started colder and warmer, a small slab's constant-energy runs settle within 0.015 of each other between kT
    0.54 and 0.59 (the full study: 0.565 +- 0.005), the colder one by freezing liquid, the warmer by melting crystal;
    a start too warm for the small crystal melts it through, and the run says so."""
    spacing = zero_pressure_spacing(0.55, spacings=(1.12, 1.14, 1.16))
    assert 1.13 < spacing < 1.16
    cold, warm, hot = (run_three_phase(spacing, t, cells=5, layers=4, settle=20000) for t in (0.50, 0.56, 0.62))
    assert cold.coexisted and warm.coexisted
    assert 0.54 < cold.temperature < 0.59 and 0.54 < warm.temperature < 0.59
    assert abs(cold.temperature - warm.temperature) < 0.015
    assert cold.solid_last >= cold.solid_first - 0.05 and warm.solid_last <= warm.solid_first + 0.05
    assert not hot.coexisted and hot.solid_last < 0.1 and math.isnan(hot.temperature)
