"""``servobot evolve`` and ``servobot trace`` (and ``python -m evolve``): smoke tests with
tiny budgets, error exits, and a hand-worked trace."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from evolve.codec import read_chromosome, write_chromosome
from evolve.settings import (
    ENVELOPE_COVERAGE_STARTS_PER_GENERATION,
    NAVIGATION_STARTS_PER_GENERATION,
)
from evolve.table import PAPER_TABLE
from servobot.cli import evolve as cli
from servobot.cli import main as servobot
from servobot.cli import trace

TINY = ["--populations", "2", "--population-size", "8", "--no-progress"]
COVERAGE = ["coverage", *TINY, "--generations", "3", "--starts-per-generation", "3"]
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A tiny navigation run, then a tiny coverage run (3 training starts per generation) with
    its default --navigation."""
    out = tmp_path_factory.mktemp("evolve")
    assert servobot(["evolve", "navigation", *TINY, "--generations", "6", "--out", str(out)]) == 0
    assert servobot(["evolve", *COVERAGE, "--out", str(out)]) == 0
    return out


def test_navigation_outputs(run_dir):
    nav = run_dir / "navigation"
    best = read_chromosome(nav / "best.txt")
    assert best.shape == (8, 30)
    assert (nav / "best.txt").read_text().startswith("# servobot navigation stage")
    summary = json.loads((nav / "summary.json").read_text())
    assert 0.0 <= summary["dock_success"] <= 1.0
    assert summary["test_starts"] == 100
    assert len(summary["populations"]) == 2
    assert summary["settings"]["GASettings"]["generations"] == 6
    assert summary["settings"]["GASettings"]["population_size"] == 8
    assert (nav / "settings.json").exists()
    saved = sorted(p.name for p in (nav / "populations").iterdir())
    assert saved == [f"pop{k}_gen{g:04d}.npz" for k in (0, 1) for g in (0, 1, 6)]


def test_coverage_outputs(run_dir):
    cov = run_dir / "coverage"
    nav = read_chromosome(run_dir / "navigation/best.txt")
    with open(cov / "figure9.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["population", "generation", "inner_percent"]
    assert [(r["population"], r["generation"]) for r in rows] == [
        (str(k), str(g)) for k in (0, 1) for g in (0, 1, 3)
    ]
    assert all(0.0 <= float(r["inner_percent"]) <= 100.0 for r in rows)
    for k in (0, 1):
        best = read_chromosome(cov / f"best_pop{k}.txt")
        assert best.shape == (16, 30)
        np.testing.assert_array_equal(best[8:], nav)
        assert (cov / f"figure10_pop{k}.png").stat().st_size > 10_000
    for png in (cov / "figure9.png", run_dir / "figure8.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((cov / "summary.json").read_text())
    assert summary["generations"] == [0, 1, 3]
    assert summary["settings"]["GASettings"]["starts_per_generation"] == 3
    with np.load(cov / "populations" / "pop0_gen0003.npz") as saved:
        assert saved["starts"].shape == (3, 3)  # the generation's 3 training starts (x, y, h)
    mean = np.mean([float(r["inner_percent"]) for r in rows if r["generation"] == "3"])
    assert math.isclose(summary["final_mean_inner_percent"], mean, abs_tol=1e-3)


def test_colony_outputs(run_dir, capsys):
    args = ["evolve", "colony", *TINY, "--generations", "2", "--robots", "2", "--blocking",
            "slide", "--out", str(run_dir)]  # fmt: skip
    assert servobot(args) == 0
    assert "colony of 2: Figure 9 at generation 2" in capsys.readouterr().out
    col = run_dir / "colony"
    summary = json.loads((col / "summary.json").read_text())
    assert summary["robots"] == 2 and summary["generations"] == [0, 1, 2]
    assert summary["settings"]["ColonySettings"]["robots"] == 2
    assert summary["settings"]["ColonySettings"]["blocking"] == "slide"
    nav = read_chromosome(run_dir / "navigation/best.txt")
    for k in (0, 1):
        np.testing.assert_array_equal(read_chromosome(col / f"best_pop{k}.txt")[8:], nav)
        assert (col / f"figure10_pop{k}.png").stat().st_size > 10_000
    assert (col / "figure9.csv").read_text().startswith("population,generation,inner_percent")


def test_resume_of_a_finished_run_changes_nothing(run_dir, capsys):
    before = (run_dir / "coverage/figure9.csv").read_text()
    args = [*COVERAGE, "--out", str(run_dir), "--resume"]
    assert servobot(["evolve", *args]) == 0
    assert (run_dir / "coverage/figure9.csv").read_text() == before
    assert "Figure 9 at generation 3" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["coverage", "--out", "{tmp}"], "no navigation section file"),
        (["navigation", "--population-size", "1", "--out", "{tmp}"], "population-size must be"),
        (["navigation", "--generations", "0", "--out", "{tmp}"], "generations must be"),
        (["coverage", "--starts-per-generation", "0", "--out", "{tmp}"],
         "--starts-per-generation must be ≥ 1, got 0"),
        (["navigation", "--table", "{tmp}/none.json", "--out", "{tmp}"], "no such gait-table"),
        (["navigation", "--navigation", "x.txt", "--out", "{tmp}"], "option of the coverage"),
        (["colony", "--out", "{tmp}"], "no navigation section file"),
        (["coverage", "--robots", "2", "--out", "{tmp}"], "option of the colony"),
        (["navigation", "--blocking", "slide", "--out", "{tmp}"], "--blocking is an option"),
        (["colony", "--robots", "0", "--out", "{tmp}"], "--robots must be"),
        (
            ["colony", "--robots", "40", "--navigation", "{nav}", "--out", "{tmp}"],
            "cannot place robot",
        ),
    ],
)
def test_bad_input_exits_2_with_a_message(tmp_path, capsys, args, message):
    nav = write_chromosome(tmp_path / "nav.txt", np.zeros((8, 30), dtype=np.uint8))
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{nav}", str(nav)) for a in args]
    argv += ["--no-progress"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_resume_with_other_settings_exits_2(run_dir, capsys):
    args = ["navigation", *TINY, "--generations", "6", "--seed", "5", "--out", str(run_dir)]
    assert cli.main([*args, "--resume"]) == 2
    assert "other settings (GASettings.seed: 0 there, 5 here)" in capsys.readouterr().err


def test_evolve_help_needs_no_mujoco():
    code = (
        "import sys\nfrom servobot.cli import main\n"
        "try:\n    main(['evolve', '--help'])\nexcept SystemExit:\n    pass\n"
        "assert 'mujoco' not in sys.modules, 'mujoco imported'\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert res.returncode == 0, res.stderr
    assert "--population-size" in res.stdout


# --------------------------------------------------------------------------- trace

FORWARD = "\n".join(["00 0000000 0000000 0000000 0000000"] * 8) + "\n"
"""8 genes, gene 0 loops forever over four 'gait 0' (F 11.6, T −0.8, dH −1.3)."""


@pytest.fixture
def forward(tmp_path):
    path = tmp_path / "forward.txt"
    path.write_text("# walk with gait 0 forever\n" + FORWARD)
    return path


def _expected_poses(n: int) -> list[tuple[float, float, float]]:
    """Gait 0 from (250, 275) heading 90 (east), by the SPEC §1 formula, worked here."""
    f, t, dh = PAPER_TABLE[0]
    x, y, h = 250.0, 275.0, 90.0
    poses = []
    for _ in range(n):
        r = math.radians(h)
        x, y = x + f * math.sin(r) + t * math.cos(r), y + f * math.cos(r) - t * math.sin(r)
        h = (h + dh) % 360.0
        poses.append((x, y, h))
    return poses


def _square(x: float, y: float) -> int:
    """Square i + 10·j whose central 38 × 38 contact zone holds (x, y), else −1 (SPEC §3)."""
    i, j = int(x // 50), int(y // 50)
    inside = abs(x - (50 * i + 25)) <= 19 and abs(y - (50 * j + 25)) <= 19
    return i + 10 * j if inside else -1


def test_trace_json_hand_worked(forward, capsys):
    argv = [str(forward), "--start", "250", "275", "90", "--steps", "5", "--json"]
    assert servobot(["trace", *argv]) == 0
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [e["kind"] for e in events] == ["gait"] * 5 + ["end"]
    assert events[-1]["text"] == "end: step limit"
    # first step: (250 + 11.6, 275 + 0.8), heading 88.7
    assert events[0]["x"] == pytest.approx(261.6) and events[0]["y"] == pytest.approx(275.8)
    reached: list[int] = []
    for k, (e, (x, y, h)) in enumerate(zip(events, _expected_poses(5), strict=False)):
        assert (e["step"], e["gene"], e["instruction"], e["gait"]) == (k + 1, 0, k % 4, 0)
        assert (e["x"], e["y"], e["heading"]) == pytest.approx((x, y, h))
        assert e["power"] == pytest.approx(4.0 - 0.0209 * (k + 1))
        assert e["mode"] == "navigation"
        sq = _square(x, y)
        new = sq if sq >= 0 and sq not in reached else -1
        reached += [new] if new >= 0 else []
        assert (e["new_square"], e["squares"]) == (new, len(reached))
    # (261.6, 275.8) is in square 5 + 10·5; by step 5 (307.7, 281.6) also in 56
    assert reached == [55, 56]
    # below 4.0 V the low-power sensor is active
    assert "low-power" in events[0]["sensors"]


def test_trace_text_one_line_per_event(forward, capsys):
    argv = [str(forward), "--start", "250", "275", "90", "--steps", "3", "--power", "4.5"]
    assert trace.main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("# ") and lines[1] == trace.TEXT_HEADER
    body = lines[2:-1]
    assert len(body) == 4  # 3 gait steps + the end
    first = body[0].split()
    assert first[:5] == ["1", "0.0", "gait", "gait", "0"]
    assert first[5:10] == ["0", "261.6", "275.8", "88.7", "4.479"]
    assert first[10:12] == ["navigation", "1"]
    # 4.479 V: no low power. Looking east at the lights (500, 235/265), 238 cm away inside
    # their westward cones, a few degrees right of the heading: both light sensors; no wall
    # within 50 cm: no object sensor. Square 55 is new.
    assert first[12:] == ["light-left,light-right", "+55"]
    assert lines[-1] == (
        "# end: step limit; 1 squares (1 inner), 0 docks, 3 steps; final pose "
        + "({:.1f}, {:.1f}, {:.1f})".format(*_expected_poses(3)[-1])
    )


def test_trace_16_genes_defaults_to_coverage(tmp_path, capsys):
    bits = np.zeros((16, 30), dtype=np.uint8)
    path = write_chromosome(tmp_path / "full.txt", bits)
    assert servobot(["trace", str(path), "--start", "250", "250", "0", "--json"]) == 0
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert events[0]["mode"] == "coverage"
    assert events[-1]["kind"] == "end"


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--mode", "coverage"], "needs a 16-gene chromosome"),
        (["--steps", "-1"], "--steps must be"),
        (["--table", "missing.json"], "no such gait-table"),
    ],
)
def test_trace_bad_input_exits_2(forward, capsys, extra, message):
    assert trace.main([str(forward), "--start", "250", "275", "90", *extra]) == 2
    assert message in capsys.readouterr().err


def test_trace_start_outside_arena_exits_2(forward, capsys):
    assert trace.main([str(forward), "--start", "520", "250", "90"]) == 2
    assert "outside the arena" in capsys.readouterr().err


def test_trace_rrd_records_the_table_run(forward, tmp_path, capsys):
    rr = pytest.importorskip("rerun")
    rrd = tmp_path / "trace.rrd"
    argv = [str(forward), "--start", "250", "275", "90", "--steps", "5", "--rrd", str(rrd)]
    assert trace.main(argv) == 0
    assert f"# recording: {rrd}" in capsys.readouterr().out
    rows: dict[str, int] = {}  # rows on the step timeline per entity (static ones apart)
    static: set[str] = set()
    reader = rr.chunk.RrdReader(str(rrd))
    for chunk in reader.stream().collect().stream():
        path = str(chunk.entity_path)
        if chunk.is_static:
            static.add(path)
        else:
            rows[path] = rows.get(path, 0) + chunk.num_rows
    assert "/world/arena/squares" in static and "/world/arena/kill_zone" in static
    table = "/world/robots/servobot/table"
    assert rows[f"{table}/pose"] == 6  # 5 steps + the end event
    assert rows[f"{table}/track"] == 5  # one segment per step, from the start
    assert rows[f"{table}/squares"] == 2  # squares 55 and 56 newly reached
    assert any(p.startswith(f"{table}/pose/ghost/torso/geoms/") for p in static)
    from evolve.table import PAPER_TABLE
    from tests.test_recording import Rrd, assert_provenance

    command = "servobot trace " + " ".join(argv)
    assert_provenance(Rrd(rrd), table=PAPER_TABLE, source="paper", command=command)


def test_stage_files_list_every_file_a_stage_writes(run_dir):
    from evolve.stages import STAGE_FILES
    from infra.rundir import LOCK_FILE, RECORD_FILE, owned_files

    for stage in ("navigation", "coverage"):
        folder = run_dir / stage
        written = {p for p in folder.rglob("*") if p.is_file() and p.name != LOCK_FILE}
        assert set(owned_files(folder, [*STAGE_FILES, RECORD_FILE])) == written


@pytest.mark.parametrize(
    ("argv", "starts"),
    [
        (["navigation"], NAVIGATION_STARTS_PER_GENERATION),
        (["coverage"], 10),  # the paper's
        (["coverage", "--envelope", "none"], 10),
        (["coverage", "--envelope", "default"], ENVELOPE_COVERAGE_STARTS_PER_GENERATION),
        (["coverage", "--envelope", "default", "--starts-per-generation", "12"], 12),
        (["colony", "--envelope", "default"], 10),
    ],
)
def test_training_starts_per_generation_by_stage_and_envelope(argv, starts):
    assert ENVELOPE_COVERAGE_STARTS_PER_GENERATION == 30
    assert cli.ga_settings(cli.build_parser().parse_args(argv)).starts_per_generation == starts
