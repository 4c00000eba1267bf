"""The heating study's report (sandbox study --heating, research/heating_curve.py) says what its runs measured: a
"boiling liquid" above the model's critical point is no boiling point (issue 75)."""

from __future__ import annotations

import numpy as np


def test_the_heating_study_says_when_its_boiling_liquid_was_above_the_critical_point():
    """`sandbox study --heating --quick` printed a "boiling liquid" at kT 1.35 under both lids as if it were a boiling
    point: above the model's critical point (kT 0.93) nothing boils. The line and the report now say so, for that
    run only."""
    from sandbox.research.heating_curve import HeatingRun, report, said

    def run(pressure: float, liquid_kt: float) -> HeatingRun:
        gas = np.linspace(0.0, 1.0, 11)  # rows 2..8 are the boiling stage (20-80% gas)
        flat = np.full(11, liquid_kt)
        return HeatingRun(pressure, 2.0, 63, np.arange(11.0), flat, flat, np.zeros(11), gas, np.full(11, 5.0), 1.0)

    honest, quick = run(0.03, 0.80), run(0.03, 1.35)
    assert "critical" not in said(honest)
    assert "above the model's critical point, kT 0.93: no liquid boils there" in said(quick)
    text = report([honest, quick])
    assert text.count("above the model's critical point") == 1
