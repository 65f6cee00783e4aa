"""``servobot reproduce`` on a tiny budget: every stage's files, REPORT.md, and resuming."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from evolve.codec import read_chromosome
from evolve.envelope import DEFAULT
from evolve.population import save_generations
from evolve.settings import ENVELOPE_COVERAGE_STARTS_PER_GENERATION
from evolve.table import load_table
from infra.rundir import RunDirError
from servobot.cli.reproduce import main
from servobot.reproduce.run import (
    ReproduceError,
    ReproduceSettings,
    best_finalists,
    quick_settings,
    read_done,
    reproduce,
    stage_key,
)
from servobot.reproduce.settings import COLONY_FIELDS, COLONY_OPTIONS
from servobot.robustness.worlds import BUILT_IN

TINY = ReproduceSettings(
    calibration_cycles=1, calibration_settle_cycles=0,
    navigation_populations=1, navigation_population_size=6, navigation_generations=2,
    coverage_populations=2, coverage_population_size=6, coverage_generations=2, test_starts=4,
    validate_starts=2, validate_max_steps=6, validate_navigation_starts=2, robustness_starts=1,
    robustness_steps=5, robustness_finalists=2, colony_validate_starts=2, seed=3,
)  # fmt: skip
"""Smaller than --quick: seconds, but every stage and file of a full run."""
COLONY_ARGV = ["--quick", "--robots", "3", "--colony-fitness", "alive", "--start-power-spread",
               "0.5", "--robots-unseen", "--contact-yaw", "9.3", "--workers", "1",
               "--no-progress"]  # fmt: skip
"""``servobot reproduce --quick --robots 3`` with every colony option (made tiny:
``quick_settings`` patched to TINY)."""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("reproduce")
    res = reproduce(out, settings=TINY, workers=1, log=lambda _m: None)
    return out, res


@pytest.fixture(scope="module")
def envelope_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny run through the command line with ``--envelope default``."""
    out = tmp_path_factory.mktemp("reproduce-envelope")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("servobot.reproduce.run.quick_settings", lambda: TINY)
        argv = ["--out", str(out), "--quick", "--envelope", "default", "--workers", "1"]
        assert main([*argv, "--no-progress"]) == 0
    return out


@pytest.fixture(scope="module")
def colony_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny run through the command line with ``--robots 3``: every stage, then the colony's."""
    out = tmp_path_factory.mktemp("reproduce-colony")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("servobot.reproduce.run.quick_settings", lambda: TINY)
        assert main(["--out", str(out), *COLONY_ARGV]) == 0
    return out


def test_tiny_run_writes_every_stage(run_dir: tuple[Path, dict]) -> None:
    out, res = run_dir
    assert all(not st["skipped"] for st in res["stages"].values())
    assert set(res["stages"]) == {
        "calibration", "navigation", "coverage", "validation", "robustness"
    }  # fmt: skip
    table = load_table(out / "calibration" / "gait_table.json")
    assert table.values.shape == (16, 3)
    assert table.meta["seed"] == TINY.seed
    assert (out / "calibration" / "figure4.png").stat().st_size > 0
    assert read_chromosome(out / "navigation" / "best.txt").shape == (8, 30)
    for k in range(TINY.coverage_populations):
        assert read_chromosome(out / "coverage" / f"best_pop{k}.txt").shape == (16, 30)
        assert (out / "coverage" / f"figure10_pop{k}.png").exists()
        rep = json.loads((out / "validation" / f"pop{k}" / "report.json").read_text())
        assert len(rep["runs"]) == TINY.validate_starts
        for j in range(TINY.validate_starts):
            assert (out / "validation" / f"pop{k}" / f"run{j}.rrd").exists()
    # The navigation section alone, in navigation mode, from fresh starts in both worlds.
    nav = json.loads((out / "validation" / "navigation_fresh" / "report.json").read_text())
    assert nav["settings"]["mode"] == "navigation" and len(nav["runs"]) == 2
    assert nav["settings"]["max_steps"] == 100
    assert all(r["physics"]["steps"] <= 100 for r in nav["runs"])
    # Every finalist ran from the same seeded starts.
    starts = json.loads((out / "validation" / "starts.json").read_text())["starts"]
    rep0 = json.loads((out / "validation" / "pop0" / "report.json").read_text())
    got = [[r["start"][a] for a in "xyh"] for r in rep0["runs"]]
    np.testing.assert_allclose(got, starts, rtol=0, atol=1e-9)
    # A validation recording holds both worlds' tracks.
    paths = {c.entity_path for c in rr.chunk.RrdReader(out / "validation/pop0/run0.rrd")
             .stream().collect().stream()}  # fmt: skip
    robot = "/world/robots/servobot"
    assert {f"{robot}/table/track", f"{robot}/physics/track", f"{robot}/bodies/torso"} <= paths


def test_report_embeds_figures_and_lists_recordings(run_dir: tuple[Path, dict]) -> None:
    out, _ = run_dir
    text = (out / "REPORT.md").read_text()
    for fig in ("calibration/figure4.png", "figure8.png", "coverage/figure9.png",
                "coverage/figure10_pop0.png", "coverage/figure10_pop1.png"):  # fmt: skip
        assert f"]({fig})" in text
        assert (out / fig).exists()
    assert "`rerun validation/pop1/run0.rrd` (2 recordings in `validation/pop1/`)" in text
    assert "`rerun calibration/calibration.rrd`" in text
    assert "| **all** |" in text  # the reality-gap summary row
    assert '"coverage_generations": 2' in text


def test_second_call_skips_finished_stages(run_dir: tuple[Path, dict]) -> None:
    out, first = run_dir
    marker = out / "coverage" / "done.json"
    before = marker.read_text()
    res = reproduce(out, settings=TINY, workers=1, log=lambda _m: None)
    assert all(st["skipped"] for st in res["stages"].values())
    assert marker.read_text() == before
    for name, st in res["stages"].items():  # earlier wall times are reported, not zero
        assert st["wall_s"] == pytest.approx(first["stages"][name]["wall_s"], abs=1e-3)


def test_interrupted_validation_resumes_per_finalist(run_dir: tuple[Path, dict]) -> None:
    out, _ = run_dir
    # As if killed while validating finalist 1: its outputs and the stage marker are missing.
    (out / "validation" / "done.json").unlink()
    for f in (out / "validation" / "pop1").iterdir():
        f.unlink()
    kept = (out / "validation" / "pop0" / "report.json").stat().st_mtime_ns
    res = reproduce(out, settings=TINY, workers=1, log=lambda _m: None)
    val = res["stages"]["validation"]
    assert not val["skipped"]
    assert val["finalists"]["0"]["skipped"] and not val["finalists"]["1"]["skipped"]
    assert (out / "validation" / "pop0" / "report.json").stat().st_mtime_ns == kept
    assert (out / "validation" / "pop1" / "run1.rrd").exists()
    assert res["stages"]["coverage"]["skipped"]


def test_robustness_stage_runs_every_finalist_in_every_world(run_dir: tuple[Path, dict]) -> None:
    out, res = run_dir
    doc = json.loads((out / "robustness" / "robustness.json").read_text())
    assert [w["name"] for w in doc["worlds"]] == list(BUILT_IN)
    names = [c["name"] for c in doc["table_per_chromosome"]]
    assert names == [f"best_pop{k}" for k in range(TINY.coverage_populations)]
    assert (doc["starts"], doc["steps"], doc["seed"]) == (1, TINY.robustness_steps, TINY.seed)
    assert doc["table"]["source"] == str(out / "calibration" / "gait_table.json")
    assert set(res["stages"]["robustness"]["worlds"]) == set(BUILT_IN)
    text = (out / "REPORT.md").read_text()
    assert "## 5. Robustness" in text and "](robustness/robustness.png)" in text
    assert "| **drop vs shipped (pp)** |" in text and "| best_pop1 |" in text
    assert (out / "robustness" / "robustness.png").exists()
    # the finalist physics chooses: the most inner coverage in its worst world, long-legs unseen
    seen = [w for w in doc["worlds"] if w["name"] != "long-legs"]
    vals = [[w["per_chromosome"][k]["physics_inner_percent"] or 0.0 for w in seen]
            for k in range(len(names))]  # fmt: skip
    k = max(range(len(names)), key=lambda k: (min(vals[k]), sum(vals[k])))
    assert f"worst world of {', '.join(w['name'] for w in seen)}): **{names[k]}**" in text


def test_interrupted_matrix_resumes_cell_by_cell(run_dir: tuple[Path, dict]) -> None:
    out, _ = run_dir
    # As if killed in the matrix's last cell: its report and the stage marker are missing.
    (out / "robustness" / "done.json").unlink()
    (out / "robustness" / "runs" / "long-legs" / "best_pop1" / "report.json").unlink()
    runs: list[dict] = []
    res = reproduce(out, settings=TINY, workers=1, log=lambda _m: None, on_run=runs.append)
    assert not res["stages"]["robustness"]["skipped"] and res["stages"]["validation"]["skipped"]
    assert len(runs) == TINY.robustness_starts  # only the missing cell ran
    assert (out / "robustness" / "done.json").exists()


def test_other_settings_in_the_same_folder_are_refused(run_dir: tuple[Path, dict]) -> None:
    out, _ = run_dir
    other = dataclasses.replace(TINY, coverage_generations=3)
    report = (out / "REPORT.md").read_text()
    with pytest.raises(RunDirError, match="coverage_generations: 2 there, 3 here"):
        reproduce(out, settings=other, workers=1, log=lambda _m: None)
    assert (out / "REPORT.md").read_text() == report  # nothing rewritten


def test_envelope_reaches_the_stages(envelope_dir: Path) -> None:
    out = envelope_dir
    record = json.loads((out / "settings.json").read_text())
    assert record["ReproduceSettings"]["envelope"] == "default"
    assert record["Envelope"] == DEFAULT.to_dict()
    nav = json.loads((out / "navigation" / "done.json").read_text())["info"]
    cov = json.loads((out / "coverage" / "done.json").read_text())["info"]
    assert nav["envelope"] == cov["envelope"] == DEFAULT.to_dict()
    assert 0.0 <= nav["envelope_dock_success"] <= 1.0
    assert 0.0 <= cov["envelope_final_mean_inner_percent"] <= 100.0
    summ = json.loads((out / "coverage" / "summary.json").read_text())
    assert summ["envelope_final_mean_inner_percent"] == cov["envelope_final_mean_inner_percent"]
    ga = json.loads((out / "coverage" / "settings.json").read_text())["GASettings"]
    assert ga["starts_per_generation"] == ENVELOPE_COVERAGE_STARTS_PER_GENERATION  # 10 in none
    assert json.loads((out / "navigation" / "settings.json").read_text())["Envelope"]
    text = (out / "REPORT.md").read_text()
    assert "Envelope: `default`" in text
    assert "station_stops true" in text and "station_blocking slide" in text  # names print too
    assert "In its envelope, on the same test starts:" in text  # docking
    assert "In the envelope, on the same test starts: mean" in text  # Figure 9
    assert "mean (envelope) |" in text and "## 5. Robustness" in text
    assert json.loads((out / "robustness" / "done.json").read_text())["settings"]["envelope"]


def test_another_envelope_is_refused(envelope_dir: Path, tmp_path: Path) -> None:
    out = envelope_dir
    refused = 'ReproduceSettings.envelope: "default" there, "none" here'
    with pytest.raises(RunDirError, match=refused):
        reproduce(out, settings=TINY, workers=1, log=lambda _m: None)
    # A stage marker says the same: calibration does not depend on the envelope, the stages
    # from navigation on do (also when the envelope file's fields change).
    assert read_done(out / "calibration", stage_key(TINY, "calibration")) is not None
    for stage in ("navigation", "coverage", "validation", "robustness"):
        with pytest.raises(ReproduceError, match="other settings.*envelope"):
            read_done(out / stage, stage_key(TINY, stage))
    file = tmp_path / "env.json"
    file.write_text(json.dumps(DEFAULT.to_dict() | {"reach_units": 7.0}))
    key = stage_key(dataclasses.replace(TINY, envelope=str(file)), "coverage")
    assert key["envelope_fields"]["reach_units"] == 7.0
    with pytest.raises(ReproduceError, match="envelope"):
        read_done(out / "coverage", key)


def test_cli_names_a_bad_envelope_file(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    missing = tmp_path / "nope.json"
    assert main(["--out", str(tmp_path / "x"), "--envelope", str(missing), "--no-progress"]) == 2
    assert "nope.json" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text('{"scatter_scale": -1}')
    assert main(["--out", str(tmp_path / "y"), "--envelope", str(bad), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "scatter_scale" in err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_settings_keys_and_presets() -> None:
    full = ReproduceSettings()
    assert (full.navigation_populations, full.navigation_population_size) == (5, 256)
    assert (full.navigation_generations, full.coverage_generations) == (1024, 512)
    assert full.validate_starts == 20 and full.validate_max_steps == 600
    assert full.coverage_ga().save_generations[-1] == 512
    assert full.navigation_ga().generations == 1024
    quick = quick_settings()
    assert quick.coverage_generations < full.coverage_generations
    # A stage's key holds the settings of the stages before it, not those after it.
    assert "calibration_cycles" in stage_key(full, "coverage")
    assert "validate_starts" not in stage_key(full, "coverage")
    # The exact world keeps the keys of before; an envelope enters navigation and later.
    assert full.envelope == "none" and "envelope" not in stage_key(full, "robustness")
    env = dataclasses.replace(full, envelope="default")
    assert stage_key(env, "calibration") == stage_key(full, "calibration")
    assert stage_key(env, "navigation")["envelope"] == "default"
    assert "robustness_starts" in stage_key(full, "robustness")
    assert (full.robustness_starts, quick.robustness_starts) == (2, 1)
    assert (full.robustness_finalists, quick.robustness_finalists) == (5, 1)
    assert "robustness_finalists" in stage_key(full, "robustness")
    assert dataclasses.replace(full, coverage_populations=2).matrix_finalists() == 2
    assert full.validate_max_steps == full.robustness(Path("d")).steps == 600
    assert quick.robustness(Path("d")).steps == quick.robustness_steps == 300


def test_the_matrix_runs_the_best_finalists_first() -> None:
    # Figure 9 finals per population: 4 is best, then 1 and 3 tie (lower index first).
    finals = [20.0, 40.0, 10.0, 40.0, 55.0]
    assert best_finalists(finals, 5) == [4, 1, 3, 0, 2]
    assert best_finalists(finals, 1) == [4]


def test_cli_rejects_bad_budget(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["--out", str(tmp_path / "x"), "--validate-starts", "0", "--no-progress"]) == 2
    assert "validate_starts" in capsys.readouterr().err
    assert main(["--out", str(tmp_path / "y"), "--workers", "0"]) == 2


def test_failed_stage_is_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import servobot.reproduce.run as rp

    def broken(*_a, **_k):
        raise ReproduceError("calibration failed (test)")

    monkeypatch.setattr(rp, "calibrate", broken)
    with pytest.raises(ReproduceError, match="calibration failed"):
        reproduce(tmp_path, settings=TINY, workers=1, log=lambda _m: None)
    text = (tmp_path / "REPORT.md").read_text()
    assert "| calibration |" in text and "failed: calibration failed (test)" in text
    assert "| navigation | — | not reached |" in text
    assert not (tmp_path / "calibration" / "done.json").exists()


def test_force_would_delete_exactly_the_files_a_run_wrote(run_dir: tuple[Path, dict]) -> None:
    from infra.rundir import LOCK_FILE, RECORD_FILE, owned_files
    from servobot.reproduce.run import REPRODUCE_FILES

    out, _ = run_dir
    written = {p for p in out.rglob("*") if p.is_file() and p.name != LOCK_FILE}
    assert set(owned_files(out, [*REPRODUCE_FILES, RECORD_FILE])) == written


def test_colony_stages_evolve_validate_and_report(colony_dir: Path) -> None:
    out, r = colony_dir, 3
    assert json.loads((out / "settings.json").read_text())["ReproduceSettings"]["robots"] == r
    # The colony evolved with the coverage stage's budget: Figure 9 at every saved generation.
    summ = json.loads((out / "colony" / "summary.json").read_text())
    gens = save_generations(TINY.coverage_ga())
    assert summ["robots"] == r and summ["generations"] == list(gens)
    assert summ["generations"][-1] == TINY.coverage_generations
    fig9 = np.asarray(summ["figure9_inner_percent"])
    assert fig9.shape == (TINY.coverage_populations, len(gens))
    assert np.all((fig9 >= 0) & (fig9 <= 100))
    assert (out / "colony" / "figure9.png").stat().st_size > 0
    info = json.loads((out / "colony" / "done.json").read_text())["info"]
    assert info["robots"] == r and len(info["final_test"]) == TINY.coverage_populations
    # The colony options reach the colony stage and both worlds of its validation.
    evolved = json.loads((out / "colony" / "settings.json").read_text())["ColonySettings"]
    validated = json.loads((out / "colony_validation/pop0/report.json").read_text())["settings"]
    for colony in (evolved, validated["ColonySettings"]):
        assert (colony["start_power_spread"], colony["robots_seen"]) == (0.5, False)
    assert evolved["fitness"] == "alive"
    assert evolved["contact_yaw_deg"] == validated["ColonySettings"]["contact_yaw_deg"] == 9.3
    # Each colony finalist in physics with R robots, from the same seeded colony starts.
    starts = np.asarray(json.loads((out / "colony_validation/starts.json").read_text())["starts"])
    assert starts.shape == (TINY.colony_validate_starts, r, 3)
    val = json.loads((out / "colony_validation" / "done.json").read_text())["info"]
    assert set(val["colony_finalists"]) == {str(k) for k in range(TINY.coverage_populations)}
    for k, f in val["colony_finalists"].items():
        assert f["runs_ok"] == f["starts"] == TINY.colony_validate_starts
        for what in ("docks", "station_waits"):
            assert all(len(f[what][w]) == r for w in ("table", "physics"))
            assert all(v >= 0 for w in ("table", "physics") for v in f[what][w])
        assert np.isfinite(f["gap_inner_pp"])
        assert f["gap_inner_pp"] == pytest.approx(
            f["table_inner_percent"] - f["physics_inner_percent"]
        )
        sub = out / "colony_validation" / f"pop{k}"
        rep = json.loads((sub / "report.json").read_text())
        assert rep["summary"]["robots"] == r and rep["settings"]["max_steps"] == 6
        got = [[[p[a] for a in "xyh"] for p in run["start"]] for run in rep["runs"]]
        np.testing.assert_allclose(got, starts, rtol=0, atol=1e-9)
        for j in range(TINY.colony_validate_starts):
            assert (sub / f"run{j}.rrd").stat().st_size > 0
            assert (sub / f"tracks{j}.png").exists()
    assert np.isfinite(val["gap_inner_pp"])
    text = (out / "REPORT.md").read_text()
    # The finalist physics chooses (colony_choice's rule, worked from the reports' summaries).
    phys = {k: json.loads((out / "colony_validation" / f"pop{k}" / "report.json").read_text())
            ["summary"]["physics"] for k in val["colony_finalists"]}  # fmt: skip
    live = {k: p["live_at_end_per_run"] for k, p in phys.items()}
    assert {k: f["live_at_end"]["physics"] for k, f in val["colony_finalists"].items()} == live
    assert "| live at the end (of 3), table | physics |" in text
    fine = [k for k in phys if live[k] >= 2.0]
    chosen = (max(fine, key=lambda k: phys[k]["inner_pct"]) if fine else
              max(phys, key=lambda k: (live[k], phys[k]["inner_pct"])))  # fmt: skip
    inner = phys[chosen]["inner_pct"]
    assert f"else the most live): **pop{chosen}**, physics {inner:.1f} %" in text
    # The team colony_team makes: the chosen finalist on robots 0–1, the best coverer on 2.
    coverer = max(phys, key=lambda k: phys[k]["inner_pct"])
    if coverer == chosen:
        assert f"**pop{chosen}** both lives and covers most" in text
    else:
        assert f"robots 0–1 carry the liver **pop{chosen}** (as chosen above), robot 2 the " \
            f"coverer **pop{coverer}**" in text
    for line in ("| colony |", "| colony_validation |", "## 6. A colony of 3 robots",
                 "](colony/figure9.png)", "](colony_validation/pop1/tracks0.png)",
                 "`rerun colony_validation/pop0/run0.rrd` (2 recordings in "
                 "`colony_validation/pop0/`)", f"**{val['gap_inner_pp']:+.1f}**",
                 "## 7. Recordings", "## 8. Settings", '"robots": 3',
                 "fitness `alive`, start powers staggered by 0.5 V, the other robots unseen "
                 "by the object sensors, a blocked move turning 9.3° away from a robot abeam",
                 '"colony_robots_seen": false'):  # fmt: skip
        assert line in text
    # Resumable: the same command again skips every stage, the colony's too.
    marker = (out / "colony_validation" / "done.json").read_text()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("servobot.reproduce.run.quick_settings", lambda: TINY)
        assert main(["--out", str(out), *COLONY_ARGV]) == 0
    assert (out / "colony_validation" / "done.json").read_text() == marker
    from infra.rundir import LOCK_FILE, RECORD_FILE, owned_files
    from servobot.reproduce.run import REPRODUCE_FILES

    written = {p for p in out.rglob("*") if p.is_file() and p.name != LOCK_FILE}
    assert set(owned_files(out, [*REPRODUCE_FILES, RECORD_FILE])) == written


def test_colony_settings_leave_the_reproduction_as_it_was() -> None:
    colony = dataclasses.replace(TINY, robots=3)
    # Without a colony (robots 1, the default): no colony stage, settings and keys as before.
    assert TINY.robots == 1 and TINY.colony() is None and "colony" not in TINY.stages()
    assert not set(COLONY_FIELDS) & set(TINY.to_dict())
    # The colony's learning options at their defaults leave a colony's settings as before.
    assert not set(COLONY_OPTIONS) & set(colony.to_dict())
    unseen = dataclasses.replace(colony, colony_robots_seen=False)
    assert stage_key(unseen, "colony_validation")["colony_robots_seen"] is False
    assert stage_key(unseen, "coverage") == stage_key(TINY, "coverage")
    assert unseen.colony().robots_seen is False
    for stage in ("calibration", "navigation", "coverage", "validation", "robustness"):
        assert stage_key(colony, stage) == stage_key(TINY, stage)
    # The colony stages depend on the stages up to coverage and their own fields only.
    key = stage_key(colony, "colony_validation")
    assert key["robots"] == 3 and key["colony_blocking"] == "cancel"
    assert key["colony_validate_starts"] == 2 and "coverage_generations" in key
    assert "robustness_starts" not in key and "validate_starts" not in key
    assert colony.colony().robots == 3 and colony.stages()[-2:] == ("colony", "colony_validation")
    assert (ReproduceSettings().colony_validate_starts, quick_settings().colony_validate_starts) \
        == (3, 1)  # fmt: skip


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--robots", "0"], "--robots must be an integer ≥ 1, got 0"),
        (["--robots", "-2"], "--robots must be an integer ≥ 1, got -2"),
        (["--blocking", "slide"], "--blocking is an option of the colony stages"),
        (["--robots", "1", "--blocking", "slide"], "--blocking is an option"),
        (["--robots", "40"], "--robots 40: cannot place robot"),
        (["--robots-unseen"], "--robots-unseen is an option of the colony stages"),
        (["--colony-fitness", "docks"], "--colony-fitness is an option of the colony stages"),
        (["--robots", "3", "--start-power-spread", "-1"],
         "--start-power-spread must be a finite number ≥ 0"),
    ],
)
def test_cli_rejects_bad_robots(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "x"
    assert main(["--out", str(out), "--quick", *argv, "--no-progress"]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()  # refused before any stage
