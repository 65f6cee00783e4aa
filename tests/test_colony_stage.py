"""The colony stage (``evolve.colony_stage``): its files, the Figure 9 test and the lone
comparison against independent evaluations, resume bit for bit, settings checked on resume,
and a short evolution that measurably learns."""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER
from test_stages import Interrupt, _files

from evolve import evaluate, evaluate_colony
from evolve.codec import parse_chromosome, read_chromosome
from evolve.colony_stage import figure10_starts, run_colony_stage
from evolve.population import StageError, stage_seeds
from evolve.settings import ColonySettings, GASettings, WorldSettings
from evolve.starts import colony_starts
from evolve.table import load_table
from infra.errors import InputError
from infra.executors import ProcessExecutor

WORLD = WorldSettings()
TABLE = load_table("paper")
NAV = parse_chromosome(LIGHT_FOLLOWER)
TINY = GASettings(populations=2, population_size=10, generations=18, test_starts=12, seed=3)
"""18 generations: checkpoints at 0 and 16, saves at 0, 1 and 18."""


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("colony")
    return out, run_colony_stage(out, navigation=NAV, table=TABLE, ga=TINY)


def test_outputs_and_their_numbers(tiny_run):
    out, summary = tiny_run
    folder = out / "colony"
    with open(folder / "figure9.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["population"], r["generation"]) for r in rows] == [
        (str(k), str(g)) for k in (0, 1) for g in (0, 1, 18)
    ]
    for k in (0, 1):
        assert (folder / f"figure10_pop{k}.png").stat().st_size > 10_000
    assert (folder / "figure9.png").read_bytes()[:4] == b"\x89PNG"
    assert json.loads((folder / "summary.json").read_text())["robots"] == 3
    # every field but ``blocking``, ``fitness`` and its weights and cap, and the fields added
    # after them at their defaults: the record of the colonies made before them
    record = dataclasses.asdict(ColonySettings())
    for field in ("blocking", "fitness", "alive_weight", "dock_weight", "dock_cap",
                  "start_power_spread", "sections", "robots_seen", "contact_yaw_deg"):
        del record[field]
    assert summary["settings"]["ColonySettings"] == record
    # The final test, redone independently: the written bests from the stage's test starts.
    test_seq, _ = stage_seeds(TINY.seed, "colony", TINY.populations)
    starts = colony_starts(
        np.random.Generator(np.random.PCG64(test_seq)), TINY.test_starts, WORLD, ColonySettings()
    )
    bests = np.stack([read_chromosome(folder / f"best_pop{k}.txt") for k in (0, 1)])
    np.testing.assert_array_equal(bests[:, 8:], np.broadcast_to(NAV, (2, 8, 30)))
    ev = evaluate_colony(bests, starts, table=TABLE.values, mode="coverage")
    lone = evaluate(bests, starts[:, 0], table=TABLE.values, mode="coverage")
    for k, t in enumerate(summary["final_test"]):
        assert t["colony_inner_percent"] == pytest.approx(100 * ev.inner_squares[k].mean() / 64)
        assert t["colony_inner_percent"] == pytest.approx(summary["final_inner_percent"][k])
        assert t["robot_inner_percent"] == pytest.approx(
            100 * ev.robot_inner_squares[k].mean() / 64
        )
        assert t["one_robot_inner_percent"] == pytest.approx(
            100 * lone.inner_squares[k].mean() / 64
        )
        assert t["station_waits_per_run"] == pytest.approx(ev.station_waits[k].sum(1).mean())
        assert sum(t["ends"].values()) == pytest.approx(1.0)
    fig = summary["figure10"][0]
    assert len(fig["robots"]) == 3
    assert fig["squares"] <= sum(r["squares"] for r in fig["robots"])
    np.testing.assert_array_equal(
        summary["figure10_starts"], figure10_starts(WORLD, ColonySettings())
    )


def assert_resumes_bit_for_bit(ref, out, checkpoint, ga=TINY, **kw):
    """A colony stage killed in population 1's generation 17 (``ga``: 18 generations,
    checkpoints at 0 and 16) leaves ``checkpoint`` and, resumed, replays generations 16–18
    to the files of the uninterrupted run in ``ref``."""

    def kill_at(info):
        if info["population"] == 1 and info["generation"] == 17:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_colony_stage(out, navigation=NAV, table=TABLE, ga=ga, on_generation=kill_at, **kw)
    assert (out / "colony/checkpoints" / checkpoint).exists()
    seen = []
    run_colony_stage(out, navigation=NAV, table=TABLE, ga=ga, resume=True,
                     on_generation=seen.append, **kw)  # fmt: skip
    assert [(i["population"], i["generation"]) for i in seen] == [(1, g) for g in (16, 17, 18)]
    assert _files(ref / "colony") == _files(out / "colony")


def test_resume_after_interruption_equals_uninterrupted_run(tiny_run, tmp_path):
    assert_resumes_bit_for_bit(tiny_run[0], tmp_path, "pop1.npz")


def test_populations_in_a_process_pool_give_the_same_files(tiny_run, tmp_path):
    """The colony's Stage (its bound evaluator and starts) travels to worker processes."""
    ref, _ = tiny_run
    run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, executor=ProcessExecutor(2))
    assert _files(ref / "colony") == _files(tmp_path / "colony")


def test_other_colony_settings_are_refused_on_resume(tmp_path):
    def kill_at(info):
        if info["generation"] == 2:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, on_generation=kill_at)
    with pytest.raises(InputError, match=r"other settings \(ColonySettings.robots: 3 there"):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, resume=True,
                         colony=ColonySettings(robots=2))  # fmt: skip
    with pytest.raises(InputError, match='ColonySettings.blocking: absent there, "slide" here'):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, resume=True,
                         colony=ColonySettings(blocking="slide"))  # fmt: skip
    with pytest.raises(StageError, match="cannot place robot"):
        run_colony_stage(tmp_path / "crowded", navigation=NAV, table=TABLE, ga=TINY,
                         colony=ColonySettings(robots=30))  # fmt: skip
    with pytest.raises(StageError, match="navigation section"):
        run_colony_stage(tmp_path, navigation=NAV[:7], table=TABLE, ga=TINY)


def test_short_colony_evolution_learns_to_cover(tmp_path):
    # 32 × 40 with the light follower: over seeds 0–4 the test fitness rose by 4.7–22 points
    # to ≥ 26 %, and the colony covered 2–3× what each best covers alone.
    ga = GASettings(populations=1, population_size=32, generations=40, test_starts=30, seed=0)
    summary = run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=ga)
    first, last = summary["figure9_inner_percent"][0][0], summary["final_inner_percent"][0]
    assert last >= first + 5.0 and last >= 25.0
    assert last > 1.5 * summary["one_robot_final_mean_inner_percent"]
    hist = np.loadtxt(tmp_path / "colony/history_pop0.csv", delimiter=",", skiprows=1)
    assert hist[-8:, 2].mean() > 1.3 * hist[:8, 2].mean()  # population mean fitness rises
