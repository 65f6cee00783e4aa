"""The noise floor of issue 16's agreement measures: ``servobot robustness --noise-seed`` (the
same starts under another servo-noise draw), ``ranking.noise_ceiling`` (an envelope against
one draw of itself) and ``python -m servobot.robustness.floor`` on hand-made matrices."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from evolve.envelope import DEFAULT, NONE
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import load_table
from servobot.cli import main as servobot
from servobot.robustness.floor import FloorError, physics_floor
from servobot.robustness.floor import main as floor_main
from servobot.robustness.matrix import RobustnessSettings, check_settings, settings_record
from servobot.robustness.ranking import Genome, noise_ceiling

GENE = "01 0100000 0100000 0100000 0100000\n"


def _genomes(n: int) -> list[Genome]:
    rng = np.random.default_rng(3)
    return [Genome(f"g{i}", rng.integers(0, 2, (16, 30), dtype=np.uint8)) for i in range(n)]


def test_a_world_without_variation_is_its_own_perfect_prediction():
    starts = coverage_starts(np.random.default_rng(0), 6, WorldSettings())
    ceiling = noise_ceiling(_genomes(12), starts, table=load_table("paper"), envelope=NONE,
                            realisations=2, steps=120)  # fmt: skip
    assert ceiling["spearman"] == 1.0 and ceiling["mean_abs_delta"] == 0.0
    assert ceiling["table_mean"] == ceiling["physics_mean"]


def test_an_envelope_disagrees_with_one_draw_of_itself():
    starts = coverage_starts(np.random.default_rng(0), 6, WorldSettings())
    args = dict(table=load_table("paper"), envelope=DEFAULT, draws=4, realisations=2, steps=120)
    ceiling = noise_ceiling(_genomes(12), starts, **args)
    assert ceiling["mean_abs_delta"] > 0.0 and ceiling["spearman"] < 1.0
    assert noise_ceiling(_genomes(12), starts, **args) == ceiling  # seeded: repeatable
    with pytest.raises(ValueError, match="realisations must be ≥ 1"):
        noise_ceiling(_genomes(2), starts, **args | {"realisations": 0})


def test_the_noise_seed_is_recorded_only_when_given():
    assert "noise_seed" not in settings_record(RobustnessSettings(worlds=()), [], [], [], {})[
        "RobustnessSettings"
    ]  # so folders written before it still resume
    given = RobustnessSettings(worlds=(), noise_seed=4)
    assert settings_record(given, [], [], [], {})["RobustnessSettings"]["noise_seed"] == 4
    assert given.servo_seed == 4 and RobustnessSettings(seed=2).servo_seed == 2
    with pytest.raises(ValueError, match="--noise-seed must be an integer ≥ 0, got -1"):
        check_settings(RobustnessSettings(noise_seed=-1), 1, 1)


def test_another_noise_seed_runs_the_same_starts_under_other_noise(tmp_path):
    (tmp_path / "c16.txt").write_text(GENE * 16)
    argv = ["robustness", str(tmp_path / "c16.txt"), "--worlds", "shipped", "--starts", "2",
            "--steps", "12", "--workers", "1", "--no-progress"]  # fmt: skip
    assert servobot([*argv, "--out", str(tmp_path / "a")]) == 0
    assert servobot([*argv, "--noise-seed", "1", "--out", str(tmp_path / "b")]) == 0
    a, b = (json.loads((tmp_path / d / "robustness.json").read_text()) for d in "ab")
    assert a["start_poses"] == b["start_poses"] and b["noise_seed"] == 1 and "noise_seed" not in a
    assert a["table_per_chromosome"] == b["table_per_chromosome"]
    runs = [json.loads((tmp_path / d / "runs/shipped/c16/report.json").read_text())["runs"]
            for d in "ab"]  # fmt: skip
    poses = [[r["physics"]["final_pose"] for r in rs] for rs in runs]
    assert poses[0] != poses[1]  # the servo noise differs, run by run
    physics, genomes, starts = physics_floor(tmp_path / "a", tmp_path / "b")
    assert [g.label for g in genomes] == ["c16"] and starts.shape == (2, 3)
    assert set(physics) == {"shipped"} and physics["shipped"]["chromosomes"] == 1


def _fake_matrix(folder: Path, inner: list[list[int]], *, noise_seed: int | None, poses=None):
    """A finished matrix folder of len(inner) chromosomes in ``shipped`` with these physics
    inner squares per start (only what ``floor`` reads)."""
    poses = poses or [[100.0, 100.0 + 10 * s, 0.0] for s in range(len(inner[0]))]
    doc = {"starts": len(poses), "steps": 600, "seed": 0, "start_poses": {"coverage": poses},
           "worlds": [{"name": "shipped"}]} | ({} if noise_seed is None else
                                              {"noise_seed": noise_seed})  # fmt: skip
    folder.mkdir(parents=True)
    (folder / "robustness.json").write_text(json.dumps(doc))
    controllers = [{"name": f"c{i}", "chromosome": GENE * 16} for i in range(len(inner))]
    (folder / "settings.json").write_text(json.dumps({"controllers": controllers}))
    for i, row in enumerate(inner):
        cell = folder / "runs" / "shipped" / f"c{i}"
        cell.mkdir(parents=True)
        runs = [{"index": s, "physics": {"inner_squares": v}} for s, v in enumerate(row)]
        (cell / "report.json").write_text(json.dumps({"runs": runs}))


def test_the_physics_floor_by_hand(tmp_path):
    _fake_matrix(tmp_path / "a", [[10, 20], [30, 40], [5, 5]], noise_seed=None)
    _fake_matrix(tmp_path / "b", [[12, 17], [30, 44], [9, 7]], noise_seed=1)
    physics, _, _ = physics_floor(tmp_path / "a", tmp_path / "b")
    shipped = physics["shipped"]
    # |Δ| per run: 2, 3, 0, 4, 4, 2 → 15 / 6; means a 15, 35, 5 and b 14.5, 37, 8 (same order)
    assert shipped["mean_abs_delta"] == pytest.approx(2.5)
    assert shipped["best_abs_delta"] == pytest.approx(2.5 / np.sqrt(2.0))
    assert shipped["spearman"] == pytest.approx(1.0)
    assert shipped["table_mean"] == pytest.approx(55 / 3) and shipped["chromosomes"] == 3
    assert floor_main([str(tmp_path / "a"), str(tmp_path / "b"), "--draws", "2",
                       "--realisations", "1", "--out", str(tmp_path / "out")]) == 0  # fmt: skip
    doc = json.loads((tmp_path / "out" / "floor.json").read_text())
    assert doc["physics"]["shipped"]["mean_abs_delta"] == pytest.approx(2.5)
    assert set(doc["table"]) == {"shipped"} and "| shipped | 1.00 | 2.5 | 1.8 |" in (
        tmp_path / "out" / "floor.md"
    ).read_text()


@pytest.mark.parametrize(
    ("b_kwargs", "message"),
    [
        ({"noise_seed": None}, "share their servo noise (seed 0)"),
        ({"noise_seed": 1, "poses": [[1.0, 1.0, 0.0], [2.0, 2.0, 0.0]]}, "differ in start_poses"),
    ],
)
def test_matrices_that_are_not_a_repeat_are_refused(tmp_path, b_kwargs, message, capsys):
    _fake_matrix(tmp_path / "a", [[10, 20]], noise_seed=None)
    _fake_matrix(tmp_path / "b", [[10, 20]], **b_kwargs)
    with pytest.raises(FloorError, match=re.escape(message)):
        physics_floor(tmp_path / "a", tmp_path / "b")
    assert floor_main([str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "o").exists()
    with pytest.raises(FloorError, match="not a finished `servobot robustness` folder"):
        physics_floor(tmp_path / "a", tmp_path / "missing")
