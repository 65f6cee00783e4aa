"""``servobot variant``: write a ServoBot variant as a complete MJCF file (or show one's).

::

    servobot variant [--torso-mass KG] [--leg-length M] [--servo-torque NM] [--servo-kp K]
                     [--foot-friction MU] [--floor-friction MU] --out FILE.xml [--force]
    servobot variant --show FILE.xml

Parses and prints; ``servo_mj.robot.variant`` builds the file from the shipped model with
``dm_control.mjcf``, checks that the robot stands and walks every gait, and writes it
atomically; an existing ``--out`` file is replaced only with ``--force``. Errors name each
parameter by its option (``--torso-mass``, not the field ``torso_mass_kg``). Every parameter's
unit, default and meaning: ``models/servobot/README.md``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from infra.io import check_output_file
from servo_mj.robot.variant import VariantError, VariantParams, read_variant, write_variant
from servobot.cli.runner import run_main

PROG = "servobot variant"

DEFAULTS = VariantParams()
OPTIONS = (
    ("--torso-mass", "torso_mass_kg", "KG", "torso mass incl. capacitors, kg"),
    ("--leg-length", "leg_length_m", "M", "foot reach from the thrust axis, m (legs scale)"),
    ("--servo-torque", "servo_torque_nm", "NM", "servo torque limit (stall torque), N·m"),
    ("--servo-kp", "servo_kp", "K", "position-servo stiffness kp, N·m/rad"),
    ("--foot-friction", "foot_friction", "MU", "feet sliding friction"),
    ("--floor-friction", "floor_friction", "MU", "floor sliding friction"),
)
"""(option, VariantParams field, metavar, help) of each parameter."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="servobot variant",
        description="Write a complete MJCF ServoBot variant (robot, floor, options) built from "
        "the shipped model; use it with calibrate/validate/reproduce --model FILE.",
    )
    for flag, field, metavar, help_ in OPTIONS:
        default = getattr(DEFAULTS, field)
        p.add_argument(flag, dest=field, type=float, default=default, metavar=metavar,
                       help=f"{help_} (default {default:g})")  # fmt: skip
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--out", type=Path, help="variant file to write (.xml)")
    what.add_argument("--show", type=Path, metavar="FILE", help="print the parameters of FILE")
    p.add_argument("--force", action="store_true", help="replace an existing --out file")
    return p


def params_from_args(args: argparse.Namespace) -> VariantParams:
    """The ``VariantParams`` of the options; ``VariantError`` naming the option as typed
    (``--torso-mass``) for a value that is not a finite number > 0."""
    for flag, field, _, _ in OPTIONS:
        v = getattr(args, field)
        if not math.isfinite(v) or v <= 0.0:
            raise VariantError(f"{flag} must be a finite number > 0, got {v:g}")
    return VariantParams(**{field: getattr(args, field) for _, field, _, _ in OPTIONS})


def options_label(params: VariantParams) -> str:
    """The variant as the options that make it, e.g. ``variant --torso-mass 0.9``."""
    flag = {field: f for f, field, _, _ in OPTIONS}
    changed = " ".join(f"{flag[k]} {v:g}" for k, v in params.changed().items())
    return f"variant {changed}" if changed else "the shipped robot"


def _print_params(params: VariantParams) -> None:
    for flag, field, _, help_ in OPTIONS:
        mark = "  (changed)" if field in params.changed() else ""
        print(f"  {flag[2:]:<15} {getattr(params, field):<10g} {help_}{mark}")
    if params.foot_friction != params.floor_friction:
        print(f"  foot-floor friction used by MuJoCo: {params.effective_friction:g} (the larger)")


def _run(args: argparse.Namespace) -> int:
    if args.show is not None:
        params = read_variant(args.show)
        if params is None:
            print(f"{args.show}: records no variant parameters (not a servobot variant file)")
            return 0
        print(f"{args.show}: ServoBot variant")
        _print_params(params)
        return 0
    params = params_from_args(args)
    check_output_file(args.out, option="--out")
    if args.out.exists() and not args.force:
        raise VariantError(f"--out {args.out}: the file exists; pass --force to replace it")
    path = write_variant(params, args.out, label=options_label(params))
    print(f"wrote {path}: it stands and walks every gait")
    _print_params(params)
    print(f"next: servobot calibrate --model {path} --out runs/calibration_{path.stem}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot variant``; 0 ok, 2 bad input or an impossible robot, 130 interrupted."""
    return run_main(PROG, build_parser(), argv, lambda args, _command: _run(args),
                    lambda _args: "nothing (the file is written only once checked)")  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
