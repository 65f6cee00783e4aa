"""``python -m servobot COMMAND ...``: the ``servobot`` command without the installed script."""

import sys

from servobot.cli import main

sys.exit(main())
