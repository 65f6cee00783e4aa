"""A colony team of liver and coverer (``servobot.validation.colony_team``): the roles on
hand-made finalists, the team's layout, validations that do not compare refused, the stage's
table test, and a tiny team run end to end."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from evolve.codec import format_chromosome, parse_chromosome
from evolve.colony_stage import final_test
from evolve.population import stage_seeds
from evolve.settings import ColonySettings, GASettings, WorldSettings
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE, GaitTable
from infra.errors import InputError
from servobot.cli import validate as validate_cli
from servobot.validation import colony_team
from servobot.validation.colony_choice import CONFIRM_SEED_OFFSET
from servobot.validation.colony_team import (
    TeamRule,
    finalists,
    main,
    physics_settings,
    pick,
    stage_table_test,
    team_files,
)
from tests.chromosome_text import G, chrom, gene
from tests.test_colony_choice import report, row
from tests.test_physics_colony import DOCKER

WALKER = chrom(gene("00", G(8), G(8), G(8), G(8)))
"""Walks straight ahead forever."""


def test_the_liver_lives_and_the_coverer_covers() -> None:
    rows = [
        row("pop0", 80.0, 0.5),
        row("pop1", 70.0, 2.2),
        row("pop2", 72.0, 2.0),
        row("pop3", 75.0, 1.9),
    ]
    assert pick(rows) == (2, 0)  # pop2: the most coverage with ≥ 2 live; pop0: the most coverage
    assert pick(rows, TeamRule(min_live=2.1)) == (1, 0)
    assert pick(rows, TeamRule(min_live=2.5)) == (1, 0)  # none qualifies: the most live
    # One finalist both lives and covers most: the team is that finalist alone.
    assert pick([row("pop0", 60.0, 2.0), row("pop1", 65.0, 2.1)]) == (1, 1)


def test_the_coverer_rides_the_last_robots(tmp_path) -> None:
    liver, coverer = tmp_path / "l.txt", tmp_path / "c.txt"
    assert team_files(liver, coverer, 3, 1) == [liver, liver, coverer]
    assert team_files(liver, coverer, 3, 0) == [liver] * 3
    assert team_files(liver, coverer, 3, 3) == [coverer] * 3
    with pytest.raises(InputError, match="--coverers 4: a colony of 3 robots"):
        team_files(liver, coverer, 3, 4)
    with pytest.raises(InputError, match="coverers"):
        TeamRule(coverers=-1)


def test_validations_compare_when_only_their_table_world_differs(tmp_path) -> None:
    a, b = (
        {**report(f), "runs": [{"start": [{"x": 400.0, "y": 250.0, "h": 90.0}]}]}
        for f in ("a.txt", "b.txt")
    )
    b["settings"]["ColonySettings"] = {
        **b["settings"]["ColonySettings"],
        "blocking": "cancel",
        "contact_yaw_deg": 0.0,
    }
    assert physics_settings(a) == physics_settings(b)
    b["settings"]["ColonySettings"]["start_power_spread"] = 0.0  # physics reads this one
    assert physics_settings(a) != physics_settings(b)
    b["settings"]["ColonySettings"]["start_power_spread"] = 0.5
    b["runs"][0]["start"][0]["h"] = 91.0
    assert physics_settings(a) != physics_settings(b)


def validate(chromosome, out, seed: int = 3, *extra: str) -> None:
    options = f"--robots 3 --blocking slide --robots-unseen --starts 1 --steps 2 --seed {seed}"
    argv = [str(chromosome), *options.split(), *extra, "--workers", "1", "--no-progress"]
    assert validate_cli.main([*argv, "--out", str(out)]) == 0


def test_finalists_of_runs_that_started_apart_are_refused(tmp_path) -> None:
    c = tmp_path / "c.txt"
    c.write_text(format_chromosome(DOCKER))
    validate(c, tmp_path / "a" / "pop0")
    validate(c, tmp_path / "b" / "pop0", 3, "--contact-yaw", "9.3")  # table only: compares
    validate(c, tmp_path / "c" / "pop0", 4)  # other starts
    paths, _, rows = finalists([tmp_path / "a", tmp_path / "b"])
    assert [r["name"] for r in rows] == ["a/pop0", "b/pop0"]
    with pytest.raises(InputError, match=r"c/pop0/report.json: its physics ran otherwise .*seed"):
        finalists([tmp_path / "a", tmp_path / "c"])


def test_the_stage_table_test_of_a_team_of_one_finalist_is_the_finalists(tmp_path) -> None:
    """A team whose robots all carry one finalist is that finalist's colony: the test equals
    ``final_test``'s homogeneous colony on the stage's test starts (``stage_seeds`` child 0)."""
    stage = tmp_path / "run" / "colony"
    stage.mkdir(parents=True)
    world, ga = WorldSettings(), GASettings(populations=2, test_starts=6, seed=5)
    colony = ColonySettings(robots=3, blocking="slide", start_power_spread=0.5)
    doc = {
        "stage": "colony",
        "WorldSettings": dataclasses.asdict(world),
        "ColonySettings": dataclasses.asdict(colony),
        "GASettings": dataclasses.asdict(ga),
        "table": {"source": "paper", "values": PAPER_TABLE.tolist()},
    }
    (stage / "settings.json").write_text(json.dumps(doc))
    finalist = stage / "best_pop1.txt"
    finalist.write_text(format_chromosome(DOCKER))
    got = stage_table_test(finalist, [finalist] * 3)
    seq, _ = stage_seeds(5, "colony", 2)
    starts = colony_starts(np.random.Generator(np.random.PCG64(seq)), 6, world, colony)
    want = final_test(DOCKER[None], starts, GaitTable(PAPER_TABLE), world, colony)[0]
    assert got["starts"] == 6 and got["stage"] == str(stage)
    for key in ("colony_inner_percent", "live_at_end_per_run", "docks_per_robot", "ends"):
        assert got[key] == want[key], key
    # A coverer of its own changes the colony; a file outside a stage folder has no test.
    walker = tmp_path / "w.txt"
    walker.write_text(format_chromosome(WALKER))
    mixed = stage_table_test(finalist, [finalist, finalist, walker])
    assert mixed["colony_inner_percent"] != got["colony_inner_percent"]
    assert stage_table_test(walker, [walker] * 3) is None


def test_a_team_run_end_to_end(tmp_path, capsys, monkeypatch) -> None:
    """Two finalists validated (1 start, 2 steps): the team (pop0 the liver, pop1 the coverer)
    runs from their start and from a fresh one of seed + 1000, robot 2 carrying the coverer."""
    val = tmp_path / "val"
    for k, bits in enumerate((DOCKER, WALKER)):
        path = tmp_path / f"c{k}.txt"
        path.write_text(format_chromosome(bits))
        validate(path, val / f"pop{k}")
    capsys.readouterr()
    monkeypatch.setattr(colony_team, "pick", lambda rows, rule=None: (0, 1))
    assert main([str(val), "--confirm", "1", "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    out = val / "team"
    doc = json.loads((out / "team.json").read_text())
    assert (doc["liver"], doc["coverer"]) == ("pop0", "pop1")
    assert doc["team"] == [str(tmp_path / f"c{k}.txt") for k in (0, 0, 1)]
    assert doc["table_test"] is None
    assert (out / "team.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    same = json.loads((out / "team" / "report.json").read_text())
    first = json.loads((val / "pop0" / "report.json").read_text())
    assert same["runs"][0]["start"] == first["runs"][0]["start"]
    robots = same["chromosome"].split("# robot ")[1:]
    assert [parse_chromosome(r.split("\n", 1)[1]).tolist() for r in robots] == [
        DOCKER.tolist(),
        DOCKER.tolist(),
        WALKER.tolist(),
    ]
    fresh = json.loads((out / "confirm" / "report.json").read_text())
    colony = ColonySettings(robots=3, blocking="slide", robots_seen=False)
    want = colony_starts(np.random.default_rng(3 + CONFIRM_SEED_OFFSET), 1, WorldSettings(), colony)
    np.testing.assert_allclose([[p[k] for k in "xyh"] for p in fresh["runs"][0]["start"]], want[0])
    assert doc["confirmation"]["seed"] == 3 + CONFIRM_SEED_OFFSET
    assert "**(liver)**" in printed and "**(coverer)**" in printed
    assert printed == (out / "team.md").read_text()
    line = colony_team.team_line(val, 3)
    assert (
        "robots 0–1 carry the liver **pop0** (as chosen above), robot 2 the coverer **pop1**"
        in line
    )


def test_bad_inputs_exit_2_naming_them(tmp_path, capsys) -> None:
    assert main([str(tmp_path)]) == 2
    assert "no report.json" in capsys.readouterr().err
    assert main([str(tmp_path), "--coverers", "-1"]) == 2
    assert "coverers" in capsys.readouterr().err
    assert main([str(tmp_path), "--min-live", "-1"]) == 2
    assert "min_live" in capsys.readouterr().err


def test_the_reports_line_names_why_no_team_was_made(tmp_path) -> None:
    assert colony_team.team_line(tmp_path, 3).startswith("*(no team made by physics:")


def test_the_team_runs_from_the_finalists_own_starts_however_drawn(tmp_path) -> None:
    """A validation from given poses (``--start``, as the reproduction's colony validation runs
    its own seeded starts): the team's ``team/`` run starts where the finalists did."""
    c = tmp_path / "c.txt"
    c.write_text(format_chromosome(DOCKER))
    poses = [[400.0, 200.0, 90.0], [400.0, 300.0, 90.0], [360.0, 250.0, 0.0]]
    argv = [str(c), "--robots", "3", "--steps", "2", "--workers", "1", "--no-progress"]
    for pose in poses:
        argv += ["--start", *map(str, pose)]
    assert validate_cli.main([*argv, "--out", str(tmp_path / "val" / "pop0")]) == 0
    assert main([str(tmp_path / "val"), "--workers", "1"]) == 0
    same = json.loads((tmp_path / "val" / "team" / "team" / "report.json").read_text())
    got = [[p[k] for k in "xyh"] for p in same["runs"][0]["start"]]
    np.testing.assert_allclose(got, poses)
