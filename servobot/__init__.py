"""The applications on top of the libraries: physics validation, rerun recordings, the
end-to-end reproduction and the ``servobot`` command line (``servobot.cli``).

Nothing below this package imports it.
"""
