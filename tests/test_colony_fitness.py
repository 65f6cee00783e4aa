"""The colony's run fitness (``ColonySettings.fitness``, issue 17 "learning to share"):
``"squares"`` (SPEC §7), ``"alive"`` (+ ``alive_weight`` × live robots / R), ``"per_step"``
(squares × R·N / gait steps), ``"docks"`` (+ ``dock_weight`` × Σ min(docks, ``dock_cap``)
/ R) and ``"alive_docks"`` (both terms). Hand-worked colonies in the interpreter and the kernel, the
kernel against the interpreter on random colonies for every option, ``"squares"`` against the
fitness before the setting existed, one robot, the setting's validation and record, resume
of a run folder written before the field existed, and the CLI options."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, STILL, B, G, chrom, gene
from test_colony_kernel import NEAR_STATION
from test_stages import Interrupt

from evolve import evaluate, evaluate_colony
from evolve.codec import parse_chromosome, write_chromosome
from evolve.colony_stage import colony_stage, run_colony_stage
from evolve.evaluation import colony_run_fitness
from evolve.interpreter import (
    END_BRANCH_LIMIT,
    END_KILL_ZONE,
    END_STEP_LIMIT,
    colony_fitness,
    run_colony,
)
from evolve.settings import (
    COLONY_FITNESSES,
    ColonySettings,
    GASettings,
    SettingsError,
    WorldSettings,
    settings_json,
)
from evolve.stages import coverage_run_fitness
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE, load_table
from evolve.world import TableColony
from infra.errors import InputError

WORLD = WorldSettings()
STEP = np.zeros((16, 3))
STEP[0] = (10.0, 0.0, 0.0)  # gait 0: 10 units straight ahead; every other gait stands still
FORWARD = chrom(gene("00", G(0), G(0), G(0), G(0)))
"""Every robot walks gait 0 forever."""
DOCKER = chrom(gene("00", B(4, 0), G(0), G(0), G(0)), *[STILL] * 7, gene("00", *[G(0)] * 4))
"""Low power (below 4.0 V) sends it to navigation gene 8 at once, which walks gait 0."""
TWO = np.array([[440.0, 225.0, 90.0], [300.0, 275.0, 270.0]])
"""Robot 0 faces east at x 440: x 450, 460 (square (9, 4), outer), 470, 480: kill zone (> 475)
at its 4th step. Robot 1 faces west on the row y = 275 (square centres 25 + 50 i, reached
within 19): x 290–260 square (5, 5), 250 none, 240–210 (4, 5), 190–160 (3, 5), ..."""
VARIANTS = (
    *((f, {}) for f in COLONY_FITNESSES),
    ("alive", {"alive_weight": 2.5}),
    ("docks", {"dock_weight": 2.5, "dock_cap": 1}),
    ("docks", {"dock_weight": 7.0, "dock_cap": 3}),
    ("alive_docks", {"alive_weight": 16.0, "dock_weight": 12.0, "dock_cap": 1}),
)
"""(fitness, other ``ColonySettings`` fields): every option at its defaults, and other weights
and caps."""


def both(bits, starts, colony, *, max_steps, table=STEP, **kw):
    """(interpreter result, {fitness: (interpreter value, kernel value)}) of one colony run."""
    world = TableColony(table, starts, WORLD, colony)
    res = run_colony(bits, world, colony=colony, max_steps=max_steps, **kw)
    values = {}
    for f in COLONY_FITNESSES:
        c = dataclasses.replace(colony, fitness=f)
        ev = evaluate_colony(bits[None], starts[None], table=table, mode="coverage",
                             max_steps=max_steps, colony=c, **kw)  # fmt: skip
        values[f] = (colony_fitness(res, c, max_steps), colony_run_fitness(ev, c, max_steps))
        assert ev.live[0, 0].sum() == res.live
    return res, values


def assert_values(values, want):
    for f, (interp, kern) in values.items():
        assert interp == want[f], f
        assert kern.shape == (1, 1) and kern[0, 0] == want[f], f


# --------------------------------------------------------------------------- hand-worked


def test_one_robot_killed_one_at_its_step_limit():
    # Robot 0: 4 steps, square (9, 4), kill zone. Robot 1: 6 steps (its limit), squares (5, 5)
    # and (4, 5). Colony: 3 squares (2 inner), 1 of 2 live, 10 gait steps.
    res, values = both(FORWARD, TWO, ColonySettings(robots=2), max_steps=6)
    assert [(r.steps, r.end, r.squares) for r in res.robots] == [
        (4, END_KILL_ZONE, 1), (6, END_STEP_LIMIT, 2)
    ]  # fmt: skip
    assert (res.squares, res.inner_squares, res.live, res.steps) == (3, 2, 1, 10)
    # squares 3; alive 3 + 8 · 1/2 = 7; per step 3 · (2 · 6) / 10 = 3.6
    want = {"squares": 3.0, "alive": 7.0, "per_step": 3.0 * 12 / 10, "docks": 3.0}
    assert_values(values, {**want, "alive_docks": 7.0})
    w = ColonySettings(robots=2, fitness="alive", alive_weight=3.0)
    assert colony_fitness(res, w, 6) == 3.0 + 1.5


def test_the_colony_step_limit_leaves_every_robot_live():
    # After 2 colony steps: robot 0 at x 460 (square (9, 4)), robot 1 at x 280 (square (5, 5)).
    res, values = both(FORWARD, TWO, ColonySettings(robots=2, colony_step_limit=2), max_steps=6)
    assert [r.end for r in res.robots] == [END_STEP_LIMIT] * 2
    assert (res.squares, res.live, res.steps) == (2, 2, 4)
    # alive 2 + 8 · 2/2 = 10; per step 2 · 12 / 4 = 6
    assert_values(values, {"squares": 2.0, "alive": 10.0, "per_step": 6.0, "docks": 2.0,
                           "alive_docks": 10.0})  # fmt: skip


def test_a_robot_charging_at_the_end_is_live():
    # Robot 0 starts low on power at (450, 250) facing east, switches to navigation, docks
    # after its first step (x 460) and charges for 10 colony steps; the colony-step limit 5
    # ends the run while it charges. Robot 1 walks 5 steps west: square (5, 5).
    starts = np.array([[450.0, 250.0, 90.0], [300.0, 275.0, 270.0]])
    colony = ColonySettings(robots=2, colony_step_limit=5)
    res, values = both(DOCKER, starts, colony, max_steps=20, start_power=3.95)
    assert [(r.steps, r.docks, r.end) for r in res.robots] == [
        (1, 1, END_STEP_LIMIT), (5, 0, END_STEP_LIMIT)
    ]  # fmt: skip
    assert (res.squares, res.live, res.steps) == (1, 2, 6)
    # alive 1 + 8 = 9; per step 1 · (2 · 20) / 6; docks 1 + 4 · 1/2 = 3; both 1 + 8 + 2 = 11
    want = {"squares": 1.0, "alive": 9.0, "per_step": 40.0 / 6, "docks": 3.0, "alive_docks": 11.0}
    assert_values(values, want)
    # Without the limit it charges, backs up 4 cycles (gait 15 stands still here), walks
    # east into the kill zone (x 480 after 2 more steps); robot 1 takes its 20 steps west:
    # squares (5, 5), (4, 5), (3, 5), (2, 5).
    res, values = both(DOCKER, starts, ColonySettings(robots=2), max_steps=20, start_power=3.95)
    assert [(r.steps, r.docks, r.end) for r in res.robots] == [
        (7, 1, END_KILL_ZONE), (20, 0, END_STEP_LIMIT)
    ]  # fmt: skip
    assert (res.squares, res.live, res.steps) == (4, 1, 27)
    want = {"squares": 4.0, "alive": 4.0 + 4.0, "per_step": 4.0 * 40 / 27, "docks": 4.0 + 2.0,
            "alive_docks": 4.0 + 4.0 + 2.0}  # fmt: skip
    assert_values(values, want)


def test_no_step_taken_scores_zero_per_step():
    # Every instruction a branch: each robot ends at the branch limit before any gait step.
    looping = chrom(*[gene("00", B(0, 0), B(0, 0), B(0, 0), B(0, 0))] * 16)
    res, values = both(looping, TWO, ColonySettings(robots=2), max_steps=6)
    assert [r.end for r in res.robots] == [END_BRANCH_LIMIT] * 2
    assert (res.squares, res.live, res.steps) == (0, 0, 0)
    assert_values(values, {"squares": 0.0, "alive": 0.0, "per_step": 0.0, "docks": 0.0,
                           "alive_docks": 0.0})  # fmt: skip
    # max_steps 0: no step allowed, every robot ends at its step limit, live
    res, values = both(FORWARD, TWO, ColonySettings(robots=2), max_steps=0)
    assert (res.squares, res.live, res.steps) == (0, 2, 0)
    assert_values(values, {"squares": 0.0, "alive": 8.0, "per_step": 0.0, "docks": 0.0,
                           "alive_docks": 8.0})  # fmt: skip


BACK = STEP.copy()
BACK[15] = (-10.0, 0.0, 0.0)  # gait 15, the charging routine's backup: 10 units straight back
LOW = WorldSettings(charged_power_v=3.9)
"""Charging leaves a robot at 3.9 V, still low (below 4.0 V): after every charge DOCKER goes
straight back to navigation."""


def test_docks_count_each_robot_up_to_the_cap():
    # Both face east in the docking band (|y − 250| ≤ 30), robot 0 at x 450 (y 235), robot 1
    # at x 350 (y 270); DOCKER sends both to navigation (gait 0, 10 units east) at once.
    # Robot 0 docks at x 460 after its 1st step (colony step 1), charges, backs up to x 420,
    # walks back to 460 (colony step 19) while robot 1 charges there (docked at its 11th
    # step, colony step 11): refused at 460 and 470, kill zone at 480 — 1 dock, 11 steps.
    # Robot 1 docks again after its 19th and 27th steps and ends backing up at its 30-step
    # limit — 3 docks. Squares: robot 0 (9, 4) at 460 and (8, 4) at 440–420; robot 1 (7, 5)
    # at 360–390, (8, 5), (9, 5): 5 colony squares.
    starts = np.array([[450.0, 235.0, 90.0], [350.0, 270.0, 90.0]])
    res, values = both(DOCKER, starts, ColonySettings(robots=2), max_steps=30, table=BACK,
                       settings=LOW, start_power=3.95)  # fmt: skip
    assert [(r.steps, r.docks, r.end) for r in res.robots] == [
        (11, 1, END_KILL_ZONE), (30, 3, END_STEP_LIMIT)
    ]  # fmt: skip
    assert (res.squares, res.live, res.station_waits) == (5, 1, 2)
    # docks (cap 2): 5 + 4 · (min(1, 2) + min(3, 2)) / 2 = 5 + 4 · 3/2 = 11; alive 5 + 8 · 1/2;
    # both 5 + 4 + 6
    assert_values(values, {"squares": 5.0, "alive": 9.0, "per_step": 5.0 * 60 / 41, "docks": 11.0,
                           "alive_docks": 15.0})  # fmt: skip
    for cap, weight, want in ((3, 4.0, 5.0 + 4.0 * 4 / 2), (1, 3.0, 5.0 + 3.0 * 2 / 2),
                              (2, 0.0, 5.0), (5, 0.5, 5.0 + 0.5 * 4 / 2)):  # fmt: skip
        c = ColonySettings(robots=2, fitness="docks", dock_weight=weight, dock_cap=cap)
        ev = evaluate_colony(DOCKER[None], starts[None], table=BACK, mode="coverage",
                             max_steps=30, colony=c, settings=LOW, start_power=3.95)  # fmt: skip
        assert colony_fitness(res, c, 30) == want
        assert colony_run_fitness(ev, c, 30)[0, 0] == want
    # alive_docks at issue 17's weights: 5 + 16 · 1/2 + 12 · (1 + 2)/2 = 31; with cap 1 robot
    # 1's extra docks earn nothing: 5 + 8 + 12 · 2/2 = 25
    for cap, want in ((2, 31.0), (1, 25.0)):
        c = ColonySettings(robots=2, fitness="alive_docks", alive_weight=16.0, dock_weight=12.0,
                           dock_cap=cap)  # fmt: skip
        ev = evaluate_colony(DOCKER[None], starts[None], table=BACK, mode="coverage",
                             max_steps=30, colony=c, settings=LOW, start_power=3.95)  # fmt: skip
        assert colony_fitness(res, c, 30) == want
        assert colony_run_fitness(ev, c, 30)[0, 0] == want


def test_alive_docks_does_not_pay_a_parked_robot_in_full():
    """A robot that parks and never docks (docs/colony.md): ``"alive"`` pays its life in full,
    ``"alive_docks"`` withholds its docks' pay (a robot that docks and dies keeps its docks'
    pay and loses its life's: ``test_a_robot_charging_at_the_end_is_live``). Robot 0 stands
    still to its step limit (live, no dock); robot 1 is DOCKER of
    ``test_docks_count_each_robot_up_to_the_cap``'s robot 1, from (350, 270)."""
    parked = chrom(*[STILL] * 16)
    starts = np.array([[200.0, 100.0, 0.0], [350.0, 270.0, 90.0]])
    colony = ColonySettings(robots=2)
    world = TableColony(BACK, starts, LOW, colony)
    team = np.stack([parked, DOCKER])
    res = run_colony(team, world, colony=colony, max_steps=30, settings=LOW, start_power=3.95)
    r0, r1 = res.robots
    # (200, 100) lies 35 units from the nearest square centre (175, 75): robot 0 reaches none
    assert (r0.docks, r0.end, r0.squares) == (0, END_STEP_LIMIT, 0)
    assert r1.docks >= 2 and r1.end == END_STEP_LIMIT
    w = {"alive_weight": 16.0, "dock_weight": 12.0}
    fit = {f: colony_fitness(res, ColonySettings(robots=2, fitness=f, **w), 30) - res.squares
           for f in ("alive", "docks", "alive_docks")}  # fmt: skip
    # alive: both live, 16 (as if robot 0 took part); docks: robot 0 none, robot 1 capped at 2:
    # 12 · 2/2 = 12; alive_docks 28, short of the 16 + 12 · 4/2 = 40 of two live dockers
    assert fit == {"alive": 16.0, "docks": 12.0, "alive_docks": 28.0}


# --------------------------------------------------------------------------- kernel = interpreter


def test_kernel_fitness_equals_the_interpreter_on_random_colonies():
    """3,000 colony runs (half near the station, switching to navigation at once, so that
    robots dock, charge and wait; a third under a colony-step limit that cuts charges):
    every fitness (``VARIANTS``) of every run equal bit for bit, and the docks per robot."""
    rng = np.random.default_rng(1717)
    genomes = rng.integers(0, 2, size=(500, 16, 30), dtype=np.uint8)
    genomes[:250, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    plain, limited = ColonySettings(), ColonySettings(colony_step_limit=40)
    spread = colony_starts(rng, 2, WORLD, plain)
    near = colony_starts(rng, 2, NEAR_STATION, plain)
    cases = [
        (plain, np.concatenate([spread, near])),
        (limited, colony_starts(rng, 2, NEAR_STATION, limited)),
    ]
    live_kinds, per_step_max, docked_live = set(), 0.0, 0
    for colony, starts in cases:
        kw = dict(table=PAPER_TABLE, mode="coverage", start_power=3.95, colony=colony)
        ev = evaluate_colony(genomes, starts, **kw)
        variants = [dataclasses.replace(colony, fitness=f, **kw) for f, kw in VARIANTS]
        fits = [colony_run_fitness(ev, c, WORLD.coverage_steps) for c in variants]
        np.testing.assert_array_equal(fits[0], ev.squares.astype(np.float64))
        for i in range(genomes.shape[0]):
            for s in range(starts.shape[0]):
                res = run_colony(genomes[i], TableColony(PAPER_TABLE, starts[s], WORLD, colony),
                                 colony=colony, start_power=3.95)  # fmt: skip
                assert res.squares == ev.squares[i, s]
                assert [r.end for r in res.robots] == ev.end[i, s].tolist()
                assert [r.docks for r in res.robots] == ev.docks[i, s].tolist()
                for v, c in enumerate(variants):
                    got = colony_fitness(res, c, WORLD.coverage_steps)
                    assert got == fits[v][i, s], (VARIANTS[v], i, s, got, fits[v][i, s])
                live_kinds.add(res.live)
                per_step_max = max(per_step_max, fits[2][i, s])
        if colony.colony_step_limit is not None:
            docked_live = int(((ev.docks > 0) & ev.live).sum())
        else:
            dock_counts = np.bincount(ev.docks.ravel())
    assert live_kinds == {0, 1, 2, 3}
    assert per_step_max > 100 and docked_live > 10
    # the caps bite: robots docking once (410 of 3,000), twice (12), three times (3)
    assert dock_counts[1] > 100 and dock_counts[2] > 5 and dock_counts[3:].sum() > 0, dock_counts


def test_squares_is_the_fitness_before_the_setting_bit_for_bit():
    """The colony stage's run fitness under ``"squares"`` is ``coverage_run_fitness`` of the
    colony evaluation (what it was before the setting), and a short stage writes the history
    that the code before the setting wrote (recorded from main at c1a04be)."""
    nav = parse_chromosome(LIGHT_FOLLOWER)
    rng = np.random.default_rng(3)
    stage = colony_stage(WORLD, ColonySettings(), nav)
    sections = rng.integers(0, 2, size=(40, 8, 30), dtype=np.uint8)
    starts = colony_starts(rng, 5, WORLD, ColonySettings())
    ev = evaluate_colony(stage.genomes(sections), starts, table=PAPER_TABLE, mode="coverage")
    got = stage.run_fitness(ev, starts, WORLD)
    want = coverage_run_fitness(ev, starts, WORLD)
    assert got.dtype == want.dtype == np.float64
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got, ev.squares)


HISTORY_BEFORE = """generation,best_fitness,mean_fitness,docked_fraction,unique
0,13.8,6.84167,0.0972222,12
1,11.8,7.3,0.075,12
2,17.4,9.10833,0.0611111,11
3,13.9,10.1583,0.00277778,12
4,16.7,12.3583,0.00833333,12
5,17.3,13.1833,0.0638889,11
6,17.4,11.35,0.147222,12
"""
"""``colony/history_pop0.csv`` of ``run_colony_stage`` with the light follower, the paper's
table and ``GASettings(populations=1, population_size=12, generations=6, test_starts=4,
seed=5)``, written by the code before ``ColonySettings.fitness`` existed."""


def test_a_short_stage_writes_the_history_of_before(tmp_path):
    ga = GASettings(populations=1, population_size=12, generations=6, test_starts=4, seed=5)
    run_colony_stage(tmp_path, navigation=parse_chromosome(LIGHT_FOLLOWER),
                     table=load_table("paper"), ga=ga)  # fmt: skip
    assert (tmp_path / "colony/history_pop0.csv").read_text() == HISTORY_BEFORE


def test_one_robot_with_squares_is_the_lone_robot():
    rng = np.random.default_rng(1718)
    one = ColonySettings(robots=1)
    genomes = rng.integers(0, 2, size=(300, 16, 30), dtype=np.uint8)
    genomes[:100, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]
    starts = colony_starts(rng, 6, NEAR_STATION, one)
    kw = dict(table=PAPER_TABLE, mode="coverage", start_power=3.95)
    col = evaluate_colony(genomes, starts, colony=one, **kw)
    lone = evaluate(genomes, starts[:, 0], **kw)
    np.testing.assert_array_equal(
        colony_run_fitness(col, one, WORLD.coverage_steps), coverage_run_fitness(lone, None, WORLD)
    )
    assert lone.docks.sum() > 50


# --------------------------------------------------------------------------- the setting


def test_the_setting_is_validated():
    allowed = "'squares', 'alive', 'per_step', 'docks', 'alive_docks'"
    with pytest.raises(SettingsError, match=f"fitness must be one of {allowed}, got 'coverage'"):
        ColonySettings(fitness="coverage")
    for bad in (-1.0, float("nan"), float("inf"), "8", True):
        with pytest.raises(SettingsError, match="alive_weight must be a finite number ≥ 0"):
            ColonySettings(fitness="alive", alive_weight=bad)
    assert ColonySettings().fitness == "squares" and ColonySettings().alive_weight == 8.0
    for bad in (-0.5, float("nan"), float("-inf"), None, False):
        with pytest.raises(SettingsError, match="dock_weight must be a finite number ≥ 0"):
            ColonySettings(fitness="docks", dock_weight=bad)
    for bad in (0, -2, 2.0, True, "2"):
        with pytest.raises(SettingsError, match="dock_cap must be an integer ≥ 1"):
            ColonySettings(fitness="docks", dock_cap=bad)
    c = ColonySettings(fitness="docks", dock_weight=0, dock_cap=np.int64(5))
    assert (c.dock_weight, c.dock_cap) == (0, 5)
    assert (ColonySettings().dock_weight, ColonySettings().dock_cap) == (4.0, 2)


def test_the_record_names_fitness_only_when_not_squares():
    # the default: the record of a colony made before the fields existed
    record = json.loads(settings_json(ColonySettings()))["ColonySettings"]
    new_fields = ("blocking", "fitness", "alive_weight", "dock_weight", "dock_cap")
    new_fields += ("start_power_spread", "sections", "robots_seen", "contact_yaw_deg")
    before = {k: v for k, v in dataclasses.asdict(ColonySettings()).items() if k not in new_fields}
    assert record == before
    alive = json.loads(settings_json(ColonySettings(fitness="alive", alive_weight=4.0)))
    assert alive["ColonySettings"]["fitness"] == "alive"
    assert alive["ColonySettings"]["alive_weight"] == 4.0
    per_step = json.loads(settings_json(ColonySettings(fitness="per_step")))["ColonySettings"]
    assert per_step["fitness"] == "per_step" and "alive_weight" not in per_step
    assert "dock_weight" not in per_step and "dock_cap" not in per_step
    assert not {"dock_weight", "dock_cap"} & set(alive["ColonySettings"])
    docks = json.loads(settings_json(ColonySettings(fitness="docks", dock_weight=6.0)))
    assert docks["ColonySettings"]["fitness"] == "docks"
    assert (docks["ColonySettings"]["dock_weight"], docks["ColonySettings"]["dock_cap"]) == (6.0, 2)
    assert "alive_weight" not in docks["ColonySettings"]
    both = json.loads(settings_json(ColonySettings(fitness="alive_docks", dock_cap=3)))
    want = {"fitness": "alive_docks", "alive_weight": 8.0, "dock_weight": 4.0, "dock_cap": 3}
    assert want.items() <= both["ColonySettings"].items()


TINY = GASettings(populations=1, population_size=10, generations=6, test_starts=4, seed=2)
NAV = parse_chromosome(LIGHT_FOLLOWER)
TABLE = load_table("paper")


def tiny_colony_cli(tmp_path) -> list[str]:
    """Options of a tiny ``servobot evolve colony`` run whose navigation section is ``NAV``
    (written to ``tmp_path/nav.txt``)."""
    nav = write_chromosome(tmp_path / "nav.txt", NAV)
    return ["--populations", "1", "--population-size", "8", "--generations", "2",
            "--no-progress", "--navigation", str(nav)]  # fmt: skip


def interrupted_colony_stage(tmp_path) -> dict:
    """A tiny colony stage with the default ``ColonySettings`` interrupted at generation 3 in
    ``tmp_path``; its ``settings.json``."""

    def kill_at(info):
        if info["generation"] == 3:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, on_generation=kill_at)
    return json.loads((tmp_path / "colony/settings.json").read_text())


def test_a_folder_written_before_the_field_resumes(tmp_path):
    """A settings.json without ``fitness`` (as written before the field existed) resumes with
    the default; another fitness is refused on resume."""
    doc = interrupted_colony_stage(tmp_path)
    assert not {"fitness", "alive_weight", "blocking"} & set(doc["ColonySettings"])
    with pytest.raises(InputError, match='ColonySettings.fitness: absent there, "alive" here'):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, resume=True,
                         colony=ColonySettings(fitness="alive"))  # fmt: skip
    summary = run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, resume=True)
    assert summary["settings"]["ColonySettings"] == doc["ColonySettings"]
    for t in summary["final_test"]:
        assert 0.0 <= t["live_at_end_per_run"] <= 3.0
        assert t["run_fitness"] == pytest.approx(t["colony_squares"])


def test_the_summary_reports_live_robots_and_the_run_fitness(tmp_path):
    colony = ColonySettings(fitness="alive")
    summary = run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, colony=colony)
    assert summary["settings"]["ColonySettings"]["fitness"] == "alive"
    for t in summary["final_test"]:
        live = t["live_at_end_per_run"]
        assert live == pytest.approx(3 * (t["ends"]["step limit"] + t["ends"]["docked"]))
        assert t["run_fitness"] == pytest.approx(t["colony_squares"] + 8.0 * live / 3)


def test_the_cli_option(tmp_path, capsys):
    from servobot.cli.evolve import main

    tiny = tiny_colony_cli(tmp_path)
    out = tmp_path / "run"
    assert main(["colony", *tiny, "--colony-fitness", "per_step", "--out", str(out)]) == 0
    summary = json.loads((out / "colony/summary.json").read_text())
    assert summary["settings"]["ColonySettings"]["fitness"] == "per_step"
    assert "robots live at the end" in capsys.readouterr().out
    assert main(["coverage", *tiny, "--colony-fitness", "alive", "--out", str(out)]) == 2
    assert "--colony-fitness is an option of the colony stage" in capsys.readouterr().err
    docks = tmp_path / "docks"
    args = ["--colony-fitness", "docks", "--dock-weight", "6", "--dock-cap", "3"]
    assert main(["colony", *tiny, *args, "--out", str(docks)]) == 0
    record = json.loads((docks / "colony/summary.json").read_text())["settings"]["ColonySettings"]
    assert (record["fitness"], record["dock_weight"], record["dock_cap"]) == ("docks", 6.0, 3)
    both = tmp_path / "alive_docks"
    args = ["--colony-fitness", "alive_docks", "--alive-weight", "16", "--dock-weight", "12"]
    assert main(["colony", *tiny, *args, "--out", str(both)]) == 0
    record = json.loads((both / "colony/summary.json").read_text())["settings"]["ColonySettings"]
    assert (record["alive_weight"], record["dock_weight"], record["dock_cap"]) == (16.0, 12.0, 2)
    refused = {
        ("--colony-fitness", "alive", "--dock-weight", "4"): "--dock-weight is an option of "
        "--colony-fitness docks or alive_docks",
        ("--dock-cap", "2"): "--dock-cap is an option of --colony-fitness docks or alive_docks",
        ("--colony-fitness", "docks", "--alive-weight", "8"): "--alive-weight is an option of "
        "--colony-fitness alive or alive_docks",
        ("--colony-fitness", "docks", "--dock-weight", "nan"): "--dock-weight must be a finite "
        "number ≥ 0",
        ("--colony-fitness", "alive", "--alive-weight", "-1"): "--alive-weight must be a finite "
        "number ≥ 0",
        ("--colony-fitness", "docks", "--dock-cap", "0"): "--dock-cap must be an integer ≥ 1",
    }
    for extra, message in refused.items():
        assert main(["colony", *tiny, *extra, "--out", str(tmp_path / "no")]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "no").exists()
