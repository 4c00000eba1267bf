"""What a simulation measures: the terms' measures composed into one kernel (diagnostics.py), the readouts of an
instant (stats.py: Stats and the CSV's columns) and the blow-up guard's limits and verdict (guard.py)."""
