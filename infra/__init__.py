"""Run infrastructure shared by every layer: atomic files, batches of independent runs, and how
a command ends (exit codes, Ctrl-C and SIGTERM).

Pure Python (no MuJoCo, no numba), so the table simulation, the physics side and the
applications all build on it without importing each other.
"""
