"""Anytime learning with MuJoCo as the real robot (``servobot anytime``).

``run`` holds the run folder, the physics punctuations and the final test; ``report`` the
summary and figure; ``bench`` the measurement of every method on the same seeds.
"""
