"""What every layer above stands on: the Taichi runtime and its internals in one place (runtime.py, taichi_compat.py),
batched host copies (transfer.py), the Model (what a scene fixes) and the State (what a step changes, declared entry
by entry), particle and spring storage, the domain box, loop policy, threads and the CG driver."""
