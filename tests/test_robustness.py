"""``servobot robustness``: the physics test matrix end to end on a tiny case (a coverage
chromosome and a navigation section × shipped and weak, 1 start, 20 steps), resume, the
worlds registry, and bad inputs."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER

from infra.executors import SerialExecutor
from infra.rundir import RunDirError
from servo_mj.robot.model import model_sha256
from servo_mj.robot.variant import VariantParams, read_variant
from servobot.cli import main as servobot
from servobot.robustness.matrix import (
    RobustnessError,
    RobustnessSettings,
    run_matrix,
    unique_names,
)
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


def test_a_matrix_resumed_across_the_hand_off_records_still_finishes(matrix, tmp_path):
    # a cell finished before coverage records carried their hand-offs (forty-fifth session),
    # the other world's cell run anew: the table world is still one world
    out, files, doc = matrix
    copy = tmp_path / "m"
    shutil.copytree(out, copy)
    old = copy / "runs" / "shipped" / "c16" / "report.json"
    rep = json.loads(old.read_text())
    assert all("handoffs" in r["table"] for r in rep["runs"])
    for r in rep["runs"]:
        for side in ("table", "physics"):
            del r[side]["handoffs"]
    old.write_text(json.dumps(rep))
    (copy / "runs" / "weak" / "c16" / "report.json").unlink()
    again = run_matrix(files, copy, SETTINGS, executor=SerialExecutor(), resume=True)
    assert _placeless(again) == _placeless(doc)
    # a table run that differs is still caught
    rep["runs"][0]["table"]["docks"] += 1
    old.write_text(json.dumps(rep))
    (copy / "runs" / "weak" / "c16" / "report.json").unlink()
    with pytest.raises(RuntimeError, match="c16: the table world differs"):
        run_matrix(files, copy, SETTINGS, executor=SerialExecutor(), resume=True)


def _without_wall_times(report: dict) -> list[dict]:
    """A cell report's runs with the per-run wall times (which no two runs share) dropped."""
    return [{k: ({f: v for f, v in side.items() if f != "wall_s"} if isinstance(side, dict)
                 and k in ("table", "physics") else side) for k, side in r.items()}
            for r in report["runs"]]  # fmt: skip


def _placeless(d: dict) -> dict:
    """A matrix document without its worlds' model paths (the weak world's model file lies in
    each folder)."""
    return d | {"worlds": [{k: v for k, v in w.items() if k != "model"} for w in d["worlds"]]}


def test_a_grown_matrix_takes_the_earlier_runs_and_equals_one_run_in_full(matrix, tmp_path):
    """Start poses and servo noise of run k depend on the seed and k alone, so a matrix grown
    from 1 start to 2 takes each cell's first run from the earlier one and runs only the
    second; its records are those of the 2-start matrix run from scratch."""
    out, files, _ = matrix
    grown = dataclasses.replace(SETTINGS, starts=2)
    runs, taken = [], []
    doc = run_matrix(files, tmp_path / "grown", grown, executor=SerialExecutor(), reuse=out,
                     on_run=runs.append, on_skip=taken.append)  # fmt: skip
    assert [r["index"] for r in runs] == [1, 1, 1, 1] and taken == [1, 1, 1, 1]
    full = run_matrix(files, tmp_path / "full", grown, executor=SerialExecutor())
    assert _placeless(doc) == _placeless(full)
    for w in WORLDS:
        for name in ("c16", "nav"):
            a, b = (tmp_path / d / "runs" / w / name for d in ("grown", "full"))
            ra, rb = (json.loads((c / "report.json").read_text()) for c in (a, b))
            assert _without_wall_times(ra) == _without_wall_times(rb)
            assert ra["meta"]["reused_runs"] == 1 and "reused_runs" not in rb["meta"]
            with np.load(a / "tracks.npz") as ta, np.load(b / "tracks.npz") as tb:
                assert sorted(ta.files) == sorted(tb.files)
                for k in ta.files:
                    np.testing.assert_array_equal(ta[k], tb[k])


def test_reuse_takes_nothing_from_other_starts_and_refuses_bad_folders(matrix, tmp_path):
    out, files, _ = matrix
    runs: list[dict] = []
    other = dataclasses.replace(SETTINGS, seed=1, worlds=("shipped",))  # other start poses
    run_matrix(files[:1], tmp_path / "s1", other, executor=SerialExecutor(), reuse=out,
               on_run=runs.append)  # fmt: skip
    assert len(runs) == 1
    with pytest.raises(RobustnessError, match="the output folder itself"):
        run_matrix(files, out, SETTINGS, executor=SerialExecutor(), resume=True, reuse=out)
    with pytest.raises(RobustnessError, match="--rrd"):
        run_matrix(files, tmp_path / "r", dataclasses.replace(SETTINGS, rrd=True), reuse=out)


def test_reuse_gathers_a_matrix_from_folders_run_controller_by_controller(matrix, tmp_path):
    """``--reuse A --reuse B``: each cell's runs come from the first folder that has them, so
    a matrix whose controllers ran in separate folders is gathered without running again."""
    out, files, doc = matrix
    parts = {}
    for name, other in (("c16", "nav"), ("nav", "c16")):
        parts[name] = tmp_path / f"only_{name}"
        shutil.copytree(out, parts[name])
        for w in WORLDS:
            shutil.rmtree(parts[name] / "runs" / w / other)
    gathered = tmp_path / "gathered"
    argv = ["robustness", *map(str, files), *ARGV, "--out", str(gathered)]
    assert servobot([*argv, "--reuse", str(parts["c16"]), "--reuse", str(parts["nav"])]) == 0
    for w in WORLDS:
        for name in ("c16", "nav"):
            meta = json.loads((gathered / "runs" / w / name / "report.json").read_text())["meta"]
            assert meta["reused_runs"] == 1 and meta["reused_from"] == str(parts[name])
    assert _placeless(json.loads((gathered / "robustness.json").read_text())) == _placeless(doc)
    first = tmp_path / "first"  # both folders hold the c16 cells: the first named gives them
    argv = ["robustness", *map(str, files), *ARGV, "--out", str(first)]
    assert servobot([*argv, "--reuse", str(out), "--reuse", str(parts["c16"])]) == 0
    for w in WORLDS:
        for name in ("c16", "nav"):
            meta = json.loads((first / "runs" / w / name / "report.json").read_text())["meta"]
            assert meta["reused_from"] == str(out)


class _StopAfter(SerialExecutor):
    """A serial executor interrupted (Ctrl-C) after ``n`` items."""

    def __init__(self, n: int) -> None:
        self.n = n

    def imap(self, fn, items):
        for k, outcome in enumerate(super().imap(fn, items)):
            if k == self.n:
                raise KeyboardInterrupt
            yield outcome


def test_an_interrupted_matrix_keeps_its_finished_runs_and_shares_cycles(tmp_path):
    """Two coverage chromosomes × 2 starts in ``shipped``, their runs from one start sharing
    one physics tree: Ctrl-C after the first start keeps its two runs (``kept/``), the resumed
    matrix runs only the second start and the run whose kept file was damaged, and every
    record is the one of a matrix run apart."""
    files = [tmp_path / "c16.txt", tmp_path / "d16.txt"]
    files[0].write_text(GENE * 16)
    files[1].write_text("00 0100000 0010000 0100000 0010000\n" * 16)
    s = RobustnessSettings(worlds=("shipped",), starts=2, steps=20)
    full = run_matrix(files, tmp_path / "full", s, executor=SerialExecutor())
    cut = tmp_path / "cut"
    with pytest.raises(KeyboardInterrupt):
        run_matrix(files, cut, s, executor=_StopAfter(1), share=True)
    assert sorted(p.relative_to(cut).as_posix() for p in (cut / "kept").rglob("*.npz")) == [
        "kept/shipped/c16/run0.npz", "kept/shipped/d16/run0.npz"]  # fmt: skip
    (cut / "kept/shipped/d16/run0.npz").write_bytes(b"not a zip")  # damaged: runs again
    runs, skipped = [], []
    again = run_matrix(files, cut, s, executor=SerialExecutor(), resume=True, share=True,
                       on_run=runs.append, on_skip=skipped.append)  # fmt: skip
    assert sorted(r["index"] for r in runs) == [0, 1, 1] and skipped == [1]
    assert again == full and not (cut / "kept").exists()
    for name in ("c16", "d16"):
        a, b = (json.loads((d / "runs" / "shipped" / name / "report.json").read_text())
                for d in (cut, tmp_path / "full"))  # fmt: skip
        assert _without_wall_times(a) == _without_wall_times(b)


def test_the_share_option_gives_the_same_matrix(tmp_path):
    (tmp_path / "c16.txt").write_text(GENE * 16)
    (tmp_path / "d16.txt").write_text("00 0100000 0010000 0100000 0010000\n" * 16)
    files = [str(tmp_path / f) for f in ("c16.txt", "d16.txt")]
    argv = ["--worlds", "shipped", "--starts", "1", "--steps", "10", "--workers", "1",
            "--no-progress"]  # fmt: skip
    for out, extra in (("a", []), ("b", ["--share"])):
        assert servobot(["robustness", *files, *argv, *extra, "--out", str(tmp_path / out)]) == 0
    a, b = (json.loads((tmp_path / d / "robustness.json").read_text()) for d in "ab")
    assert a == b


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ({"index": 2}, "run index 2 is not one of 2 starts"),
        ({"index": 0, "start": {"x": 1.0, "y": 2.0, "h": 3.0}}, "run 0 started at"),
        ({"index": 1, "physics": None}, "run 1 has no physics result"),
    ],
)
def test_a_validation_refuses_taken_runs_that_are_not_its_own(record, message):
    from servobot.validation.lone import ValidationError, plan_validation, start_record

    starts = np.array([[250.0, 250.0, 0.0], [200.0, 300.0, 90.0]])
    bits = np.array([[int(c) for c in GENE.replace(" ", "").strip()]] * 16, dtype=np.uint8)
    good = {"index": 0, "start": start_record(tuple(starts[0])), "physics": {}, "error": None}
    plan = plan_validation(bits, starts, table=np.zeros((16, 3)), done=[good])
    assert [j.index for j in plan.jobs] == [1]
    rec = good | {"start": start_record(tuple(starts[record["index"] % 2]))} | record
    with pytest.raises(ValidationError, match=message):
        plan_validation(bits, starts, table=np.zeros((16, 3)), done=[rec])


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
        (["{c16}", "--reuse", "{dir}"], "not a robustness matrix folder"),
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
