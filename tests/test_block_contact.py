"""The station block's rules against physics (servobot.robustness.block_contact)."""

from __future__ import annotations

import json
import math

import pytest

from evolve.geometry import wrap180
from evolve.table import PAPER_TABLE
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


def test_the_command_writes_its_report_and_refuses_bad_settings(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(block_contact, "POSE_SETS", {"tiny": ([(458.0, 262.0, 45.0)], (0,))})
    args = ["--frictions", "0,0.5", "--cycles", "2", "--out", str(tmp_path)]
    assert block_contact.main(args) == 0
    doc = json.loads((tmp_path / "block_contact.json").read_text())
    assert set(doc["sets"]["tiny"]["rules"]) == {"cancel", "slide 0", "slide 0.5"}
    assert (tmp_path / "block_contact.png").stat().st_size > 0
    for bad in (["--frictions", "half"], ["--frictions", "-1"], ["--cycles", "0"]):
        with pytest.raises(SystemExit) as err:
            block_contact.main([*bad, "--out", str(tmp_path)])
        assert err.value.code == 2
    assert "station_friction must be" in capsys.readouterr().err
