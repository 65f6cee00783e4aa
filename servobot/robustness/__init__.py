"""The physics test matrix (SPEC §9, last bullet): controllers × named physics worlds.

``worlds`` holds the frozen registry of physics worlds (``shipped``, ``station-seen``,
``heavy``, ``weak``, ``slippery`` and the held-out ``long-legs``), ``matrix`` runs every
controller in each of them through ``servobot.validation.lone.validate`` (``run_matrix``), and
``report`` writes ``robustness.{json,md,png}``. The command is ``servobot robustness``
(``servobot.cli.robustness``); see docs/robustness.md.
"""
