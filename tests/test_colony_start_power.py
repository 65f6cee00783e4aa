"""The colony's start layout for power (``ColonySettings.start_power_spread``, issue 17
"learning to share"): robot i of R starts with min(P0 + i × spread, ``charged_power_v``),
never below P0. Hand-worked colonies in the interpreter and the kernel (4.0/4.5/5.0 V, the cap
at 5.0 V), the kernel against the interpreter on random colonies with a spread, spread 0 as
before bit for bit (R = 1 the lone robot, the short stage's history of before), the physics
colony's robots starting on the same powers, the setting's validation and record, resume of a
folder written before the field existed, and the CLI options."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, STILL, B, G, chrom, gene
from test_colony_fitness import HISTORY_BEFORE, interrupted_colony_stage, tiny_colony_cli
from test_colony_kernel import NEAR_STATION

from evolve.codec import LOW_POWER, parse_chromosome, write_chromosome
from evolve.colony_stage import run_colony_stage
from evolve.evaluation import evaluate, evaluate_colony
from evolve.interpreter import END_POWER_EMPTY, END_STEP_LIMIT, run_colony
from evolve.settings import ColonySettings, GASettings, SettingsError, WorldSettings, settings_json
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE, load_table
from evolve.world import TableColony
from infra.errors import InputError

WORLD = WorldSettings()
STAND = np.zeros((16, 3))
"""Every gait stands still (and every gait but 7 costs 0.0209 V: the paper's power model)."""
LOW_TEST = chrom(gene("00", B(4, 0), G(0), G(0), G(0)), *[STILL] * 7, gene("00", *[G(0)] * 4))
"""Gene 0 forever: if low-power goto gene 8 (navigation), then 3 paid gait cycles; gene 8
takes paid gait 0 cycles forever (standing still on ``STAND``, far from the station)."""
THREE = np.array([[100.0, 100.0, 0.0], [250.0, 250.0, 90.0], [400.0, 400.0, 180.0]])
"""Three robots far apart and from every wall."""
SPREAD = ColonySettings(start_power_spread=0.5)
ROBOT_FIELDS = ("robot_squares", "steps", "docks", "end", "collisions", "station_waits")
"""``ColonyEvaluation`` per-robot fields, in the order of ``RunResult``'s compared below."""


def events_of(colony, *, max_steps, starts=THREE, world=WORLD, **kw):
    """(interpreter result, each robot's ``StepEvent`` list) of ``LOW_TEST`` standing still."""
    events = [[] for _ in range(colony.robots)]
    table = TableColony(STAND, starts, world, colony)
    res = run_colony(LOW_TEST, table, colony=colony, settings=world, max_steps=max_steps,
                     on_event=lambda e: events[e.robot].append(e.event), **kw)  # fmt: skip
    return res, events


def first_taken_step(events):
    """Gait steps a robot took before its low-power branch was first taken."""
    return next(e.step for e in events if e.kind == "branch" and e.text.endswith("taken")
                and "not" not in e.text)  # fmt: skip


# --------------------------------------------------------------------------- hand-worked


def test_spread_half_a_volt_starts_three_robots_on_4_4_5_and_5_volts():
    assert SPREAD.start_powers(4.0, 5.0) == (4.0, 4.5, 5.0)
    res, events = events_of(SPREAD, max_steps=120)
    # each robot's first event: its low-power test on its start power, not taken (4.0 V is
    # not below the 4.0 V threshold; 4.5 and 5.0 V are far above it)
    firsts = [ev[0] for ev in events]
    assert [e.kind for e in firsts] == ["branch"] * 3
    assert [e.power for e in firsts] == [4.0, 4.5, 5.0]
    assert all(e.text.endswith("not taken") and not e.sensors & LOW_POWER for e in firsts)
    # its first gait cycle pays 0.0209 V from there
    gaits = [next(e for e in ev if e.kind == "gait") for ev in events]
    assert [e.power for e in gaits] == [4.0 - 0.0209, 4.5 - 0.0209, 5.0 - 0.0209]
    # the test is taken at the first test below 4.0 V (one every 3 gait cycles): after 3
    # cycles from 4.0 V, 24 from 4.5 V (4.5 − 24 × 0.0209 = 3.998), 48 from 5.0 V (3.997)
    assert [first_taken_step(ev) for ev in events] == [3, 24, 48]
    # power empty (below 2.7 V) after 63, 87 and 111 paid cycles: (P − 2.7) / 0.0209 = 62.2,
    # 86.1, 110.0; none reaches the 120-step limit
    assert [(r.steps, r.end) for r in res.robots] == [(63, END_POWER_EMPTY), (87, END_POWER_EMPTY),
                                                      (111, END_POWER_EMPTY)]  # fmt: skip
    ev = evaluate_colony(LOW_TEST[None], THREE[None], table=STAND, mode="coverage",
                         max_steps=120, colony=SPREAD)  # fmt: skip
    assert ev.steps[0, 0].tolist() == [63, 87, 111]
    assert ev.end[0, 0].tolist() == [END_POWER_EMPTY] * 3


def test_start_powers_are_capped_at_the_charged_level():
    capped = ColonySettings(start_power_spread=0.8)
    assert capped.start_powers(4.0, 5.0) == (4.0, 4.8, 5.0)  # 4.0 + 2 × 0.8 = 5.6 → 5.0
    res, events = events_of(capped, max_steps=120)
    assert [ev[0].power for ev in events] == [4.0, 4.8, 5.0]
    # 4.8 V: (4.8 − 2.7) / 0.0209 = 100.5 → empty after 101 cycles; 5.0 V as above
    assert [r.steps for r in res.robots] == [63, 101, 111]
    ev = evaluate_colony(LOW_TEST[None], THREE[None], table=STAND, mode="coverage",
                         max_steps=120, colony=capped)  # fmt: skip
    assert ev.steps[0, 0].tolist() == [63, 101, 111]
    # a smaller charged level caps lower; the cap never takes a robot below P0
    assert capped.start_powers(4.0, 4.5) == (4.0, 4.5, 4.5)
    assert capped.start_powers(5.5, 5.0) == (5.5, 5.5, 5.5)
    assert SPREAD.start_powers(3.95, 5.0) == (3.95, 4.45, 4.95)
    assert ColonySettings(robots=5, start_power_spread=0.25).start_powers(4.0, 5.0) == (
        4.0, 4.25, 4.5, 4.75, 5.0
    )  # fmt: skip
    # the world's charged level caps the interpreter's robots too
    half = dataclasses.replace(WORLD, charged_power_v=4.6)
    _, events = events_of(capped, max_steps=1, world=half)
    assert [ev[0].power for ev in events] == [4.0, 4.6, 4.6]


def test_the_start_power_argument_is_robot_0s():
    _, events = events_of(SPREAD, max_steps=1, start_power=3.95)
    assert [ev[0].power for ev in events] == [3.95, 4.45, 4.95]
    assert events[0][0].text.endswith(": taken") and events[1][0].text.endswith("not taken")
    ev = evaluate_colony(LOW_TEST[None], THREE[None], table=STAND, mode="coverage",
                         max_steps=120, colony=SPREAD, start_power=3.95)  # fmt: skip
    res, _ = events_of(SPREAD, max_steps=120, start_power=3.95)
    assert ev.steps[0, 0].tolist() == [r.steps for r in res.robots]


# --------------------------------------------------------------------------- kernel = interpreter


def test_kernel_equals_the_interpreter_on_random_colonies_with_a_spread():
    """1,200 colony runs with spread 0.5 (half near the station, switching to navigation as
    soon as a robot is low, so that robots dock, charge and wait; a quarter from 3.95 V and
    under a colony-step limit): every robot's squares, steps, docks, end, collisions, waits and
    final pose equal bit for bit."""
    rng = np.random.default_rng(2024)
    genomes = rng.integers(0, 2, size=(300, 16, 30), dtype=np.uint8)
    genomes[:150, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    limited = dataclasses.replace(SPREAD, colony_step_limit=60)
    cases = [
        (SPREAD, colony_starts(rng, 1, WORLD, SPREAD), 4.0),
        (SPREAD, colony_starts(rng, 2, NEAR_STATION, SPREAD), 4.0),
        (limited, colony_starts(rng, 1, NEAR_STATION, limited), 3.95),
    ]
    docks = 0
    ends = set()
    for colony, starts, power in cases:
        ev = evaluate_colony(genomes, starts, table=PAPER_TABLE, mode="coverage",
                             start_power=power, colony=colony)  # fmt: skip
        for i in range(genomes.shape[0]):
            for s in range(starts.shape[0]):
                res = run_colony(genomes[i], TableColony(PAPER_TABLE, starts[s], WORLD, colony),
                                 colony=colony, start_power=power)  # fmt: skip
                where = (i, s, power)
                assert res.squares == ev.squares[i, s], where
                assert res.inner_squares == ev.inner_squares[i, s], where
                assert res.colony_steps == ev.colony_steps[i, s], where
                for r, rob in enumerate(res.robots):
                    got = (rob.squares, rob.steps, rob.docks, rob.end, rob.collisions,
                           rob.station_waits)  # fmt: skip
                    want = tuple(getattr(ev, f)[i, s, r] for f in ROBOT_FIELDS)
                    assert got == want, (where, r)
                    assert tuple(rob.final_pose) == tuple(ev.final_pose[i, s, r]), (where, r)
                    ends.add(rob.end)
                docks += sum(r.docks for r in res.robots)
    assert docks > 50 and {END_POWER_EMPTY, END_STEP_LIMIT} <= ends


# --------------------------------------------------------------------------- spread 0 = before


def test_spread_zero_is_every_robot_on_the_start_power():
    assert ColonySettings().start_power_spread == 0.0
    assert ColonySettings().start_powers(4.0, 5.0) == (4.0, 4.0, 4.0)
    assert ColonySettings().start_powers(5.5, 5.0) == (5.5, 5.5, 5.5)  # no cap without spread
    _, events = events_of(ColonySettings(), max_steps=1)
    assert [ev[0].power for ev in events] == [4.0] * 3


def test_one_robot_with_any_spread_is_the_lone_robot():
    rng = np.random.default_rng(1719)
    genomes = rng.integers(0, 2, size=(200, 16, 30), dtype=np.uint8)
    genomes[:70, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]
    kw = dict(table=PAPER_TABLE, mode="coverage", start_power=3.95)
    for spread in (0.0, 0.7):
        one = ColonySettings(robots=1, start_power_spread=spread)
        starts = colony_starts(rng, 4, NEAR_STATION, one)
        col = evaluate_colony(genomes, starts, colony=one, **kw)
        lone = evaluate(genomes, starts[:, 0], **kw)
        np.testing.assert_array_equal(col.squares, lone.squares)
        np.testing.assert_array_equal(col.docks[..., 0], lone.docks)
        np.testing.assert_array_equal(col.end[..., 0], lone.end)
        assert lone.docks.sum() > 20


NAV = parse_chromosome(LIGHT_FOLLOWER)
TABLE = load_table("paper")
TINY = GASettings(populations=1, population_size=10, generations=6, test_starts=4, seed=2)


def test_spread_zero_writes_the_history_of_before(tmp_path):
    """The short stage of ``test_colony_fitness`` with ``start_power_spread`` 0 given
    explicitly: the history the code before the setting wrote; with a spread it differs."""
    ga = GASettings(populations=1, population_size=12, generations=6, test_starts=4, seed=5)
    run_colony_stage(tmp_path / "zero", navigation=NAV, table=TABLE, ga=ga,
                     colony=ColonySettings(start_power_spread=0.0))  # fmt: skip
    assert (tmp_path / "zero/colony/history_pop0.csv").read_text() == HISTORY_BEFORE
    summary = run_colony_stage(tmp_path / "half", navigation=NAV, table=TABLE, ga=ga,
                               colony=SPREAD)  # fmt: skip
    assert (tmp_path / "half/colony/history_pop0.csv").read_text() != HISTORY_BEFORE
    assert summary["settings"]["ColonySettings"]["start_power_spread"] == 0.5


# --------------------------------------------------------------------------- physics


def test_the_physics_colony_starts_its_robots_on_the_same_powers():
    """``servobot validate --robots R`` runs the interpreter on a ``PhysicsColony`` with the
    job's ``ColonySettings``: the robots start on 4.0, 4.5 and 5.0 V there too, and their
    first events match the table world's."""
    from servo_mj.world.physics_colony import PhysicsColony

    got = []
    world = PhysicsColony(THREE, colony_settings=SPREAD)
    run_colony(LOW_TEST, world, colony=SPREAD, max_steps=1,
               on_event=lambda e: got.append((e.robot, e.event.kind, e.event.power)))  # fmt: skip
    _, table = events_of(SPREAD, max_steps=1)
    want = [(r, e.kind, e.power) for r, ev in enumerate(table) for e in ev]
    assert sorted(got) == sorted(want)
    assert [p for r, k, p in got if k == "branch"] == [4.0, 4.5, 5.0]


# --------------------------------------------------------------------------- the setting


def test_the_setting_is_validated():
    for bad in (-0.1, float("nan"), float("inf"), "0.5", True, None):
        with pytest.raises(SettingsError, match="start_power_spread must be a finite number ≥ 0"):
            ColonySettings(start_power_spread=bad)
    assert ColonySettings(start_power_spread=1).start_powers(4.0, 5.0) == (4.0, 5.0, 5.0)


def test_the_record_names_the_spread_only_when_not_zero():
    record = json.loads(settings_json(ColonySettings()))["ColonySettings"]
    assert "start_power_spread" not in record
    record = json.loads(settings_json(SPREAD))["ColonySettings"]
    assert record["start_power_spread"] == 0.5
    assert ColonySettings(**record) == SPREAD


def test_a_folder_written_before_the_field_resumes(tmp_path):
    """A settings.json without ``start_power_spread`` resumes with spread 0; a spread is
    refused on resume."""
    doc = interrupted_colony_stage(tmp_path)
    assert "start_power_spread" not in doc["ColonySettings"]
    with pytest.raises(InputError, match="ColonySettings.start_power_spread: absent there, 0.5"):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, resume=True,
                         colony=SPREAD)  # fmt: skip
    summary = run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, resume=True,
                               colony=ColonySettings(start_power_spread=0.0))  # fmt: skip
    assert summary["settings"]["ColonySettings"] == doc["ColonySettings"]


def test_the_cli_options(tmp_path, capsys):
    from servobot.cli import validate as validate_cli
    from servobot.cli.evolve import main

    tiny = tiny_colony_cli(tmp_path)
    out = tmp_path / "run"
    assert main(["colony", *tiny, "--start-power-spread", "0.5", "--out", str(out)]) == 0
    summary = json.loads((out / "colony/summary.json").read_text())
    assert summary["settings"]["ColonySettings"]["start_power_spread"] == 0.5
    zero = tmp_path / "zero"
    assert main(["colony", *tiny, "--start-power-spread", "0", "--out", str(zero)]) == 0
    summary = json.loads((zero / "colony/summary.json").read_text())
    assert "start_power_spread" not in summary["settings"]["ColonySettings"]
    capsys.readouterr()
    refused = {
        ("coverage", "--start-power-spread", "0.5"): "--start-power-spread is an option of the "
        "colony stage",
        ("colony", "--start-power-spread", "-1"): "--start-power-spread must be a finite number",
        ("colony", "--start-power-spread", "nan"): "--start-power-spread must be a finite number",
    }
    for (stage, *extra), message in refused.items():
        assert main([stage, *tiny, *extra, "--out", str(tmp_path / "no")]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "no").exists()
    # servobot validate: --start-power-spread with --robots makes the colony's settings
    chromosome = write_chromosome(tmp_path / "c.txt", LOW_TEST)
    parse = validate_cli.build_parser().parse_args
    args = parse([str(chromosome), "--robots", "3", "--start-power-spread", "0.5"])
    assert validate_cli._colony(args) == SPREAD
    args = parse([str(chromosome), "--robots", "2", "--start-power-spread", "0.25",
                  "--blocking", "slide"])  # fmt: skip
    assert validate_cli._colony(args) == ColonySettings(robots=2, blocking="slide",
                                                        start_power_spread=0.25)  # fmt: skip
    assert validate_cli._colony(parse([str(chromosome), "--robots", "3"])) == ColonySettings()
    for argv, message in (
        ([str(chromosome), "--start-power-spread", "0.5"], "--start-power-spread is an option "
         "of a colony (--robots R)"),
        ([str(chromosome), "--robots", "3", "--start-power-spread", "-0.5"],
         "--start-power-spread must be a finite number ≥ 0"),
    ):  # fmt: skip
        with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
            validate_cli._colony(parse(argv))
        assert validate_cli.main([*argv, "--out", str(tmp_path / "nov")]) == 2
        assert message in capsys.readouterr().err
