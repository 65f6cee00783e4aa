"""``validate`` and ``servobot validate``: tiny-budget smoke runs, the report layout, bad input,
a physics blow-up confined to its own run (executors: tests/test_executors.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, B, G, chrom, gene

from evolve.codec import parse_chromosome
from evolve.handoff import DOCKED, collect_handoffs, handoff_record
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import PAPER_TABLE, load_table, table_to_json
from infra.executors import SerialExecutor
from servo_mj.world import physics_world
from servobot.cli import validate as validate_cli
from servobot.validation.lone import ValidationError, validate

GENE_8 = "01 0100000 0100000 0100000 0100000\n"
BITS = parse_chromosome(GENE_8 * 16)
STARTS = np.array([[400.0, 200.0, 300.0], [300.0, 300.0, 45.0]])
RECORD_KEYS = {"squares", "inner_squares", "docks", "steps", "end"}


@pytest.fixture(scope="module")
def serial_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    rep = validate(BITS, STARTS, table=load_table("paper"), workers=1, max_steps=20, out_dir=out)
    return out, rep


def test_report_layout_and_files(serial_report):
    out, rep = serial_report
    doc = json.loads((out / "report.json").read_text())
    assert len(doc["runs"]) == 2
    for k, r in enumerate(doc["runs"]):
        assert r["index"] == k
        assert r["start"] == dict(zip("xyh", STARTS[k], strict=True))
        assert r["error"] is None
        for world in ("table", "physics"):
            assert RECORD_KEYS <= set(r[world])
            assert set(r[world]["end"]) == {"code", "name"}
            assert 0 < r[world]["steps"] <= 20
            assert 0 <= r[world]["inner_squares"] <= r[world]["squares"]
    s = doc["summary"]
    assert s["starts"] == 2 and s["physics_ok"] == 2 and s["physics_errors"] == 0
    for world in ("table", "physics"):
        w = s[world]
        mean_inner = np.mean([r[world]["inner_squares"] for r in doc["runs"]])
        assert w["inner_pct"] == pytest.approx(100 * mean_inner / 64)
        assert 0.0 <= w["dock_success"] <= 1.0
    assert s["gap"]["inner_pct_pp"] == pytest.approx(
        s["table_paired"]["inner_pct"] - s["physics"]["inner_pct"]
    )
    assert "wall_s" in s
    md = (out / "report.md").read_text()
    assert "| # | start" in md and "gap table − physics" in md
    tracks = np.load(out / "tracks.npz")
    assert tracks["physics_1"].shape == (doc["runs"][1]["physics"]["steps"] + 1, 3)
    assert np.allclose(tracks["table_0"][0], STARTS[0])


def test_physics_blow_up_is_that_runs_error_only(tmp_path, monkeypatch):
    """Start 1's physics state turns NaN at its third cycle: ServoBot's own check raises, the
    run is recorded with its error and its table record, and start 0 is unaffected."""
    original = physics_world.PhysicsWorld.step

    def step(self, gait):
        if self.cycles == 2 and abs(self.pose()[0] - 300.0) < 40.0:
            self.data.qvel[0] = np.nan
        return original(self, gait)

    monkeypatch.setattr(physics_world.PhysicsWorld, "step", step)
    rep = validate(BITS, STARTS, table=PAPER_TABLE, executor=SerialExecutor(), max_steps=10,
                   out_dir=tmp_path, rrd=True)  # fmt: skip
    ok, bad = rep["runs"]
    assert ok["error"] is None and ok["physics"]["steps"] == 10
    assert bad["physics"] is None and "PhysicsError" in bad["error"]
    assert "BADQVEL" in bad["error"] or "non-finite" in bad["error"]
    assert bad["table"]["steps"] == 10 and bad["physics_partial"]["steps"] == 2
    doc = json.loads((tmp_path / "report.json").read_text())
    assert doc["summary"]["physics_errors"] == 1 and doc["summary"]["physics_ok"] == 1
    assert "## Errors" in (tmp_path / "report.md").read_text()
    # The failed run's recording (table run + physics up to the blow-up) is still written.
    assert (tmp_path / "run0.rrd").exists() and (tmp_path / "run1.rrd").exists()


def test_bad_inputs_are_named():
    with pytest.raises(ValidationError, match="8 or 16 genes"):
        validate(BITS[:12], STARTS, table=PAPER_TABLE, workers=1)
    with pytest.raises(ValidationError, match="kill zone"):
        validate(BITS, [[480.0, 250.0, 0.0]], table=PAPER_TABLE, workers=1)
    with pytest.raises(ValidationError, match="outside"):
        validate(BITS, [[250.0, -10.0, 0.0]], table=PAPER_TABLE, workers=1)
    with pytest.raises(ValidationError, match=r"\(N, 3\)"):
        validate(BITS, [250.0, 250.0], table=PAPER_TABLE, workers=1)


# --------------------------------------------------------------------------- the CLI
@pytest.fixture
def chromosome(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text("# always gait 8\n" + GENE_8 * 16)
    return path


def test_cli_smoke(chromosome, tmp_path, capsys):
    out = tmp_path / "out"
    rc = validate_cli.main(
        [str(chromosome), "--starts", "2", "--steps", "8", "--workers", "1", "--no-progress",
         "--out", str(out), "--seed", "3"]
    )  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "report.json").read_text())
    want = coverage_starts(np.random.default_rng(3), 2, WorldSettings())
    assert np.allclose([[r["start"][k] for k in "xyh"] for r in doc["runs"]], want)
    printed = capsys.readouterr().out
    assert "| # | start" in printed and "physics:" in printed


def test_cli_station_height_reaches_the_physics_arena(chromosome, tmp_path):
    """``--station-height`` sets the physics block's height (``ArenaSettings``; what the
    rangefinders see of a tall block is tested in ``test_physics_world``); a height ≤ 0 is
    refused."""
    out = tmp_path / "tall"
    rc = validate_cli.main(
        [str(chromosome), "--start", "440", "250", "90", "--steps", "1", "--workers", "1",
         "--no-progress", "--out", str(out), "--station-height", "0.30"]
    )  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "report.json").read_text())
    assert doc["settings"]["ArenaSettings"]["station_height_m"] == 0.30
    assert validate_cli.main([str(chromosome), "--station-height", "-1", "--out", str(out)]) == 2


def test_cli_rrd_writes_one_recording_per_run(chromosome, tmp_path):
    out = tmp_path / "out"
    rc = validate_cli.main(
        [str(chromosome), "--start", "300", "300", "45", "--steps", "4", "--workers", "1",
         "--no-progress", "--out", str(out), "--rrd"]
    )  # fmt: skip
    assert rc == 0
    assert not (out / "run1.rrd").exists()
    import rerun as rr

    rows: dict[str, int] = {}
    for chunk in rr.chunk.RrdReader(out / "run0.rrd").stream().collect().stream():
        if not chunk.is_static:
            rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    # Both worlds' poses, one row per event, and the robot's bodies every control frame.
    robot = "/world/robots/servobot"
    assert rows[f"{robot}/physics/pose"] == rows[f"{robot}/table/pose"] >= 4
    assert rows[f"{robot}/bodies/torso"] >= 4 * 8
    assert "/plots/sensors/servobot/physics/object_left" in rows


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--start", "10", "250", "0"], "kill zone"),
        (["--start", "600", "250", "0"], "outside the 500 x 500 arena"),
        (["--start", "470", "260", "270"], "overlaps the power-station block"),
        (["--starts", "0"], "--starts must be an integer ≥ 1, got 0"),
        (["--workers", "0"], "--workers must be an integer between 1 and"),
        (["--table", "nope.json"], "no such gait-table file"),
    ],
)
def test_cli_bad_input_exits_2_with_a_message(chromosome, args, message, capsys):
    assert validate_cli.main([str(chromosome), "--no-progress", *args]) == 2
    assert message in capsys.readouterr().err


def test_cli_rejects_unparsable_and_8_gene_chromosomes(tmp_path, capsys):
    bad = tmp_path / "bad.txt"
    bad.write_text(GENE_8 * 3 + "01 0100000 01000x0 0100000 0100000\n" + GENE_8 * 12)
    assert validate_cli.main([str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.txt:4" in err and "non-binary" in err
    section = tmp_path / "section.txt"
    section.write_text(GENE_8 * 8)
    assert validate_cli.main([str(section), "--robots", "2"]) == 2  # a colony runs 16 genes
    assert "16-gene" in capsys.readouterr().err
    assert validate_cli.main([str(section), "--poses", str(section), "--start", "100", "100",
                              "0"]) == 2  # fmt: skip
    assert "--poses" in capsys.readouterr().err


# --------------------------------------------------------------------------- navigation mode
SECTION = parse_chromosome(LIGHT_FOLLOWER)


def test_a_navigation_section_runs_in_navigation_mode_from_its_powers(tmp_path):
    world = WorldSettings()
    starts = np.array([[300.0, 250.0, 90.0], [300.0, 250.0, 90.0]])
    rep = validate(SECTION, starts, table=load_table("paper"), workers=1, powers=[4.0, 2.9])
    assert rep["settings"]["mode"] == "navigation"
    assert rep["settings"]["max_steps"] == world.navigation_steps
    full, weak = rep["runs"]
    assert (full["power"], weak["power"]) == (4.0, 2.9)  # recorded with each run
    # 2.9 V leaves (2.9 - 2.7) / 0.0209 = 9.6 cycles before the power runs out; 4.0 V docks
    for w in ("table", "physics"):
        assert full[w]["end"]["name"] == "docked" and full[w]["docks"] == 1
        assert weak[w]["end"]["name"] == "power empty" and weak[w]["steps"] == 10
        assert "handoffs" not in full[w]  # a navigation run has none
    with pytest.raises(ValidationError, match="power of start 1 is 2.0 V"):
        validate(SECTION, starts, table=load_table("paper"), powers=[4.0, 2.0])
    with pytest.raises(ValidationError, match="one per start"):
        validate(SECTION, starts, table=load_table("paper"), powers=[4.0])


def test_coverage_runs_record_their_hand_offs_in_both_worlds():
    # coverage turns on the spot right and back left (2 × 0.0209 V), its low-power test then
    # positive at the start pose (as tests/test_navigation_choice.py's SWITCH_AT_ONCE); the
    # navigation section walks east, 5 cycles into the docking box from x = 400
    cover = gene("00", G(14), G(6), B(4, 0), G(7))
    walk = "\n".join([gene("00", G(0), G(0), G(0), G(0))] * 8)
    bits = np.concatenate([chrom(cover, n=8), parse_chromosome(walk)])
    start = np.array([[400.0, 250.0, 90.0]])
    table = load_table("paper")
    (run,) = validate(bits, start, table=table, workers=1, max_steps=40)["runs"]
    (found,) = collect_handoffs(bits, start, table=table, world=WorldSettings(), max_steps=40)
    assert run["table"]["handoffs"] == [handoff_record(h) for h in found]
    for w in ("table", "physics"):
        first = run[w]["handoffs"][0]
        assert first["step"] == 2 and first["outcome"] == DOCKED
        np.testing.assert_allclose(first["pose"], start[0], atol=0.5)  # physics turns in place
        assert first["power"] == pytest.approx(4.0 - 2 * 0.0209, abs=1e-4)
        outcomes = [h["outcome"] for h in run[w]["handoffs"]]
        assert outcomes.count(DOCKED) == run[w]["docks"] >= 1


def test_cli_runs_a_section_from_hand_off_poses(tmp_path, capsys):
    section = tmp_path / "nav.txt"
    section.write_text(LIGHT_FOLLOWER)
    poses = tmp_path / "handoffs.csv"
    poses.write_text(
        "x,y,h,power,outcome\n300,250,90,4.0,docked\n470,260,270,3.9,cut\n"
        "300,300,45,2.9,kill zone\n"
    )  # the second pose overlaps the station block: left out
    out = tmp_path / "out"
    rc = validate_cli.main([str(section), "--poses", str(poses), "--workers", "1",
                            "--no-progress", "--out", str(out)])  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    doc = json.loads((out / "report.json").read_text())
    assert [[r["start"][k] for k in "xyh"] for r in doc["runs"]] == [[300, 250, 90], [300, 300, 45]]
    assert doc["runs"][1]["table"]["steps"] == 10  # started at 2.9 V
    rc = validate_cli.main([str(section), "--poses", str(poses), "--starts", "3", "--out",
                            str(tmp_path / "o2")])  # fmt: skip
    assert rc == 2 and "2 clear of the station block" in capsys.readouterr().err


def test_cli_rejects_a_table_from_another_robot_model(chromosome, tmp_path, capsys):
    from servo_mj.robot.model import model_sha256

    other = tmp_path / "other.json"
    doc = table_to_json(PAPER_TABLE, provenance={"model_sha256": "0" * 64})
    other.write_text(json.dumps(doc))
    assert validate_cli.main([str(chromosome), "--table", str(other)]) == 2
    err = capsys.readouterr().err
    assert "0" * 64 in err and model_sha256() in err
    robot = tmp_path / "robot.json"
    robot.write_text(json.dumps(dict(doc, robot="khepera")))
    assert validate_cli.main([str(chromosome), "--table", str(robot)]) == 2
    assert "khepera" in capsys.readouterr().err


def test_servo_noise_is_seeded_per_run():
    from servo_mj.robot.settings import PhysicsSettings

    noisy = PhysicsSettings(servo_noise_rad=0.03)

    def final(seed):
        rep = validate(BITS, STARTS[1:], table=PAPER_TABLE, physics=noisy, workers=1,
                       max_steps=6, seed=seed)  # fmt: skip
        return rep["runs"][0]["physics"]["final_pose"]

    assert final(1) == final(1)
    assert final(1) != final(2)
