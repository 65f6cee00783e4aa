"""``python -m calibration``: same as ``servobot calibrate``."""

import sys

from calibration.cli import main

sys.exit(main())
