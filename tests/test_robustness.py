"""``servobot robustness``: the physics test matrix end to end on a tiny case (a coverage
chromosome and a navigation section × shipped and weak, 1 start, 20 steps), resume, the
worlds registry, and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from chromosome_text import LIGHT_FOLLOWER

from infra.executors import SerialExecutor
from infra.rundir import RunDirError
from servo_mj.robot.model import model_sha256
from servo_mj.robot.variant import VariantParams, read_variant
from servobot.cli import main as servobot
from servobot.robustness.matrix import RobustnessSettings, run_matrix, unique_names
from servobot.robustness.worlds import (
    BUILT_IN,
    HELD_OUT,
    SLIPPERY_FRICTION_SCALE,
    WEAK_TORQUE_SCALE,
    WorldError,
    resolve_worlds,
)

GENE = "01 0100000 0100000 0100000 0100000\n"
WORLDS = ("shipped", "weak")
SETTINGS = RobustnessSettings(worlds=WORLDS, starts=1, steps=20)
ARGV = ["--worlds", ",".join(WORLDS), "--starts", "1", "--steps", "20", "--workers", "1",
        "--no-progress"]  # fmt: skip


@pytest.fixture(scope="module")
def matrix(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path], dict]:
    """The tiny matrix, run once through the command line."""
    d = tmp_path_factory.mktemp("robustness")
    (d / "c16.txt").write_text(GENE * 16)
    (d / "nav.txt").write_text(LIGHT_FOLLOWER)
    files = [d / "c16.txt", d / "nav.txt"]
    out = d / "out"
    assert servobot(["robustness", *map(str, files), *ARGV, "--out", str(out)]) == 0
    return out, files, json.loads((out / "robustness.json").read_text())


def test_json_schema(matrix):
    out, files, doc = matrix
    assert [w["name"] for w in doc["worlds"]] == list(WORLDS)
    assert doc["starts"] == 1 and doc["steps"] == 20 and doc["seed"] == 0
    assert doc["table"]["source"] == "paper" and len(doc["table"]["sha256"]) == 64
    for w in doc["worlds"]:
        assert {"name", "description", "model_sha256", "physics_inner_percent", "dock_rate",
                "drop_vs_shipped_pp", "per_chromosome"} <= set(w)  # fmt: skip
        cov, nav = w["per_chromosome"]
        assert [cov["file"], nav["file"]] == [str(f) for f in files]
        assert 0.0 <= cov["physics_inner_percent"] <= 100.0
        assert nav["physics_inner_percent"] is None and 0.0 <= nav["dock_rate"] <= 1.0
        assert sum(cov["ends"].values()) == 1 and sum(nav["ends"].values()) == 1
        assert w["physics_inner_percent"] == cov["physics_inner_percent"]
        assert w["dock_rate"] == nav["dock_rate"]
    assert doc["worlds"][0]["drop_vs_shipped_pp"] == 0.0
    t_cov, t_nav = doc["table_per_chromosome"]
    assert doc["table_inner_percent"] == t_cov["table_inner_percent"]
    assert t_nav["table_inner_percent"] is None and doc["table_dock_rate"] == t_nav["dock_rate"]
    assert set(doc["start_poses"]) == {"coverage", "navigation"}


def test_the_table_world_is_the_same_in_every_world(matrix):
    out, _, doc = matrix
    for name, mode in (("c16", "coverage"), ("nav", "navigation")):
        reps = [json.loads((out / "runs" / w / name / "report.json").read_text()) for w in WORLDS]
        for rep in reps:
            assert rep["settings"]["mode"] == mode
            assert [list(r["start"].values()) for r in rep["runs"]] == doc["start_poses"][mode]
            assert rep["summary"]["table"]["ends"] == reps[0]["summary"]["table"]["ends"]
            t = rep["summary"]["table"]
            assert t["inner_pct"] == reps[0]["summary"]["table"]["inner_pct"]
    assert reps[0]["settings"]["max_steps"] == 20  # a section runs min(--steps, 100)


def test_markdown_and_figure_exist(matrix):
    out, _, _ = matrix
    md = (out / "robustness.md").read_text()
    assert "| chromosome | table | shipped | weak |" in md
    assert "**mean**" in md and "**drop vs shipped (pp)**" in md and "nav (docking %)" in md
    assert (out / "robustness.png").read_bytes()[:4] == b"\x89PNG"


def test_the_weak_world_has_the_lower_torque(matrix):
    out, _, doc = matrix
    weak = read_variant(out / "models" / "weak.xml")
    base = VariantParams()
    assert weak.servo_torque_nm == pytest.approx(base.servo_torque_nm * WEAK_TORQUE_SCALE)
    assert weak.servo_torque_nm < base.servo_torque_nm and weak.changed().keys() == {
        "servo_torque_nm"
    }
    shipped, w = doc["worlds"]
    assert w["model_sha256"] == model_sha256(out / "models" / "weak.xml")
    assert shipped["model_sha256"] == model_sha256(None)
    assert not (out / "models" / "shipped.xml").exists()


def test_resume_reads_every_cell_back_and_runs_no_physics(matrix):
    out, files, doc = matrix
    runs, skipped = [], []
    with pytest.raises(RunDirError, match="already holds this run"):
        run_matrix(files, out, SETTINGS, executor=SerialExecutor())
    again = run_matrix(files, out, SETTINGS, executor=SerialExecutor(), resume=True,
                       on_run=runs.append, on_skip=skipped.append)  # fmt: skip
    assert runs == [] and sum(skipped) == 4
    assert again == doc


def test_resume_reruns_only_an_unfinished_cell(matrix, tmp_path):
    out, files, doc = matrix
    (out / "runs" / "weak" / "c16" / "report.json").unlink()
    runs: list[dict] = []
    again = run_matrix(files, out, SETTINGS, executor=SerialExecutor(), resume=True,
                       on_run=runs.append)  # fmt: skip
    assert len(runs) == 1
    assert again == doc  # same seeds: the same record


def test_built_in_worlds():
    assert list(BUILT_IN) == ["shipped", "station-seen", "heavy", "weak", "slippery", "long-legs"]
    assert BUILT_IN["station-seen"].arena.station_height_m == 0.30
    assert BUILT_IN["shipped"].variant is None and BUILT_IN["station-seen"].variant is None
    slippery = BUILT_IN["slippery"].variant
    assert slippery.effective_friction == pytest.approx(
        VariantParams().effective_friction * SLIPPERY_FRICTION_SCALE
    )
    for name in ("heavy", "weak", "long-legs"):
        assert len(BUILT_IN[name].variant.changed()) == 1
    assert BUILT_IN["long-legs"] is HELD_OUT and "held out" in HELD_OUT.description
    assert unique_names([Path("a/best.txt"), Path("b/best.txt"), Path("x.txt")]) == [
        "best", "best-2", "x",
    ]  # fmt: skip


def test_a_variant_file_is_a_world_named_by_its_stem(tmp_path):
    from servo_mj.robot.variant import write_variant

    path = write_variant(VariantParams(torso_mass_kg=1.2), tmp_path / "mine.xml")
    (world,) = resolve_worlds([str(path)])
    assert world.name == "mine" and world.variant.torso_mass_kg == 1.2
    with pytest.raises(WorldError, match="given twice"):
        resolve_worlds(["shipped", "shipped"])


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["{c16}", "--worlds", "shipped,moon"], "'moon' is neither a built-in world"),
        (["{c16}", "--worlds", "moon"], "built-in worlds: shipped, station-seen, heavy"),
        (["{dir}/missing.txt"], "missing.txt: no such chromosome file"),
        (["{c16}", "--starts", "0"], "--starts must be an integer ≥ 1, got 0"),
        (["{c16}", "--steps", "0"], "--steps must be an integer ≥ 1, got 0"),
        (["{c16}", "--worlds", "{c16}"], "c16.txt: not well-formed XML"),
        (["{c7}"], "expected 8 or 16 genes, found 7"),
    ],
)
def test_bad_input_exits_2_naming_it(argv, message, tmp_path, capsys):
    (tmp_path / "c16.txt").write_text(GENE * 16)
    (tmp_path / "c7.txt").write_text(GENE * 7)
    fill = {"c16": tmp_path / "c16.txt", "c7": tmp_path / "c7.txt", "dir": tmp_path}
    args = [a.format(**fill) for a in argv]
    code = servobot(["robustness", *args, "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
