"""The colony's docks over time (``evolve.colony_timeline``, issue 17): docks dated from the
interpreter's events on a hand-worked colony (docks, refusals, a kill, charging steps), a dock
on the last allowed step and under the colony-step limit, the count against the interpreter's
``RunResult.docks`` on random colonies near the station, live robots that start at R and never
rise, the means over starts, hand-offs in the colony and alone (hand-worked: docks, a kill, a
cut approach, an approach blocked by a robot ended at the station), the figure, and the CLI on
a tiny run folder and a bad one."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import STILL, B, G, chrom, gene

from evolve.codec import write_chromosome
from evolve.colony_timeline import (
    ColonyHandoff,
    TimelineError,
    colony_timeline,
    docks_over_time,
    main,
    others_colony,
    run_timeline,
)
from evolve.figures import figure_colony_docks
from evolve.handoff import DOCKED
from evolve.interpreter import END_KILL_ZONE, END_STEP_LIMIT
from evolve.settings import ColonySettings, WorldSettings, settings_json
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE

WORLD = WorldSettings()
TABLE = np.zeros((16, 3))
TABLE[0] = (10.0, 0.0, 0.0)  # gait 0: 10 units straight ahead
TABLE[15] = (-10.0, 0.0, 0.0)  # gait 15, the charging routine's backup: 10 units back
DOCKER = chrom(gene("00", B(4, 0), G(0), G(0), G(0)), *[STILL] * 7, gene("00", *[G(0)] * 4))
"""Low power (below 4.0 V) sends it to navigation gene 8 at once, which walks gait 0."""
LOW = WorldSettings(charged_power_v=3.9)
"""Charging leaves a robot at 3.9 V, still low: after every charge DOCKER docks again."""
NEAR_STATION = dataclasses.replace(WORLD, coverage_start_x=(400, 470), coverage_start_y=(190, 310))
"""Colony starts close to the station, so that robots dock, meet there and wait."""


def test_hand_worked_colony_docks_charges_and_a_kill():
    # tests/test_colony_fitness.py's colony of 2: robot 0 (x 450) docks at x 460 in colony
    # step 1, charges 2–11, backs up to 420 (12–15), walks back to 460 (19) and 470 (20)
    # while robot 1 charges (refused twice), and meets the kill zone at 480 in step 21.
    # Robot 1 (x 350) reaches 460 in step 11, as robot 0 frees the station (robot 0 moves
    # first): docks, charges 12–21, backs up 22–25, walks 26–29 and docks again in 29,
    # charges 30–39, docks in 47, charges 48–57 and backs up to its 30-step limit in step 60.
    starts = np.array([[450.0, 235.0, 90.0], [350.0, 270.0, 90.0]])
    tl = run_timeline(DOCKER, starts, table=TABLE, world=LOW, colony=ColonySettings(robots=2),
                      start_power=3.95, max_steps=30)  # fmt: skip
    res = tl.result
    assert [(r.docks, r.end, r.station_waits) for r in res.robots] == [
        (1, END_KILL_ZONE, 2), (3, END_STEP_LIMIT, 0)
    ]  # fmt: skip
    assert tl.dock_steps == ((1,), (11, 29, 47))
    assert res.colony_steps == 60 and len(tl.docks) == 61
    want_docks = np.searchsorted([1, 11, 29, 47], np.arange(61), side="right")
    np.testing.assert_array_equal(tl.docks, want_docks)
    assert tl.docks[-1] == sum(r.docks for r in res.robots) == 4
    np.testing.assert_array_equal(tl.live, [2] * 21 + [1] * 40)  # robot 0 ends in step 21
    assert tl.live[-1] == res.live == 1
    charging = np.zeros(61, dtype=int)
    for first in (2, 12, 30, 48):
        charging[first : first + 10] = 1
    np.testing.assert_array_equal(tl.charging, charging)


def test_hand_offs_in_the_colony_and_alone_hand_worked():
    # The colony above: robot 0 hands off at once and docks (step 1), hands off again after
    # its charge and meets the kill zone; robot 1 docks after each of its 3 hand-offs. Alone
    # from the same poses and 3.95 V nobody holds the station: robot 0 docks every 8 gait
    # steps (1, 9, 17, 25) and its 5th approach is cut by the 30-step limit; robot 1 docks
    # at 11, 19 and 27 and ends backing up.
    starts = np.array([[[450.0, 235.0, 90.0], [350.0, 270.0, 90.0]]])
    c = colony_timeline(DOCKER, starts, table=TABLE, world=LOW, colony=ColonySettings(robots=2),
                        start_power=3.95, max_steps=30)  # fmt: skip
    assert c["handoffs"] == {
        "handoffs": 5, "docked": 4, "failed": 1, "cut": 0, "dock_rate": 0.8,
        "failed_by_end": {"kill zone": 1, "power empty": 0, "branch limit": 0},
        "blocked_per_failed": 0.0, "failed_beside_ended": 0.0,
    }  # fmt: skip
    assert c["handoffs_alone"] == {"handoffs": 8, "docked": 7, "failed": 0, "cut": 1,
                                   "dock_rate": 1.0}  # fmt: skip


def test_a_hand_off_blocked_by_a_robot_ended_at_the_station():
    # Robot 0 (x 470) walks into the kill zone at x 480 in colony step 1, 15 units from the dock
    # point, and stays there. Robot 1 (x 420) walks to 450 (30 units from it: allowed); every
    # later move would come closer and is cancelled, 57 of them, until its store is empty
    # after 60 cycles (3.95 − 60 × 0.0209 < 2.7 V).
    starts = np.array([[470.0, 250.0, 90.0], [420.0, 250.0, 90.0]])
    tl = run_timeline(DOCKER, starts, table=TABLE, world=WORLD, colony=ColonySettings(robots=2),
                      start_power=3.95, max_steps=100)  # fmt: skip
    assert tl.handoffs == (
        ColonyHandoff(0, "kill zone", blocked=0, beside_ended=False),
        ColonyHandoff(1, "power empty", blocked=57, beside_ended=True),
    )
    assert tl.result.robots[1].collisions == 57 and tl.result.robots[1].steps == 60
    two = ColonySettings(robots=2)
    c = colony_timeline(DOCKER, starts[None], table=TABLE, world=WORLD, colony=two,
                        start_power=3.95, max_steps=100)  # fmt: skip
    h = c["handoffs"]
    assert (h["dock_rate"], h["blocked_per_failed"], h["failed_beside_ended"]) == (0.0, 28.5, 0.5)
    assert h["failed_by_end"] == {"kill zone": 1, "power empty": 1, "branch limit": 0}
    # alone, robot 1 walks on and docks at 460
    assert c["handoffs_alone"]["docked"] == 1 and c["handoffs_alone"]["failed"] == 1


def test_the_other_robots_unseen_or_passable():
    """``--others``: robot 1 stands 38 units ahead of robot 0, inside its object sensors' 50;
    unseen, it is not in them. Passable, the robot ended at the station in the case above no
    longer blocks robot 1, which walks on and docks at 460 as it does alone."""
    ahead = np.array([[250.0, 250.0, 90.0], [288.0, 250.0, 90.0]])
    seen = others_colony("as-is", TABLE, ahead, WORLD, ColonySettings(robots=2))
    unseen = others_colony("unseen", TABLE, ahead, WORLD, ColonySettings(robots=2))
    assert seen.object_sensors(0) == (True, True) and unseen.object_sensors(0) == (False, False)
    assert unseen.step(0, 0) is True  # still blocking: gait 0 would end 28 units from it
    assert unseen.pose(0) == (250.0, 250.0, 90.0)
    starts = np.array([[470.0, 250.0, 90.0], [420.0, 250.0, 90.0]])
    kw = dict(table=TABLE, world=WORLD, colony=ColonySettings(robots=2), start_power=3.95,
              max_steps=100)  # fmt: skip
    passable = run_timeline(DOCKER, starts, others="passable", **kw)
    assert set(passable.handoffs) == {
        ColonyHandoff(0, "kill zone", blocked=0, beside_ended=False),
        ColonyHandoff(1, DOCKED, blocked=0, beside_ended=True),  # docked beside the body
    }
    assert [r.docks for r in passable.result.robots] == [0, 1]
    with pytest.raises(TimelineError, match="--others must be one of"):
        docks_over_time("nowhere", others="invisible")


def test_a_dock_without_a_charge_still_counts():
    # Robot 0 docks on its last allowed gait step (max_steps 1): the run ends before the
    # charge, no "charge" event, yet the interpreter counts the dock.
    starts = np.array([[450.0, 250.0, 90.0], [300.0, 300.0, 270.0]])
    tl = run_timeline(DOCKER, starts, table=TABLE, world=WORLD, colony=ColonySettings(robots=2),
                      start_power=3.95, max_steps=1)  # fmt: skip
    assert [r.docks for r in tl.result.robots] == [1, 0]
    assert tl.dock_steps == ((1,), ()) and tl.charging.sum() == 0
    np.testing.assert_array_equal(tl.docks, [0, 1])
    # The colony-step limit 5 cuts the charge: dock in step 1, charging steps 2–5, both live.
    colony = ColonySettings(robots=2, colony_step_limit=5)
    tl = run_timeline(DOCKER, starts, table=TABLE, world=WORLD, colony=colony, start_power=3.95,
                      max_steps=20)  # fmt: skip
    np.testing.assert_array_equal(tl.docks, [0, 1, 1, 1, 1, 1])
    np.testing.assert_array_equal(tl.charging, [0, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(tl.live, [2] * 6)


def test_docks_from_events_equal_the_interpreter_on_random_colonies():
    """100 random chromosomes that switch to navigation at once × 3 colony starts of 3 near
    the station on low power, with a wide docking box and long charges (as
    ``tests/test_colony_kernel.py``): robots dock, charge, wait and die. ``run_timeline``
    asserts its count against every robot's ``RunResult.docks``; live starts at R, never rises
    and ends at ``ColonyResult.live``; the means over starts are the runs' means."""
    rng = np.random.default_rng(22)
    genomes = rng.integers(0, 2, size=(100, 16, 30), dtype=np.uint8)
    genomes[:, 0, :9] = [0, 0, 1, 1, 0, 0, 0, 0, 0]  # gene 0 ×∞, first: if low-power goto 8
    world = dataclasses.replace(NEAR_STATION, dock_y_half_width=60.0)
    colony = ColonySettings(charge_steps=40)
    starts = colony_starts(rng, 3, NEAR_STATION, colony)
    docks = np.zeros(4, dtype=int)
    waits = 0
    for k, bits in enumerate(genomes):
        kw = dict(table=PAPER_TABLE, world=world, colony=colony, start_power=3.95)
        runs = [run_timeline(bits, s, **kw) for s in starts]
        for tl in runs:
            assert tl.live[0] == 3 and np.all(np.diff(tl.live) <= 0)
            assert tl.live[-1] == tl.result.live
            assert tl.docks[-1] == sum(r.docks for r in tl.result.robots)
            assert np.all(np.diff(tl.docks) >= 0) and tl.charging.max() <= 1
            docks += np.bincount([r.docks for r in tl.result.robots], minlength=4)[:4]
            waits += tl.result.station_waits
        if k < 5:
            mean = colony_timeline(bits, starts, **kw)
            final = np.mean([[r.docks for r in tl.result.robots] for tl in runs])
            assert mean["docks_per_robot"][-1] == pytest.approx(final)
            assert mean["final_docks_per_robot"] == pytest.approx(final)
            assert mean["live"][0] == 3 and mean["live"][-1] == mean["live_at_end"]
            assert len(mean["live"]) == max(tl.result.colony_steps for tl in runs) + 1
    # robots that dock once, twice and three times or more; station waits
    # (measured: 90 robots dock once, 7 twice, 1 three times; 25 station waits)
    assert docks[1] > 20 and docks[2] > 2 and docks[3] > 0 and waits > 10, (docks, waits)


def test_the_figure_is_written(tmp_path):
    starts = np.array([[[450.0, 235.0, 90.0], [350.0, 270.0, 90.0]]])
    c = colony_timeline(DOCKER, starts, table=TABLE, world=LOW, colony=ColonySettings(robots=2),
                        start_power=3.95, max_steps=30)  # fmt: skip
    assert c["docks_per_robot"][-1] == 2.0 and c["live_at_end"] == 1.0
    out = figure_colony_docks(tmp_path / "d.png", [{"label": "docker", **c}], "a test")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _run_folder(tmp_path, colony):
    folder = tmp_path / "run" / "colony"
    folder.mkdir(parents=True)
    write_chromosome(folder / "best_pop0.txt", DOCKER, "a docker")
    write_chromosome(folder / "best_pop1.txt", chrom(), "stands still")
    doc = json.loads(settings_json(WORLD, colony))
    doc["table"] = {"source": "paper", "values": PAPER_TABLE.tolist()}
    (folder / "settings.json").write_text(json.dumps(doc))
    return folder.parent


def test_cli_writes_the_figure_and_curves(tmp_path, capsys):
    colony = ColonySettings(robots=2, blocking="slide", fitness="docks", colony_step_limit=40)
    run = _run_folder(tmp_path, colony)
    assert main([str(run), "--starts", "2"]) == 0
    text = capsys.readouterr().out
    assert "best_pop0: docks per robot" in text and "best_pop1: docks per robot 0.00" in text
    assert "hand-offs docked" in text and "alone" in text
    assert (run / "colony" / "docks_over_time.png").stat().st_size > 0
    doc = json.loads((run / "colony" / "docks_over_time.json").read_text())
    assert doc["ColonySettings"] == colony.to_dict() and doc["table_matches_run"]
    assert [c["finalist"] for c in doc["curves"]] == ["best_pop0", "best_pop1"]
    still = doc["curves"][1]
    assert still["live"] == [2.0] * 41 and still["docks_per_robot"][-1] == 0.0
    out = tmp_path / "elsewhere.png"
    assert main([str(run), "--starts", "1", "--out", str(out), "--table", "paper"]) == 0
    assert out.exists() and out.with_suffix(".json").exists()


def test_cli_refuses_a_folder_without_colony_finalists(tmp_path, capsys):
    assert main([str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no colony finalists" in err and str(tmp_path) in err
    run = _run_folder(tmp_path, ColonySettings(robots=2))
    (run / "colony" / "settings.json").unlink()
    assert main([str(run)]) == 2
    assert "no colony/settings.json" in capsys.readouterr().err
    assert main([str(run), "--starts", "0"]) == 2
    assert "--starts must be >= 1" in capsys.readouterr().err
