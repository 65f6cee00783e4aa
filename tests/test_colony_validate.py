"""``validate_colony`` and ``servobot validate --robots R``: a colony in both worlds, its report,
tracks, figures and recording; a physics robot kept from docking while another charges; R = 1
gives the lone validation's records; bad input."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

from evolve.codec import format_chromosome
from evolve.settings import ColonySettings, WorldSettings
from evolve.starts import colony_starts
from evolve.table import PAPER_TABLE
from servobot.cli import validate as validate_cli
from servobot.recording.colony import robot_color
from servobot.validation.colony import validate_colony
from servobot.validation.lone import ValidationError, validate
from tests.test_physics_colony import DOCKER, TOLERANCE_CM
from tests.test_recording import Rrd

LOW = dataclasses.replace(WorldSettings(), start_power_v=3.95)
"""Runs start on low power: the DOCKER controller goes straight for the station."""
AT_STATION = np.array([[[440.0, 235.0, 90.0], [440.0, 266.0, 90.0]]])
"""Two robots side by side facing the station, both inside the docking box's width."""
STEPS = 14


@pytest.fixture(scope="module")
def station_run(tmp_path_factory):
    """Both robots walk into the station: robot 0 docks first and charges for 10 colony steps
    while robot 1, pushing against the block beside it, is refused; then robot 1 docks."""
    out = tmp_path_factory.mktemp("colony")
    rep = validate_colony(DOCKER, AT_STATION, table=PAPER_TABLE, world=LOW, workers=1,
                          max_steps=STEPS, out_dir=out, rrd=True)  # fmt: skip
    return out, rep


def test_report_layout_tracks_and_figure(station_run):
    out, rep = station_run
    doc = json.loads((out / "report.json").read_text())
    assert doc == json.loads(json.dumps(rep))
    (run,) = doc["runs"]
    assert run["error"] is None
    assert run["start"] == [dict(zip("xyh", p, strict=True)) for p in AT_STATION[0]]
    tracks = np.load(out / "tracks.npz")
    for world in ("table", "physics"):
        rec = run[world]
        assert set(rec["colony"]) >= {"squares", "inner_squares"}
        assert len(rec["robots"]) == 2
        for b in rec["robots"]:
            assert set(b) >= {"squares", "inner_squares", "docks", "steps", "end"}
            assert 0 < b["steps"] <= STEPS
        reached = rec["colony"]["squares"]
        assert (
            max(b["squares"] for b in rec["robots"])
            <= reached
            <= sum(b["squares"] for b in rec["robots"])
        )
        track = tracks[f"{world}_0"]
        assert track.shape == (rec["colony"]["colony_steps"] + 1, 2, 3)
        np.testing.assert_allclose(track[0], AT_STATION[0], atol=1.0)  # physics: settled
        if world == "table":  # (in physics a robot that ended may be pushed afterwards)
            np.testing.assert_allclose(track[-1], [b["final_pose"] for b in rec["robots"]],
                                       atol=1e-3)  # fmt: skip
    s = doc["summary"]
    assert s["robots"] == 2 and s["physics_ok"] == 1
    inner = run["physics"]["colony"]["inner_squares"]
    assert s["physics"]["inner_pct"] == pytest.approx(100 * inner / 64)
    assert s["gap"]["inner_pct_pp"] == pytest.approx(
        s["table_paired"]["inner_pct"] - s["physics"]["inner_pct"]
    )
    assert doc["settings"]["ColonySettings"]["robots"] == 2
    for world in ("table", "physics"):  # live at the end: step limit (or docked), of 2
        live = sum(b["end"]["name"] in ("step limit", "docked") for b in run[world]["robots"])
        assert s[world]["live_at_end_per_run"] == live
        near = [b["end"]["name"] for b in run[world]["robots"]
                if np.hypot(b["final_pose"][0] - 465, b["final_pose"][1] - 250) <= 70]  # fmt: skip
        assert s[world]["ends_at_station"] == {e: near.count(e) for e in near}
    assert (out / "tracks0.png").stat().st_size > 10_000
    md = (out / "report.md").read_text()
    assert "## Per robot" in md and "gap table − physics" in md


def test_a_physics_robot_waits_while_the_other_charges(station_run):
    """Physics: robot 1 is refused while robot 0 charges, pushing against the block, then
    docks. The table world's station is only a wall (SPEC §3): there robot 1, refused, walks
    on into the kill zone."""
    _, rep = station_run
    r0, r1 = rep["runs"][0]["physics"]["robots"]
    assert (r0["docks"], r1["docks"]) == (1, 1)
    assert r0["station_waits"] == 0
    assert 5 <= r1["station_waits"] <= 10  # robot 0 charges for 10 colony steps
    assert r0["steps"] == r1["steps"] == STEPS
    t0, t1 = rep["runs"][0]["table"]["robots"]
    assert (t0["docks"], t1["docks"]) == (1, 0)
    assert t1["station_waits"] >= 1 and t1["end"]["name"] == "kill zone"
    phys = rep["runs"][0]["physics"]
    # Side by side at the block, the bumpers touch but never overlap.
    assert 30.0 - TOLERANCE_CM < phys["min_distance_cm"] < 31.0
    assert phys["colony"]["collisions"] > 0


def test_recording_holds_every_robot_and_the_station_timeline(station_run):
    out, rep = station_run
    rrd = Rrd(out / "run0.rrd")
    for i in range(2):
        base = f"/world/robots/robot{i}"
        assert rrd.rows[f"{base}/bodies/torso"] >= STEPS * 16  # every frame of every cycle
        assert rrd.rows[f"{base}/physics/pose"] > STEPS
        assert {"sim_time", "colony_step"} <= rrd.timelines[f"{base}/bodies/torso"]
    for i in range(2):  # each robot's physics track in its own colour (RGBA packed)
        (colour,) = rrd.static_column(f"/world/robots/robot{i}/physics/track",
                                      "LineStrips3D:colors")[0]  # fmt: skip
        r, g, b = robot_color(i)
        assert colour == (r << 24) | (g << 16) | (b << 8) | 255
    assert robot_color(0) != robot_color(1)
    station = rrd.column("/colony/physics/station", "StateChange:state", order="colony_step")
    assert [v[0] for v in station] == ["free", "robot0 charging", "free", "robot1 charging", "free"]
    lane = [v[0] for v in rrd.column("/colony/physics/robot1", "StateChange:state",
                                     order="colony_step")]  # fmt: skip
    assert lane[:3] == ["coverage", "navigation", "waiting"] and "charging" in lane
    waits = rrd.column("/plots/colony/physics", "Scalars:scalars", order="colony_step")
    assert waits[-1][0] == rep["runs"][0]["physics"]["colony"]["station_waits"]
    result = rrd.static_column("/__properties/result", "physics_colony_station_waits")
    assert result == [[rep["runs"][0]["physics"]["colony"]["station_waits"]]]
    res = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(out / "run0.rrd")],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    if "unrecognized subcommand" not in res.stderr:
        assert res.returncode == 0, res.stderr[-2000:]


def test_recording_lines_both_worlds_up_on_the_colony_step(station_run):
    """The layout opens on ``colony_step``: there robot 0's table and physics poses are those of
    the same robot step, a few cm apart (the reality gap); on ``sim_time``, which the worlds do
    not share, the table world runs ahead by up to 20 gait cycles (32 s) in this run."""
    out, _ = station_run
    rrd = Rrd(out / "run0.rrd")
    assert rrd.blueprint_value("time_panel", "TimePanelBlueprint:timeline") == [["colony_step"]]
    base = "/world/robots/robot0"
    seen = {}
    for world in ("table", "physics"):
        pose = f"{base}/{world}/pose"
        seen[world] = {
            "at": list(zip(rrd.column(pose, "colony_step", "colony_step"),
                           rrd.column(pose, "step", "colony_step"), strict=True)),
            "xy": np.array([t[0][:2] for t in rrd.column(pose, "Transform3D:translation",
                                                         "colony_step")]),
            "t": np.array(rrd.column(pose, "sim_time", "colony_step")) / 1e9,
        }  # fmt: skip
    table, physics = seen["table"], seen["physics"]
    assert table["at"] == physics["at"]  # the same robot step at every colony step
    assert np.linalg.norm(table["xy"] - physics["xy"], axis=1).max() < 0.20  # m
    assert np.abs(table["t"] - physics["t"]).max() > 16.0  # s: sim_time would not line up


def test_recording_contact_arrows_are_bounded(station_run):
    """Pushing against the block the contact forces reach kN; every arrow is drawn at most
    ``force_max_length_m`` long, the same in every recording."""
    from servobot.recording import RecordingSettings

    out, _ = station_run
    rrd = Rrd(out / "run0.rrd")
    bound = RecordingSettings().force_max_length_m
    lengths = np.concatenate([
        np.linalg.norm(np.array(v), axis=1)
        for i in range(2)
        for v in rrd.column(f"/world/robots/robot{i}/contacts", "Arrows3D:vectors", "colony_step")
        if v
    ])  # fmt: skip
    assert lengths.max() <= bound * (1 + 1e-6)
    assert (lengths > 0.999 * bound).any()  # some forces above 5 N: drawn clamped


def test_recording_names_model_table_and_command(station_run):
    import shlex

    from tests.test_recording import assert_provenance

    out, _ = station_run
    assert_provenance(Rrd(out / "run0.rrd"), table=PAPER_TABLE, source="array",
                      command=shlex.join(sys.argv))  # fmt: skip


def test_one_robot_colony_validation_gives_the_lone_records():
    """The same starts, the same seeds: R = 1 in the colony validation gives the lone
    validation's records in both worlds, docking and charging included (the tracks, bit for
    bit: ``test_physics_colony``)."""
    starts = np.array([[430.0, 250.0, 90.0], [300.0, 300.0, 45.0]])
    lone = validate(DOCKER, starts, table=PAPER_TABLE, world=LOW, workers=1, max_steps=STEPS,
                    seed=4)  # fmt: skip
    col = validate_colony(DOCKER, starts[:, None, :], table=PAPER_TABLE, world=LOW, workers=1,
                          max_steps=STEPS, seed=4)  # fmt: skip
    assert lone["runs"][0]["physics"]["docks"] == 1
    keys = ("squares", "inner_squares", "docks", "steps", "end", "final_pose")
    for a, b in zip(lone["runs"], col["runs"], strict=True):
        for world in ("table", "physics"):
            (robot,) = b[world]["robots"]
            assert {k: robot[k] for k in keys} == {k: a[world][k] for k in keys}, world
            assert b[world]["colony"]["inner_squares"] == a[world]["inner_squares"]


def test_refused_colony_inputs_are_named():
    with pytest.raises(ValidationError, match=r"\(N, 2, 3\)"):
        validate_colony(DOCKER, AT_STATION[0], table=PAPER_TABLE,
                        colony=ColonySettings(robots=2))  # fmt: skip
    close = np.array([[[300.0, 300.0, 0.0], [320.0, 300.0, 0.0]]])
    with pytest.raises(ValidationError, match="robots 0 and 1 are 20 units apart"):
        validate_colony(DOCKER, close, table=PAPER_TABLE)
    with pytest.raises(ValidationError, match="start 0, robot 1.*kill zone"):
        validate_colony(DOCKER, [[[300.0, 300.0, 0.0], [10.0, 300.0, 0.0]]], table=PAPER_TABLE)


# --------------------------------------------------------------------------- the CLI
@pytest.fixture
def chromosome(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text(format_chromosome(DOCKER))
    return path


def test_cli_draws_colony_starts_and_prints_the_colony(chromosome, tmp_path, capsys):
    out = tmp_path / "out"
    rc = validate_cli.main([str(chromosome), "--robots", "3", "--starts", "1", "--steps", "2",
                            "--workers", "1", "--no-progress", "--out", str(out),
                            "--seed", "5"])  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "report.json").read_text())
    want = colony_starts(np.random.default_rng(5), 1, WorldSettings(), ColonySettings(robots=3))
    got = [[[p[k] for k in "xyh"] for p in r["start"]] for r in doc["runs"]]
    np.testing.assert_allclose(got, want)
    assert "colonies of 3" in capsys.readouterr().out


def test_cli_takes_given_starts_r_at_a_time(chromosome, tmp_path):
    out = tmp_path / "out"
    rc = validate_cli.main([str(chromosome), "--robots", "2", "--start", "300", "300", "0",
                            "--start", "300", "350", "0", "--steps", "1", "--workers", "1",
                            "--no-progress", "--out", str(out)])  # fmt: skip
    assert rc == 0
    (run,) = json.loads((out / "report.json").read_text())["runs"]
    assert [p["y"] for p in run["start"]] == [300.0, 350.0]
    # cancel, the default, is not recorded (the records made before the setting existed)
    record = json.loads((out / "report.json").read_text())["settings"]["ColonySettings"]
    assert "blocking" not in record


def test_cli_blocking_reaches_the_table_world(chromosome, tmp_path):
    """``--blocking slide``: recorded, and the table world's colony runs under it."""
    out = tmp_path / "out"
    rc = validate_cli.main([str(chromosome), "--robots", "2", "--blocking", "slide", "--start",
                            "300", "300", "0", "--start", "300", "350", "0", "--steps", "1",
                            "--workers", "1", "--no-progress", "--out", str(out)])  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "report.json").read_text())
    assert doc["settings"]["ColonySettings"]["blocking"] == "slide"
    args = validate_cli.build_parser().parse_args([str(chromosome), "--robots", "2",
                                                   "--blocking", "slide"])  # fmt: skip
    assert validate_cli._colony(args) == ColonySettings(robots=2, blocking="slide")
