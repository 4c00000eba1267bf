"""Scenes as data: TOML read and validated into typed, frozen tables (scene.py, schema.py, scene_tables.py), materials,
the particles and springs a scene builds (build.py, NumPy), size budgets, shipped resources, checked arguments.
No Taichi here."""
