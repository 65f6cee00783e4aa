"""Validation of evolved controllers: each start in the table world and in physics.

``lone`` runs one robot per start (``validate``), ``colony`` R robots per start
(``validate_colony``); ``report`` and ``colony_report`` turn their per-run records into
summaries, the table-vs-physics gap and files; ``colony_pool`` pools colony validations
(``python -m servobot.validation.colony_pool``); ``bench`` measures a validation run's cost.
"""
