"""``servobot reproduce`` on a tiny budget: every stage's files, REPORT.md, and resuming."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from evolve.codec import read_chromosome
from evolve.table import load_table
from infra.rundir import RunDirError
from servobot.cli.reproduce import main
from servobot.reproduce.run import (
    ReproduceError,
    ReproduceSettings,
    quick_settings,
    reproduce,
    stage_key,
)

TINY = ReproduceSettings(
    calibration_cycles=1, calibration_settle_cycles=0,
    navigation_populations=1, navigation_population_size=6, navigation_generations=2,
    coverage_populations=2, coverage_population_size=6, coverage_generations=2, test_starts=4,
    validate_starts=2, validate_max_steps=6, validate_navigation_starts=2, seed=3,
)  # fmt: skip
"""Smaller than --quick: seconds, but every stage and file of a full run."""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("reproduce")
    res = reproduce(out, settings=TINY, workers=1, log=lambda _m: None)
    return out, res


def test_tiny_run_writes_every_stage(run_dir: tuple[Path, dict]) -> None:
    out, res = run_dir
    assert all(not st["skipped"] for st in res["stages"].values())
    assert set(res["stages"]) == {"calibration", "navigation", "coverage", "validation"}
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


def test_other_settings_in_the_same_folder_are_refused(run_dir: tuple[Path, dict]) -> None:
    out, _ = run_dir
    other = dataclasses.replace(TINY, coverage_generations=3)
    report = (out / "REPORT.md").read_text()
    with pytest.raises(RunDirError, match="coverage_generations: 2 there, 3 here"):
        reproduce(out, settings=other, workers=1, log=lambda _m: None)
    assert (out / "REPORT.md").read_text() == report  # nothing rewritten


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
