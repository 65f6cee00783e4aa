"""Pooling colony validations (``servobot.validation.colony_pool``) on hand-made reports."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from evolve.settings import ColonySettings, WorldSettings
from infra.errors import InputError
from servobot.validation.colony_pool import main, pool, pool_markdown
from servobot.validation.colony_report import ended_at_station

WORLD = {"grid_n": 10, "dock_point": [465.0, 250.0]}
STATION, FIELD = [460.0, 262.0, 90.0], [100.0, 100.0, 0.0]  # 13 cm and 403 cm from the dock


def robot(end: str, code: int, pose: list[float], docks: int) -> dict:
    return {"end": {"name": end, "code": code}, "final_pose": pose, "docks": docks}


def run(inner: int, robots: list[dict], physics: bool = True) -> dict:
    rec = {"colony": {"inner_squares": inner}, "robots": robots}
    return {"table": rec, "physics": rec if physics else None}


def report(runs: list[dict]) -> dict:
    return {"settings": {"WorldSettings": WORLD}, "runs": runs}


STEP_LIMIT, EMPTY = ("step limit", 0), ("power empty", 2)
REPORTS = [
    report([run(32, [robot(*STEP_LIMIT, FIELD, 3), robot(*EMPTY, STATION, 1)]),
            run(64, [robot(*EMPTY, FIELD, 0), robot(*EMPTY, STATION, 2)]),
            run(0, [robot(*STEP_LIMIT, FIELD, 9)], physics=False)]),  # no physics: left out
    report([run(16, [robot(*STEP_LIMIT, STATION, 2), robot(*STEP_LIMIT, FIELD, 4)])]),
]  # fmt: skip


def test_ended_at_station_is_a_distance_from_the_dock_point() -> None:
    dock = WorldSettings().dock_point
    assert ended_at_station(robot(*EMPTY, [465.0 + 69.9, 250.0, 0.0], 0), dock)
    assert not ended_at_station(robot(*EMPTY, [465.0, 250.0 - 70.1, 0.0], 0), dock)


def test_pool_counts_runs_whose_physics_finished() -> None:
    got = pool(REPORTS)
    for w in ("table", "physics"):
        s = got[w]
        assert s["runs"] == 3 and s["robots"] == 6
        assert s["inner_pct"] == pytest.approx(100 * (32 + 64 + 16) / 64 / 3)
        assert s["docks_per_robot"] == pytest.approx((3 + 1 + 0 + 2 + 2 + 4) / 6)
        assert s["live_per_run"] == pytest.approx((1 + 0 + 2) / 3)  # step limit is live
        assert s["live_by_robot"] == pytest.approx([2 / 3, 1 / 3])
        assert s["failed_handoffs_pct"] == pytest.approx(100 * 3 / (12 + 3))  # 3 empty, 12 docks
        assert s["ends"] == {"step limit": 3, "power empty": 3}
        assert s["ends_at_station"] == {"power empty": 2, "step limit": 1}
    assert got["gap_inner_pp"] == 0.0
    md = pool_markdown(got)
    row = ("| physics | 3 | 58.3 | 2.00 | 20.0 | 1.00 | 0.67 / 0.33 | "
           "50 % (2 of 3) | 50 % (1 of 3) |")
    assert row in md


def test_pool_gives_each_robot_index_its_own_lives() -> None:
    """Teams of different sizes pool robot i over the runs that have one; a colony that never
    docks and never empties has no failed hand-off (not a division by zero)."""
    lone = report([run(8, [robot(*STEP_LIMIT, FIELD, 0)]), run(8, [robot(*STEP_LIMIT, FIELD, 0)])])
    pair = report([run(8, [robot(*EMPTY, FIELD, 0), robot(*STEP_LIMIT, FIELD, 0)])])
    got = pool([lone, pair])["physics"]
    assert got["live_by_robot"] == pytest.approx([2 / 3, 1.0])
    assert got["failed_handoffs_pct"] == 100.0  # one hand-off, never docked
    assert pool([lone])["physics"]["failed_handoffs_pct"] == 0.0


def test_cli_reads_a_folder_of_populations(tmp_path: Path, capsys) -> None:
    for k, rep in enumerate(REPORTS):
        (tmp_path / f"pop{k}").mkdir()
        (tmp_path / f"pop{k}" / "report.json").write_text(json.dumps(rep))
    assert main([str(tmp_path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(pool(REPORTS)))
    assert main([str(tmp_path / "pop0")]) == 0  # one validation's own report.json
    assert "| table | 2 |" in capsys.readouterr().out


def test_cli_names_what_it_cannot_use(tmp_path: Path, capsys) -> None:
    assert main([str(tmp_path)]) == 2
    assert f"{tmp_path}: no report.json and no pop*/report.json" in capsys.readouterr().err
    (tmp_path / "report.json").write_text("{not json")
    assert main([str(tmp_path)]) == 2
    assert "report.json: not a readable report" in capsys.readouterr().err
    (tmp_path / "report.json").write_text(json.dumps({"runs": [run(1, [])]}))
    assert main([str(tmp_path)]) == 2
    assert "report.json: not a colony validation report (bad or missing field 'settings')" \
        in capsys.readouterr().err  # fmt: skip
    (tmp_path / "report.json").write_text(json.dumps(report([run(1, [], physics=False)])))
    assert main([str(tmp_path)]) == 2
    assert "no colony run whose physics finished" in capsys.readouterr().err


@pytest.fixture(scope="module")
def pushing_report(tmp_path_factory):
    """A colony validation (both worlds) of robot 0 walking into robot 1 front-right of it."""
    from chromosome_text import G, chrom, gene

    from evolve.table import PAPER_TABLE
    from servobot.validation.colony import validate_colony

    walk = chrom(gene("00", G(8), G(8), G(8), G(8)))
    starts = np.array([[[200.0, 200.0, 0.0], [221.0, 224.0, 0.0]]])
    out = tmp_path_factory.mktemp("pool")
    validate_colony(walk, starts, table=PAPER_TABLE, colony=ColonySettings(robots=2),
                    workers=1, max_steps=3, out_dir=out)  # fmt: skip
    return out, json.loads((out / "report.json").read_text())


def test_replay_reruns_the_table_side_with_a_changed_rule(pushing_report):
    from servobot.validation.colony_pool import replay

    _, rep = pushing_report
    same = replay(rep)
    strip = [{**r, "table": {**r["table"], "wall_s": 0.0}} for r in rep["runs"]]
    assert same["runs"] == strip and same["settings"] == rep["settings"]
    turned = replay(rep, contact_yaw_deg=9.3)
    (run,) = turned["runs"]
    assert run["physics"] == rep["runs"][0]["physics"]  # physics is the report's
    old, new = rep["runs"][0]["table"]["robots"][0], run["table"]["robots"][0]
    assert old["collisions"] > 0 and new["final_pose"][2] != old["final_pose"][2]
    with pytest.raises(InputError, match="replay: ColonySettings has unknown fields \\['yaw'\\]"):
        replay(rep, yaw=1.0)
    with pytest.raises(InputError, match="replay: ColonySettings: contact_yaw_deg must be"):
        replay(rep, contact_yaw_deg=-1.0)


def test_cli_replay(pushing_report, capsys):
    out, _ = pushing_report
    assert main([str(out), "--replay", "contact_yaw_deg=9.3", "blocking=slide", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["table"]["runs"] == 1
    assert main([str(out), "--replay", "contact_yaw_deg"]) == 2
    assert "--replay: FIELD=VALUE expected, got 'contact_yaw_deg'" in capsys.readouterr().err


def test_replay_in_an_envelope_draws_per_draw_index(pushing_report):
    from evolve.envelope import Envelope
    from evolve.table import PAPER_TABLE, GaitTable
    from servobot.validation.colony_pool import replay

    _, rep = pushing_report
    assert replay(rep, envelope=Envelope(), draw=3) == replay(rep)  # none: no draw matters
    scatter = Envelope(scatter_scale=1.0)
    d0, d0_again, d1 = (replay(rep, envelope=scatter, draw=d) for d in (0, 0, 1))
    assert d0 == d0_again  # keyed draws: repeatable
    poses = [r["runs"][0]["table"]["robots"][0]["final_pose"] for r in (replay(rep), d0, d1)]
    assert len({tuple(p) for p in poses}) == 3  # the scatter moves the robot, per draw
    assert d0["runs"][0]["physics"] == rep["runs"][0]["physics"]
    wrong = GaitTable(PAPER_TABLE + 1.0, source="other.json")
    with pytest.raises(InputError, match="--table other.json: not the gait table the report"):
        replay(rep, envelope=scatter, table=wrong)


def test_cli_replay_in_an_envelope(pushing_report, capsys, tmp_path):
    out, _ = pushing_report
    env = tmp_path / "env.json"
    env.write_text(json.dumps({"scatter_scale": 1.0, "station_stops": "always"}))
    assert main([str(out), "--envelope", str(env), "--draws", "3", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["table"]["runs"] == 3 and got["physics"]["runs"] == 1  # 3 draws of 1 start
    assert got["gap_inner_pp"] == got["table"]["inner_pct"] - got["physics"]["inner_pct"]
    assert main([str(out), "--draws", "2"]) == 2
    assert "--draws and --table go with --envelope" in capsys.readouterr().err
    assert main([str(out), "--envelope", "default", "--draws", "0"]) == 2
    assert "--draws must be an integer ≥ 1, got 0" in capsys.readouterr().err
    env.write_text(json.dumps({"scatter_scale": -1.0}))
    assert main([str(out), "--envelope", str(env)]) == 2
    assert "scatter_scale must be ≥ 0" in capsys.readouterr().err
