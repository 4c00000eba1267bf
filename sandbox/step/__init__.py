"""Stepping: the rates of a step (rates.py) and the three ways of running steps (long_way.py, one launch per pass;
fused.py, many steps to a launch on one thread; team.py, many steps to a launch on every thread), chosen by what
each pass declares about itself (plan.py)."""
