"""The ``servobot`` dispatcher: usage, unknown commands, and lazy imports."""

import sys

from servobot import cli


def test_usage_lists_every_command(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in cli.COMMANDS:
        assert name in out


def test_no_command_is_a_usage_error(capsys):
    assert cli.main([]) == 2


def test_unknown_command_names_it(capsys):
    assert cli.main(["fly"]) == 2
    assert "unknown command 'fly'" in capsys.readouterr().err


def test_dispatch_does_not_import_mujoco_for_evolve_help(capsys):
    before = "mujoco" in sys.modules
    try:
        cli.main(["evolve", "--help"])
    except SystemExit:
        pass
    assert before or "mujoco" not in sys.modules
