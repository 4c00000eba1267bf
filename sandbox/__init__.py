"""Taichi particle sandbox: spring-bonded solids that heat, soften, melt and flow as a Lennard-Jones-style liquid."""

import importlib
import os
import tempfile

# Taichi prints a banner when it is first imported; the sandbox's users see their own output instead (set
# ENABLE_TAICHI_HEADER_PRINT=1 to see it).
os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "False")
# ... and info lines such as "Graphical python shell detected" in Jupyter: only its errors reach the user.
os.environ.setdefault("TI_LOG_LEVEL", "error")
if not os.environ.get("HOME"):  # importing Taichi aborts the process without it (cron jobs, services)
    os.environ["HOME"] = tempfile.gettempdir()

__version__ = "0.1.0"

# The Python API (sandbox/api.py), imported on first use so that `import sandbox` stays light.
__all__ = [
    "Cache",
    "FrameTable",
    "Simulation",
    "load",
    "material_names",
    "own_process",
    "plateau",
    "resume",
    "scene_names",
    "use",
]
_EXPORTS = {
    "load": "api",
    "resume": "api",
    "scene_names": "api",
    "material_names": "api",
    "use": "api",
    "own_process": "core.runtime",
    "Simulation": "simulation",
    "FrameTable": "files.table",
    "plateau": "measure.curves",
    "Cache": "caching",
}


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module 'sandbox' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
