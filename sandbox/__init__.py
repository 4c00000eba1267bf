"""Taichi particle sandbox: spring-bonded solids that heat, soften, melt and flow as a Lennard-Jones-style liquid."""

import os
import tempfile

# Taichi prints a banner when it is first imported; the sandbox's users see their own output instead (set
# ENABLE_TAICHI_HEADER_PRINT=1 to see it).
os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "False")
if not os.environ.get("HOME"):  # importing Taichi aborts the process without it (cron jobs, services)
    os.environ["HOME"] = tempfile.gettempdir()

__version__ = "0.1.0"
