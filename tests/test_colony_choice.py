"""The colony's finalist chosen by physics (``servobot.validation.colony_choice``): the rule on
hand-made finalists, the confirmation's arguments, and a tiny choice confirmed end to end."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from evolve.codec import format_chromosome
from evolve.settings import ColonySettings, WorldSettings
from evolve.starts import colony_starts
from infra.errors import InputError
from servo_mj.world.arena import ArenaSettings
from servobot.cli import validate as validate_cli
from servobot.validation import colony_choice
from servobot.validation.colony_choice import (
    CONFIRM_SEED_OFFSET,
    ChoiceRule,
    choose,
    confirmation_of,
    main,
)
from tests.test_physics_colony import DOCKER


def row(name: str, inner: float, live: float, table_live: float | None = None) -> dict:
    fig = {"runs": 6, "inner_pct": inner, "docks_per_robot": 3.0, "live_per_run": live}
    return {
        "name": name,
        "physics": fig,
        "table": fig if table_live is None else {**fig, "live_per_run": table_live},
    }


def test_a_qualifying_finalist_beats_a_better_coverer_that_dies() -> None:
    rows = [row("pop0", 80.0, 1.9), row("pop1", 70.0, 2.0), row("pop2", 72.0, 2.5)]
    assert choose(rows) == 2  # pop0 covers most but misses 2 live; pop2 covers most of the rest
    assert choose(rows, ChoiceRule(min_live=1.5)) == 0
    assert choose(rows, ChoiceRule(min_live=2.6)) == 2  # none qualifies: the most live


def test_without_a_qualifier_ties_in_lives_go_to_coverage() -> None:
    rows = [row("pop0", 60.0, 1.0), row("pop1", 65.0, 1.0), row("pop2", 90.0, 0.5)]
    assert choose(rows) == 1
    with pytest.raises(InputError, match="no finalist"):
        choose([])


def test_by_table_the_table_worlds_runs_choose() -> None:
    rows = [row("pop0", 70.0, 2.2, table_live=1.0), row("pop1", 75.0, 0.5, table_live=2.5)]
    assert choose(rows) == 0
    assert choose(rows, ChoiceRule(world="table")) == 1
    with pytest.raises(InputError, match="choice world"):
        ChoiceRule(world="sim")


def report(chromosome: str, **changes) -> dict:
    settings = {
        "PhysicsSettings": "default",
        "model": "shipped ServoBot (models/servobot)",
        "ArenaSettings": {"station_height_m": 0.3},
        "WorldSettings": {"start_power_v": 3.9},
        "max_steps": 40,
        "seed": 7,
        "ColonySettings": {
            "robots": 3,
            "blocking": "slide",
            "start_power_spread": 0.5,
            "robots_seen": False,
            "contact_yaw_deg": 9.3,
        },
    }
    return {
        "settings": {**settings, **changes},
        "table": {"source": "paper"},
        "meta": {"chromosome_file": chromosome},
    }


def test_confirmation_takes_every_setting_of_the_validation(tmp_path) -> None:
    chromosome = tmp_path / "c.txt"
    chromosome.write_text(format_chromosome(DOCKER))
    c = confirmation_of(report(str(chromosome)), tmp_path)
    assert c.chromosome == chromosome and c.table == "paper" and c.max_steps == 40
    assert c.colony == ColonySettings(
        robots=3, blocking="slide", start_power_spread=0.5, robots_seen=False, contact_yaw_deg=9.3
    )
    assert c.world == dataclasses.replace(WorldSettings(), start_power_v=3.9)
    assert c.arena == dataclasses.replace(ArenaSettings(), station_height_m=0.3)
    # the reproduction's reports name the chromosome relative to the run folder
    run = tmp_path / "run"
    (run / "colony").mkdir(parents=True)
    (run / "colony" / "best_pop2.txt").write_text(format_chromosome(DOCKER))
    rep = {**report("x"), "meta": {"finalist": 2, "source": "colony/best_pop2.txt"}}
    got = confirmation_of(rep, run / "colony_validation" / "pop2")
    assert got.chromosome == run / "colony" / "best_pop2.txt"


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"model": "models/long_legs.xml"}, "another robot model"),
        ({"PhysicsSettings": {"servo_noise_rad": 0.1}}, "another robot model"),
        ({"meta": {}}, "names no chromosome"),
        ({"meta": {"chromosome_file": "gone.txt"}}, "gone.txt is gone"),
        ({"table": {"source": "runs/gone/gait_table.json"}}, "gait table file .* is gone"),
    ],
)
def test_confirmation_refuses_what_it_cannot_repeat(tmp_path, changes, match) -> None:
    chromosome = tmp_path / "c.txt"
    chromosome.write_text(format_chromosome(DOCKER))
    rep = report(str(chromosome))
    for key in ("meta", "table"):
        if key in changes:
            rep[key] = changes.pop(key)
    rep["settings"].update(changes)
    with pytest.raises(InputError, match=match):
        confirmation_of(rep, tmp_path)


def test_choice_confirmed_end_to_end(tmp_path, capsys) -> None:
    """Two finalists validated by ``servobot validate --robots 3`` (1 start, 2 steps): the
    choice is written, and its confirmation reruns the chosen one with its settings from fresh
    starts of the validation's seed + 1000."""
    chromosome = tmp_path / "c.txt"
    chromosome.write_text(format_chromosome(DOCKER))
    val = tmp_path / "val"
    options = "--robots 3 --blocking slide --robots-unseen --starts 1 --steps 2 --seed 3"
    for k in range(2):
        argv = [str(chromosome), *options.split(), "--workers", "1", "--no-progress"]
        assert validate_cli.main([*argv, "--out", str(val / f"pop{k}")]) == 0
    capsys.readouterr()
    assert main([str(val), "--confirm", "1", "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    doc = json.loads((val / "choice" / "choice.json").read_text())
    assert doc["chosen"] == "pop0" and [r["name"] for r in doc["finalists"]] == ["pop0", "pop1"]
    assert (val / "choice" / "choice.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert doc["confirmation"]["seed"] == 3 + CONFIRM_SEED_OFFSET
    again = json.loads((val / "choice" / "confirm" / "report.json").read_text())
    colony = ColonySettings(robots=3, blocking="slide", robots_seen=False)
    want = colony_starts(np.random.default_rng(3 + CONFIRM_SEED_OFFSET), 1, WorldSettings(), colony)
    got = [[[p[k] for k in "xyh"] for p in r["start"]] for r in again["runs"]]
    np.testing.assert_allclose(got, want)
    assert again["settings"]["ColonySettings"]["robots_seen"] is False
    assert again["settings"]["max_steps"] == 2
    assert "**(chosen)**" in printed and "Confirmation on 1 fresh colony starts" in printed
    assert printed == (val / "choice" / "choice.md").read_text()

    # A finished confirmation is kept: the same command again runs no physics.
    def refuse(*args, **kwargs):
        pytest.fail("confirmation run again")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(colony_choice, "execute", refuse)
        assert main([str(val), "--confirm", "1"]) == 0
        with pytest.raises(pytest.fail.Exception):  # another seed is another confirmation
            main([str(val), "--confirm", "1", "--confirm-seed", "5"])


def test_bad_inputs_exit_2_naming_them(tmp_path, capsys) -> None:
    assert main([str(tmp_path)]) == 2
    assert "no report.json" in capsys.readouterr().err
    assert main([str(tmp_path), "--min-live", "-1"]) == 2
    assert "--min-live" in capsys.readouterr().err
    assert main([str(tmp_path), "--confirm", "-2"]) == 2
    assert "--confirm" in capsys.readouterr().err


def test_the_reports_line_names_why_nothing_was_chosen(tmp_path) -> None:
    assert colony_choice.choice_line(tmp_path, 3).startswith("*(no finalist chosen by physics:")
