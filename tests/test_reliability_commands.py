"""Issue 19 (folders, settings, resume, messages): the newer commands keep the reliability
promises. A run folder belongs to one command as well as one run; every setting is checked
against the others before work; resume names the record that fails; no message misleads.

Each case runs in-process (``servobot.cli.main(argv)``) with tiny settings and asserts exit 2,
no traceback, a message naming the option or file, and nothing written or changed."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from infra.rundir import RECORD_FILE, RunDirError, run_folder
from servobot.cli import main as servobot

GENE = "01 0100000 0100000 0100000 0100000\n"


def _run(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    try:
        code = servobot([str(a) for a in argv])
    except SystemExit as exc:  # argparse
        code = exc.code
    return code, capsys.readouterr().err


def _bytes(folder: Path) -> dict[Path, bytes]:
    """Every file under ``folder`` (the lock aside) and its bytes."""
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file() and p.name != ".lock"}


def _edited_copy(
    run: Path, out: Path, name: str, edit: Callable[[Any], object]
) -> tuple[Path, Any]:
    """Copy the run folder ``run`` to ``out`` and put its JSON file ``name`` through ``edit``;
    returns (that file, its edited document)."""
    shutil.copytree(run, out)
    path = out / name
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    return path, doc


def _refused(argv: list[str], capsys: pytest.CaptureFixture, *names: str) -> str:
    code, err = _run(argv, capsys)
    assert code == 2, err
    assert "Traceback" not in err, err
    for name in names:
        assert name in err, err
    return err


@pytest.fixture(scope="module")
def chrom16(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("inputs") / "c16.txt"
    path.write_text(GENE * 16)
    return path


# --------------------------------------------------------------------------- one command a folder


def test_a_folder_records_its_command_and_refuses_another_even_with_force(tmp_path):
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], command="validate"):
        (tmp_path / "a.txt").write_text("a")
    assert json.loads((tmp_path / RECORD_FILE).read_text()) == {"command": "validate", "seed": 1}
    before = _bytes(tmp_path)
    for force in (False, True):
        with pytest.raises(RunDirError, match="holds a 'servobot validate' run .* not a 'servobot "
                           "compare' one; nothing in it was changed"):  # fmt: skip
            with run_folder(tmp_path, {"tables": []}, owned=["b.txt"], command="compare",
                            force=force):  # fmt: skip
                pass
    assert _bytes(tmp_path) == before
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], command="validate", resumable=False):
        pass  # the same command and settings: redone


def test_an_old_record_without_a_command_is_judged_by_its_files(tmp_path):
    (tmp_path / RECORD_FILE).write_text(json.dumps({"seed": 1}))
    (tmp_path / "a.txt").write_text("a")
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], command="evolve navigation",
                    resume=True) as claim:  # fmt: skip
        assert claim.state == "resumed"
    assert json.loads((tmp_path / RECORD_FILE).read_text())["command"] == "evolve navigation"
    (tmp_path / RECORD_FILE).write_text(json.dumps({"seed": 1}))
    with pytest.raises(RunDirError, match=r"seed: 1 there, 2 here"):
        with run_folder(tmp_path, {"seed": 2}, owned=["a.txt"], command="evolve navigation"):
            pass


@pytest.mark.parametrize("record", [b"{not json", b"[1, 2]", b"\xff\xfe\x00"])
def test_a_corrupt_record_is_named_not_called_other_settings(tmp_path, record):
    (tmp_path / RECORD_FILE).write_bytes(record)
    for owned in (["a.txt"], ["b.txt"]):  # with and without this run's files
        (tmp_path / "a.txt").write_text("a")
        with pytest.raises(RunDirError, match=rf"ownership record that cannot be read \({tmp_path}"
                           rf"/{RECORD_FILE}: ") as exc:  # fmt: skip
            with run_folder(tmp_path, {"seed": 1}, owned=owned, command="validate"):
                pass
        assert "other settings" not in str(exc.value)
        assert (tmp_path / RECORD_FILE).read_bytes() == record
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], force=True) as claim:
        assert claim.state == "forced"


def test_compare_refuses_a_validation_folder_and_validate_a_compare_folder(
    chrom16, tmp_path, capsys
):
    val, cmp = tmp_path / "val", tmp_path / "cmp"
    code, err = _run(["validate", chrom16, "--starts", "1", "--steps", "1", "--workers", "1",
                      "--no-progress", "--out", val], capsys)  # fmt: skip
    assert code == 0, err
    assert json.loads((val / RECORD_FILE).read_text())["command"] == "validate"
    assert _run(["compare", "paper", "paper", "--labels", "a", "b", "--out", cmp], capsys)[0] == 0
    before_val, before_cmp = _bytes(val), _bytes(cmp)
    for force in ([], ["--force"]):
        _refused(["compare", "paper", "paper", "--labels", "a", "b", "--out", val, *force],
                 capsys, str(val), "'servobot validate' run")  # fmt: skip
        _refused(["validate", chrom16, "--starts", "1", "--steps", "1", "--workers", "1",
                  "--no-progress", "--out", cmp, *force], capsys, str(cmp),
                 "'servobot compare' run")  # fmt: skip
    assert _bytes(val) == before_val and _bytes(cmp) == before_cmp


# --------------------------------------------------------------------------- settings vs settings

TINY = ["--populations", "1", "--population-size", "4", "--generations", "2", "--no-progress"]


@pytest.mark.parametrize("robots", ["8", "9", "40"])
def test_colony_robots_that_jam_the_start_region_are_refused_before_work(
    chrom16, tmp_path, capsys, robots
):
    out = tmp_path / "out"
    err = _refused(["evolve", "colony", "--robots", robots, "--navigation", chrom16, *TINY,
                    "--out", out], capsys, f"--robots {robots}", "at most 7 robots",
                   "cannot place robot")  # fmt: skip
    assert "--robots 7 or fewer" in err
    assert not out.exists()


def test_colony_robots_that_fit_run(chrom16, tmp_path):
    from evolve.settings import ColonySettings, WorldSettings
    from evolve.starts import colony_capacity

    assert colony_capacity(WorldSettings(), ColonySettings(robots=3)) == 3
    assert colony_capacity(WorldSettings(), ColonySettings(robots=7)) == 7


@pytest.mark.parametrize(
    "argv",
    [
        ["evolve", "navigation", "--populations", "1000000000"],
        ["evolve", "navigation", "--generations", "1000000000000000000"],
        ["validate", "{c16}", "--starts", "1000000000"],
        ["calibrate", "--cycles", "1000000000"],
    ],
)
def test_a_refusal_for_size_leaves_no_empty_out_folder(chrom16, tmp_path, capsys, argv):
    out = tmp_path / "new" / "out"
    argv = [a.replace("{c16}", str(chrom16)) for a in argv]
    _refused([*argv, "--out", out], capsys)
    assert not (tmp_path / "new").exists()
    out.mkdir(parents=True)  # a folder that was there stays
    _refused([*argv, "--out", out], capsys)
    assert out.is_dir()


# --------------------------------------------------------------------------- anytime

ANYTIME = ["--populations", "1", "--population-size", "8", "--generations", "4", "--every", "2",
           "--top", "2", "--physics-starts", "1", "--physics-steps", "3", "--final-starts", "1",
           "--executor", "serial"]  # fmt: skip


def _anytime(nav: Path, out: Path, *more: str) -> list[str]:
    """``servobot anytime`` with the tiny settings, an option given in ``more`` replacing its
    default."""
    opts = dict(zip(ANYTIME[::2], ANYTIME[1::2], strict=True))
    opts |= dict(zip(more[::2], more[1::2], strict=True))
    return ["anytime", "--navigation", str(nav), *[x for kv in opts.items() for x in kv],
            "--no-progress", "--out", str(out)]  # fmt: skip


@pytest.fixture(scope="module")
def nav(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("nav") / "nav.txt"
    path.write_text("01 0000000 0000000 0000000 0000000\n" * 8)
    return path


@pytest.fixture(scope="module")
def runs(nav, tmp_path_factory) -> dict[str, Path]:
    """A finished bias run and a finished control (method none) run, tiny."""
    d = tmp_path_factory.mktemp("anytime")
    for method in ("bias", "none"):
        assert servobot(_anytime(nav, d / method, "--method", method)) == 0
    return {"bias": d / "bias", "none": d / "none"}


@pytest.mark.parametrize(
    ("more", "names"),
    [
        (["--every", "8"], ["--every 8 is larger than --generations 4"]),
        (["--top", "9"], ["--top 9 is larger than --population-size 8"]),
    ],
)
def test_anytime_settings_that_contradict_each_other(nav, tmp_path, capsys, more, names):
    _refused(_anytime(nav, tmp_path / "out", *more), capsys, *names)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("more", "field"),
    [
        (["--generations", "6"], "GASettings.generations: 4 there, 6 here"),
        (["--population-size", "10"], "GASettings.population_size: 8 there, 10 here"),
        (["--seed", "3"], "GASettings.seed: 0 there, 3 here"),
        (["--physics-steps", "4"], "AnytimeSettings.physics_steps: 3 there, 4 here"),
        (["--table", "{table}"], "table.values"),
    ],
)
def test_anytime_baseline_of_other_settings_is_refused(runs, nav, tmp_path, capsys, more, field):
    from evolve.table import PAPER_TABLE, table_to_json

    table = tmp_path / "table.json"
    values = PAPER_TABLE.copy()
    values[0, 0] += 1.0
    table.write_text(json.dumps(table_to_json(values)))
    more = [m.replace("{table}", str(table)) for m in more]
    argv = _anytime(nav, tmp_path / "out", *more, "--baseline", str(runs["none"]))
    _refused(argv, capsys, f"--baseline {runs['none']}", "summary.json", field)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["best_by_generation"].update(physics_fitness=["x", 1.0]),
         "best_by_generation.physics_fitness"),
        (lambda d: d["best_by_generation"].update(generations=[2]), "best_by_generation"),
        (lambda d: d.update(best_by_generation=[1, 2]), "best_by_generation"),
        (lambda d: d["final"].update(physics_inner_percent="41%"), "final.physics_inner_percent"),
        (lambda d: d.update(final=None), "final.physics_inner_percent"),
        (lambda d: d.update(settings=7), "settings"),
        (lambda d: d.update(method=["none"]), "method"),
    ],
)
def test_anytime_malformed_baseline_is_refused_before_work(
    runs, nav, tmp_path, capsys, edit, field
):
    base = tmp_path / "base"
    path, _ = _edited_copy(runs["none"], base, "anytime/summary.json", edit)
    argv = _anytime(nav, tmp_path / "out", "--baseline", str(base))
    _refused(argv, capsys, str(path), f"field {field}")
    assert not (tmp_path / "out").exists()


def _bias0(rec: dict) -> None:
    rec["bias"]["0"] = -1e308


RECORD_EDITS = [
    (_bias0, "field bias.0"),
    (lambda r: r["bias"].update({"0": "1.0"}), "field bias.0"),
    (lambda r: r.update(bias=None), "field bias"),
    (lambda r: r["tested"][0].update(population=1), "field tested[0].population"),
    (lambda r: r["tested"][0].update(population="0"), "field tested[0].population"),
    (lambda r: r["tested"][0].update(ratio=1e308), "field tested[0].ratio"),
    (lambda r: r["tested"][0].update(index=8), "field tested[0].index"),
    (lambda r: r["tested"][0].update(section=["01 0100000"]), "field tested[0].section"),
    (lambda r: r["tested"][0].pop("rank"), "field tested[0].rank: missing"),
    (lambda r: r.update(tested="all"), "field tested"),
    (lambda r: r.update(residual_sum=[[0.0] * 3] * 15), "field residual_sum"),
    (lambda r: r.update(residual_count=[-1] * 16), "field residual_count"),
    (lambda r: r.update(generation=3), "field generation"),
    (lambda r: r.update(method="model"), "field method"),
    (lambda r: r.pop("physics_runs"), "field physics_runs: missing"),
    (lambda r: r.update(physics_wall_s=None), "field physics_wall_s"),
]


@pytest.mark.parametrize(("edit", "field"), RECORD_EDITS,
                         ids=[f"{i}-{f.split()[-1]}" for i, (_, f) in enumerate(RECORD_EDITS)])
def test_anytime_resume_names_the_record_and_field_that_fail(
    runs, nav, tmp_path, capsys, edit, field
):
    out = tmp_path / "run"
    path, _ = _edited_copy(runs["bias"], out, "anytime/punctuations/gen0002.json", edit)
    before = _bytes(out)
    _refused([*_anytime(nav, out, "--method", "bias"), "--resume"], capsys, str(path), field)
    assert _bytes(out) == before


def test_anytime_resume_of_intact_records_runs(runs, nav, capsys):
    code, err = _run([*_anytime(nav, runs["bias"], "--method", "bias"), "--resume"], capsys)
    assert code == 0, err


FINAL_EDITS = [
    (lambda d: d["summary"]["physics"].update(inner_pct="high"), "summary.physics.inner_pct"),
    (lambda d: d["summary"].update(physics_errors=-1), "summary.physics_errors"),
    (lambda d: d["summary"].update(wall_s=None), "summary.wall_s"),
    (lambda d: d.update(summary=[]), "field summary"),
]


@pytest.mark.parametrize(("edit", "field"), FINAL_EDITS)
def test_anytime_resume_names_a_broken_final_test(runs, nav, tmp_path, capsys, edit, field):
    out = tmp_path / "run"
    path, doc = _edited_copy(runs["bias"], out, "anytime/final/pop0.json", edit)
    _refused([*_anytime(nav, out, "--method", "bias"), "--resume"], capsys, str(path), field)
    assert json.loads(path.read_text()) == doc


def test_anytime_resume_measures_a_final_test_of_other_genomes_again(runs, nav, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(runs["bias"], out)
    path = out / "anytime" / "final" / "pop0.json"
    path.write_text("[1, 2]")  # JSON, but not a final test: measured again
    code, err = _run([*_anytime(nav, out, "--method", "bias"), "--resume"], capsys)
    assert code == 0, err
    assert json.loads(path.read_text())["population"] == 0


# --------------------------------------------------------------------------- messages


def test_duplicate_compare_labels_are_refused(tmp_path, capsys):
    out = tmp_path / "out"
    _refused(["compare", "paper", "paper", "--labels", "a", "a", "--out", out], capsys,
             "--labels: 'a' given twice")  # fmt: skip
    assert not out.exists()


@pytest.mark.parametrize("steps", ["0", "-1"])
def test_trace_of_no_step_is_refused(chrom16, capsys, steps):
    _refused(["trace", chrom16, "--start", "250", "250", "0", "--steps", steps], capsys,
             "--steps must be ≥ 1", f"got {steps}")  # fmt: skip


@pytest.mark.parametrize("heading", ["1e308", "361", "-720", "-1000000"])
def test_a_heading_beyond_one_turn_is_refused_naming_the_option(
    chrom16, tmp_path, capsys, heading
):
    out = tmp_path / "out"
    start = ["--start", "250", "250", heading]
    _refused(["trace", chrom16, *start], capsys, "--start heading", "beyond ±360°")
    _refused(["validate", chrom16, *start, "--steps", "1", "--out", out], capsys,
             "--start: start 0", f"heading {float(heading):g} is beyond ±360°")  # fmt: skip
    poses = tmp_path / "poses.csv"
    poses.write_text(f"x,y,h\n250,250,0\n260,240,{heading}\n")
    section = tmp_path / "c8.txt"
    section.write_text(GENE * 8)
    _refused(["validate", section, "--poses", poses, "--steps", "1", "--out", out], capsys,
             f"--poses {poses}: start 1", "beyond ±360°")  # fmt: skip
    assert not out.exists()


def test_a_heading_within_one_turn_is_accepted(chrom16, capsys):
    code, err = _run(["trace", chrom16, "--start", "250", "250", "-360", "--steps", "1"], capsys)
    assert code == 0, err


def test_poses_outside_the_arena_name_the_poses_file(tmp_path, capsys):
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,h\n250,250,0\n900,250,0\n")
    section = tmp_path / "c8.txt"
    section.write_text(GENE * 8)
    out = tmp_path / "out"
    _refused(["validate", section, "--poses", poses, "--steps", "1", "--out", out], capsys,
             f"--poses {poses}: start 1", "lies outside the")  # fmt: skip
    assert not out.exists()


def test_a_missing_navigation_file_given_is_named_as_given(tmp_path, capsys):
    missing = tmp_path / "nope.txt"
    for argv in (["evolve", "coverage", *TINY, "--navigation", missing],
                 ["anytime", "--navigation", missing]):  # fmt: skip
        err = _refused([*argv, "--out", tmp_path / "out"], capsys,
                       f"--navigation {missing}: no such file")  # fmt: skip
        assert "give --navigation" not in err
    err = _refused(["evolve", "coverage", *TINY, "--out", tmp_path / "out"], capsys,
                   "no navigation section file", "give --navigation FILE")  # fmt: skip
    assert not (tmp_path / "out").exists()


def test_a_corrupt_settings_json_is_named_corrupt(chrom16, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = _run(["compare", "paper", "paper", "--labels", "a", "b", "--out", out], capsys)
    assert code == 0, err
    (out / RECORD_FILE).write_text('{"command": "compare", "tables": [')
    before = _bytes(out)
    err = _refused(["compare", "paper", "paper", "--labels", "a", "b", "--out", out], capsys,
                   f"{out / RECORD_FILE}: not valid JSON", "cannot be read")  # fmt: skip
    assert "other settings" not in err
    assert _bytes(out) == before


# --------------------------------------------------------------------------- reproduce resume


def test_reproduce_resume_names_a_damaged_coverage_summary_and_reruns_a_damaged_cell(tmp_path):
    """The records a resumed reproduction reads: the coverage summary (its finalists) names
    the file and field; a robustness cell's report that is not one is run again."""
    from servobot.reproduce.run import ReproduceError, reproduce
    from servobot.reproduce.settings import ReproduceSettings

    tiny = ReproduceSettings(
        calibration_cycles=1, calibration_settle_cycles=0,
        navigation_populations=1, navigation_population_size=6, navigation_generations=2,
        coverage_populations=2, coverage_population_size=6, coverage_generations=2,
        test_starts=4, validate_starts=1, validate_max_steps=3, validate_navigation_starts=1,
        robustness_starts=1, robustness_finalists=1, seed=3,
    )  # fmt: skip
    quiet = dict(settings=tiny, workers=1, log=lambda _m: None)
    out = tmp_path / "run"
    reproduce(out, **quiet)
    (out / "robustness" / "done.json").unlink()
    summary = out / "coverage" / "summary.json"
    good = summary.read_bytes()
    doc = json.loads(good)
    for bad in (None, ["41%", 3.0], [], "all"):
        summary.write_text(json.dumps(doc | {"final_inner_percent": bad}))
        with pytest.raises(ReproduceError, match=rf"{summary}: field final_inner_percent"):
            reproduce(out, **quiet)
    summary.write_bytes(good)
    cell = next((out / "robustness" / "runs").glob("*/*/report.json"))
    cell.write_text(json.dumps({"settings": ["abc"], "chromosome": "x"}))  # dict() → ValueError
    runs: list = []
    reproduce(out, **quiet, on_run=runs.append)
    assert len(runs) == tiny.robustness_starts  # the damaged cell only, run again
    assert json.loads(cell.read_text())["chromosome"] != "x"
