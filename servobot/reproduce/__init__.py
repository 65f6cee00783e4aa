"""The end-to-end reproduction (``servobot reproduce``).

``settings`` holds its budgets and what each stage depends on, ``run`` the stages into one
resumable run folder, ``report`` the ``REPORT.md`` built from that folder.
"""
