"""Run infrastructure shared by every layer: atomic files and batches of independent runs.

Pure Python (no MuJoCo, no numba), so the table simulation, the physics side and the
applications all build on it without importing each other.
"""
