"""Taichi particle sandbox: spring-bonded solids that heat, soften, melt and flow as a Lennard-Jones-style liquid."""

__version__ = "0.1.0"
