"""Physics passes. Each module owns its fields and offers per-particle `ti.func` contributions; simulation.py fuses
the contributions a scene needs into as few kernels per step as possible (a kernel launch costs about 20 us)."""
