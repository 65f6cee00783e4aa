"""Validation of evolved controllers: each start in the table world and in physics.

``lone`` runs one robot per start (``validate``), ``colony`` R robots per start
(``validate_colony``); ``report`` and ``colony_report`` turn their per-run records into
summaries, the table-vs-physics gap and files; ``bench`` measures a validation run's cost.
"""
