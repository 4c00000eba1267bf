"""The front-ends: the command line (cli*.py), the headless runner and its files (runner.py, run_files.py), the window
(window*.py, tools.py, probe.py, history.py) and sweeps (sweep*.py). They wire a Simulation to a Renderer."""
