"""Taichi particle sandbox: spring-bonded solids that heat, soften, melt and flow as a Lennard-Jones-style liquid."""

import os

# Taichi prints a banner when it is first imported; the sandbox's users see their own output instead (set
# ENABLE_TAICHI_HEADER_PRINT=1 to see it).
os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "False")

__version__ = "0.1.0"
