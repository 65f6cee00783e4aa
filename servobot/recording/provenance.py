"""What made a recording: the robot model, the gait table and the command, as properties.

Every recording names them (``provenance``; a calibration's table is the one it measured)::

    model    label (``shipped ServoBot (models/servobot)`` or the model file), sha256
             (``servo_mj.robot.model.model_sha256``)
    table    source (``paper``, a calibration file, or ``array``), sha256 of its values
             (``table_sha256``)
    command  text: the command line that made the recording (given, else ``sys.argv``)
"""

from __future__ import annotations

import hashlib
import shlex
import sys
from typing import Any

import numpy as np


def table_sha256(values: Any) -> str:
    """SHA-256 of a gait table's values: the (16, 3) F, T, dH as little-endian float64, row
    by row (the same for the same numbers, whatever file or array they came from)."""
    arr = np.ascontiguousarray(np.asarray(values, dtype="<f8"))
    return hashlib.sha256(arr.tobytes()).hexdigest()


def command_text(command: str | None = None) -> str:
    """``command``, or this process's command line (``sys.argv``, shell-quoted) when None."""
    return command if command else shlex.join(sys.argv)


def provenance(
    *, model: str | None, table: Any, table_source: str, command: str | None
) -> dict[str, dict[str, str]]:
    """The ``model``, ``table`` and ``command`` properties of a recording: ``model`` is a model
    file (None = the shipped ServoBot), ``table`` the (16, 3) values the table world used (or
    that a calibration measured)."""
    from servo_mj.robot.model import model_label, model_sha256

    return {
        "model": {"label": model_label(model), "sha256": model_sha256(model)},
        "table": {"source": str(table_source), "sha256": table_sha256(table)},
        "command": {"text": command_text(command)},
    }


__all__ = ["command_text", "provenance", "table_sha256"]
