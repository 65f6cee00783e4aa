"""The station block's rules against physics (servobot.robustness.block_contact)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from evolve.geometry import wrap180
from evolve.table import PAPER_TABLE
from evolve.world import TableWorld
from servo_mj.world.physics_world import PhysicsWorld
from servobot.robustness import block_contact
from servobot.robustness.block_contact import contact_errors, report, rules


def test_errors_are_measured_against_physics_on_the_cases_the_block_stops():
    """Head-on at 455 the first cycle would end 13.4 units from the block (radius 15): the
    cancel rule keeps the start pose, so its error is physics' own displacement. Far from the
    block (x = 300) nothing stops: the case is left out."""
    head_on = (455.0, 250.0, 90.0)
    rows = contact_errors(PAPER_TABLE, [head_on, (300.0, 250.0, 90.0)], [0], rules([0.5]), 2)
    assert [r.rule for r in rows] == ["cancel", "slide 0.5"]
    phys = PhysicsWorld(*head_on)
    phys.step(0), phys.step(0)
    x, y, h = phys.pose()
    cancel = rows[0].errors
    assert cancel.shape == (1, 2)
    assert cancel[0, 0] == pytest.approx(math.hypot(x - 455.0, y - 250.0), abs=1e-9)
    assert cancel[0, 1] == pytest.approx(abs(wrap180(h - 90.0)), abs=1e-9)
    # head-on, friction holds the slid move too (|along| 0.8 < 0.5 × 11.6 into the block)
    assert rows[1].errors[0, 0] == pytest.approx(cancel[0, 0], abs=1e-9)
    doc, md = report({"one": rows}, 2)
    assert doc["sets"]["one"]["cases"] == 1 and "## one: 1 cases the block stops" in md


def test_cycle_errors_start_each_cycle_from_physics_pose():
    """Cycle by cycle, a rule's error is measured from physics' pose before the cycle: two
    cycles of gait 0 far from the block, where no rule stops, give the open table's error of
    each physics cycle."""
    pose = (300.0, 250.0, 90.0)
    rows = block_contact.cycle_errors(PAPER_TABLE, [pose], [0], block_contact.margin_rules([3.0]),
                                      2)  # fmt: skip
    phys = PhysicsWorld(*pose)
    want = []
    for _ in range(2):
        start = phys.pose()
        phys.step(0)
        tab = TableWorld(PAPER_TABLE, *start)
        tab.step(0)
        (x, y, h), (px, py, ph) = tab.pose(), phys.pose()
        want.append((math.hypot(x - px, y - py), abs(wrap180(h - ph))))
    for r in rows:
        np.testing.assert_allclose(r.errors, want, rtol=0, atol=1e-9)


def test_the_command_writes_its_report_and_refuses_bad_settings(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(block_contact, "POSE_SETS", {"tiny": ([(458.0, 262.0, 45.0)], (0,))})
    monkeypatch.setattr(block_contact, "CORNERS", ([(468.0, 294.0, 90.0)], (0,)))
    args = ["--frictions", "0,0.5", "--cycles", "2", "--margins", "0,3", "--bodies", "15/15/15",
            "--out", str(tmp_path)]  # fmt: skip
    assert block_contact.main(args) == 0
    doc = json.loads((tmp_path / "block_contact.json").read_text())
    assert set(doc["sets"]["tiny"]["rules"]) == {"cancel", "slide 0", "slide 0.5"}
    by_cycle = doc["cycle_by_cycle"]["tiny"]
    assert by_cycle["cases"] == 2  # every cycle of the one case
    assert set(by_cycle["rules"]) == {"cancel", "slide 0.5, margin 0", "slide 0.5, margin 3",
                                      "slide 0.5, body 15/15/15"}  # fmt: skip
    # an oval as wide as long is the disc, cycle for cycle
    for name in ("tiny", "corners"):
        rules = doc["cycle_by_cycle"][name]["rules"]
        assert rules["slide 0.5, body 15/15/15"] == rules["slide 0.5, margin 0"]
    assert (tmp_path / "block_contact.png").stat().st_size > 0
    bad_args = (["--frictions", "half"], ["--frictions", "-1"], ["--cycles", "0"],
                ["--margins", "-2"], ["--bodies", "15/15"], ["--bodies", "15/0/12"],
                ["--world", "icy"])  # fmt: skip
    for bad in bad_args:
        with pytest.raises(SystemExit) as err:
            block_contact.main([*bad, "--out", str(tmp_path)])
        assert err.value.code == 2
    err = capsys.readouterr().err
    assert "station_friction must be" in err and "--margins: station_margin must be" in err
    assert "--bodies: a body is FRONT/BACK/SIDE" in err and "--bodies: body_front, body_back" in err
    assert "--world: " in err and "'icy'" in err


def test_the_walk_runs_in_the_world_named(tmp_path, monkeypatch):
    """``--world slippery`` walks the slippery robot (its model written under OUT/models):
    the one case's physics end differs from the shipped robot's, and the report names the
    world."""
    pose = (458.0, 262.0, 45.0)
    monkeypatch.setattr(block_contact, "POSE_SETS", {"tiny": ([pose], (0,))})
    assert block_contact.main(["--frictions", "0.5", "--cycles", "2", "--world", "slippery",
                               "--out", str(tmp_path)]) == 0  # fmt: skip
    doc = json.loads((tmp_path / "block_contact.json").read_text())
    assert doc["world"] == "slippery" and "physics world `slippery`" in (
        tmp_path / "block_contact.md").read_text()
    model = tmp_path / "models" / "slippery.xml"
    slippery = block_contact.walk_physics([pose], [0], 2, model=model,
                                          arena=block_contact.resolve_worlds(["slippery"])[0].arena)
    shipped = block_contact.walk_physics([pose], [0], 2)
    assert slippery[pose, 0][0] == pytest.approx(shipped[pose, 0][0], abs=1e-6)  # same start
    assert slippery[pose, 0][-1] != pytest.approx(shipped[pose, 0][-1], abs=0.05)
