"""Measuring the sandbox: benchmarks (bench.py, launch_count.py), the integrator and phase-change studies (study*.py,
heat_study.py, phase_study.py) and where they run (dask_pool.py)."""
