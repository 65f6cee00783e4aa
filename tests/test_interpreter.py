"""Geometry (SPEC §1, §3) and the reference interpreter (SPEC §4) on hand-worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from chromosome_text import STILL, B, G, chrom, gene

from evolve import geometry as geo
from evolve.codec import TEST_MASKS
from evolve.interpreter import (
    END_BRANCH_LIMIT,
    END_DOCKED,
    END_KILL_ZONE,
    END_POWER_EMPTY,
    END_STEP_LIMIT,
    StepEvent,
    run,
)
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from evolve.world import TableWorld

COST = 0.0209
ZERO_TABLE = np.zeros((16, 3))
"""Gaits that do not move: control flow and power alone."""


def trace(bits, pose, *, mode="coverage", table=ZERO_TABLE, **kw):
    events: list[StepEvent] = []
    res = run(bits, TableWorld(table, *pose), mode=mode, on_event=events.append, **kw)
    return res, events


def gaits(events):
    return [e for e in events if e.kind == "gait"]


# ----------------------------------------------------------------------------- geometry


def test_motion_formula_by_hand() -> None:
    # Heading 90 (east): forward is +x, a right (positive) sideways step is −y.
    assert geo.apply_gait(100, 100, 90, 10, 2, 5) == pytest.approx((110, 98, 95), abs=1e-12)
    # Heading 0 (north): forward is +y, right is +x.
    assert geo.apply_gait(100, 100, 0, 10, 2, -5) == pytest.approx((102, 110, 355), abs=1e-12)
    # Heading 30, gait 15 of the paper: F −12.4, T 0.5, dH −1.8.
    s, c = 0.5, math.sqrt(3) / 2
    want = (200 + (-12.4 * s + 0.5 * c), 200 + (-12.4 * c - 0.5 * s), 28.2)
    assert geo.apply_gait(200, 200, 30, -12.4, 0.5, -1.8) == pytest.approx(want, abs=1e-12)
    assert geo.apply_gait(0, 0, 358, 0, 0, 5)[2] == pytest.approx(3.0)


def test_light_cones_and_dark_area() -> None:
    assert geo.lit(300, 250) == (True, True)
    assert geo.lit(100, 250) == (True, True)
    assert geo.lit(490, 30) == (False, False)  # south-east corner: dark
    assert geo.lit(490, 470) == (False, False)  # north-east corner: dark
    # Edge of source 0's cone: direction 210° (60° off west) from (500, 235).
    for off, want in ((-1.0, True), (1.0, False)):
        a = math.radians(210 - off)
        x, y = 500 + 100 * math.sin(a), 235 + 100 * math.cos(a)
        assert geo.lit(x, y)[0] is want
        assert geo.lit(x, y)[1] is False  # the other source is further off


@pytest.mark.parametrize(
    ("pose", "want"),
    [
        ((300, 250, 90), (True, True)),  # sources at ±4.3° relative
        ((300, 250, 130), (True, False)),  # sources at −35.7° and −44.3°
        ((300, 250, 50), (False, True)),  # sources at +44.3° and +35.7°
        ((300, 250, 270), (False, False)),  # facing away
        ((490, 30, 0), (False, False)),  # dark: even facing the light it sees nothing
    ],
)
def test_light_sensors(pose, want) -> None:
    assert geo.light_sensors(*pose) == want


@pytest.mark.parametrize(
    ("pose", "want"),
    [
        ((250, 470, 0), (True, True)),  # north wall 30 ahead
        ((250, 470, 90), (True, False)),  # wall 50° off the left span: 50·cos 50° = 32.1 ≥ 30
        ((250, 460, 90), (False, False)),  # 40 > 32.1
        ((250, 470, 270), (False, True)),
        ((250, 440, 0), (False, False)),  # 60 > 50
        ((250, 450, 0), (True, True)),  # exactly 50
        ((30, 250, 270), (True, True)),  # west wall
        ((470, 30, 135), (True, True)),  # south-east corner, both walls in reach
    ],
)
def test_object_sensors(pose, want) -> None:
    assert geo.object_sensors(*pose) == want


def test_squares_contact_zone_and_inner() -> None:
    assert geo.square_index(75, 125) == 1 + 10 * 2
    assert geo.square_index(94, 144) == 21  # |dx| = |dy| = 19: still inside
    assert geo.square_index(94.01, 125) == -1
    assert geo.square_index(70, 100) == -1  # on a square border
    assert geo.square_index(475, 25) == 9
    assert geo.is_inner(21) and geo.is_inner(11) and geo.is_inner(88)
    assert not (geo.is_inner(0) or geo.is_inner(9) or geo.is_inner(89) or geo.is_inner(95))
    assert sum(geo.is_inner(k) for k in range(100)) == 64


def test_kill_zone_and_docking_rule() -> None:
    assert geo.in_kill_zone(24.9, 250) and geo.in_kill_zone(250, 475.1)
    assert not geo.in_kill_zone(25, 250) and not geo.in_kill_zone(475, 475)
    assert geo.is_docked(455, 250, 90) and geo.is_docked(460, 280, 60)
    assert geo.is_docked(460, 220, 120)
    assert not geo.is_docked(454.9, 250, 90)
    assert not geo.is_docked(460, 280.1, 90)
    assert not geo.is_docked(460, 250, 121) and not geo.is_docked(460, 250, 59)


# --------------------------------------------------------------------------- interpreter


def test_each_loop_count_and_section_wrap() -> None:
    bits = chrom(
        gene("01", G(0), G(0), G(0), G(0)),
        gene("10", G(1), G(1), G(1), G(1)),
        gene("11", G(2), G(2), G(2), G(2)),
        *[gene("01", G(3 + g), G(3 + g), G(3 + g), G(3 + g)) for g in range(5)],
    )
    res, ev = trace(bits, (250, 250, 0), start_power=100.0, max_steps=80)
    seq = [e.gene for e in gaits(ev)]
    want = [0] * 4 + [1] * 8 + [2] * 12 + [g for g in range(3, 8) for _ in range(4)]
    assert seq[: len(want)] == want
    assert seq[len(want) : len(want) + 4] == [0] * 4  # coverage section wraps 7 → 0, not to 8
    assert res.end == END_STEP_LIMIT and res.steps == 80


def test_forever_gene_repeats() -> None:
    bits = chrom(gene("00", G(1), G(2), G(3), G(4)), gene("01", G(9), G(9), G(9), G(9)))
    _, ev = trace(bits, (250, 250, 0), start_power=100.0, max_steps=40)
    assert [e.gait for e in gaits(ev)] == [1, 2, 3, 4] * 10


# Poses on the zero table and their active sensors, worked out by hand (see geometry tests).
SENSOR_CASES = [
    ((250, 250, 270), 4.5, 0),
    ((250, 470, 270), 4.5, 1),  # object-right
    ((30, 250, 270), 4.5, 1 | 2),  # both object
    ((250, 250, 270), 3.9, 4),  # low power
    ((300, 250, 50), 4.5, 8),  # light-right
    ((300, 250, 130), 4.5, 16),  # light-left
    ((300, 250, 90), 4.5, 8 | 16),  # both light
    ((460, 250, 90), 3.9, 1 | 2 | 4 | 8 | 16),  # at the station, low: everything
]


@pytest.mark.parametrize(("pose", "power", "active"), SENSOR_CASES)
@pytest.mark.parametrize("test", range(8))
def test_each_sensor_test(pose, power, active, test) -> None:
    bits = chrom(
        gene("00", B(test, 2), G(1), G(1), G(1)),
        STILL,
        gene("00", G(2), G(2), G(2), G(2)),
        *[STILL] * 5,
        gene("00", G(8), G(8), G(8), G(8)),
    )
    _, ev = trace(bits, pose, start_power=power, max_steps=1)
    assert ev[0].kind == "branch" and ev[0].sensors == active
    taken = TEST_MASKS[test] & active == TEST_MASKS[test]
    assert ev[0].text.endswith("taken") and ("not taken" not in ev[0].text) is taken
    first = gaits(ev)[0]
    if not taken:
        assert (first.gene, first.gait) == (0, 1)
    elif test == 4:
        assert (first.gene, first.gait, first.mode) == (8, 8, "navigation")
    else:
        assert (first.gene, first.gait) == (2, 2)


def test_branch_limit_32() -> None:
    neg = B(1, 0)  # object-right: negative in the open
    genes = [gene("01", neg, neg, neg, neg)] * 7
    res, ev = trace(chrom(*genes, gene("01", neg, neg, neg, neg)), (250, 250, 270))
    assert res.end == END_BRANCH_LIMIT and res.steps == 0
    assert sum(e.kind == "branch" for e in ev) == 32
    # 31 branches and a gait: the count restarts, the run goes on to the step limit.
    res, _ = trace(chrom(*genes, gene("01", neg, neg, neg, G(7))), (250, 250, 270), max_steps=9)
    assert res.end == END_STEP_LIMIT and res.steps == 9
    # An always-taken branch to itself.
    res, ev = trace(chrom(gene("00", B(0, 0), G(1), G(1), G(1))), (250, 250, 270))
    assert res.end == END_BRANCH_LIMIT and len(ev) == 33  # 32 branches + end


def test_low_power_switches_to_gene_8_whatever_the_target() -> None:
    bits = chrom(
        gene("00", G(0), B(4, 3), G(0), G(0)),
        *[gene("00", G(5), G(5), G(5), G(5))] * 7,
        gene("00", G(1), G(1), G(1), G(1)),
    )
    _, ev = trace(bits, (250, 250, 0), start_power=4.05, max_steps=6)
    g = gaits(ev)
    assert [(e.gene, e.gait) for e in g] == [(0, 0)] * 4 + [(8, 1)] * 2
    assert g[3].power == pytest.approx(4.05 - 4 * COST) and g[3].power < 4.0
    branches = [e for e in ev if e.kind == "branch"]
    assert branches[0].text == "if low-power goto 8: not taken"  # 4.0291 V
    assert branches[1].text == "if low-power goto 8: taken"
    assert g[4].mode == "navigation" and g[0].mode == "coverage"


def test_navigation_branches_target_8_plus_t() -> None:
    bits = chrom(
        gene("00", B(4, 0), G(0), G(0), G(0)),
        *[STILL] * 7,
        gene("00", B(0, 5), G(1), G(1), G(1)),
        *[STILL] * 4,
        gene("00", G(3), B(0, 0), G(4), G(4)),
    )
    _, ev = trace(bits, (250, 250, 0), start_power=3.9, max_steps=2)
    assert [(e.gene, e.gait) for e in gaits(ev)] == [(13, 3), (13, 3)]
    assert [e.text for e in ev if e.kind == "branch"] == [
        "if low-power goto 8: taken",
        "if always goto 13: taken",
        "if always goto 8: taken",
        "if always goto 13: taken",
    ]
    # The same section run alone in navigation mode: targets are used as is.
    nav = chrom(
        gene("00", B(0, 5), G(1), G(1), G(1)), *[STILL] * 4, gene("01", G(3), G(3), G(3), G(3)), n=8
    )
    _, ev = trace(nav, (250, 250, 0), mode="navigation", max_steps=1)
    assert (gaits(ev)[0].gene, gaits(ev)[0].gait) == (5, 3)


def test_docking_charging_routine_then_gene_0() -> None:
    table = PAPER_TABLE.copy()
    bits = chrom(
        gene("00", B(4, 0), G(7), G(9), G(9)),
        *[STILL] * 7,
        gene("00", G(7), G(7), G(7), G(7)),
    )
    res, ev = trace(bits, (460, 250, 90), table=table, start_power=3.9, max_steps=7)
    kinds = [(e.kind, e.gene, e.gait) for e in ev]
    assert kinds[:7] == [
        ("branch", 0, -1),  # low power: go to gene 8
        ("gait", 8, 7),  # gait 7 at the station: docked
        ("charge", -1, -1),
        *[("gait", -1, 15)] * 4,
    ]
    assert ev[2].power == 5.0 and ev[2].text == "charging: 5.0 V, 4× gait 15"
    pose = (460.0, 250.0, 90.0)
    for e in ev[3:7]:
        pose = geo.apply_gait(*pose, *PAPER_TABLE[15])
        assert e.mode == "charging" and e.pose == pytest.approx(pose, abs=1e-12)
    after = 5.0 - COST - COST - COST - COST
    assert ev[6].power == pytest.approx(after, abs=1e-15)
    assert (ev[7].kind, ev[7].gene, ev[7].text) == ("branch", 0, "if low-power goto 8: not taken")
    assert (ev[8].kind, ev[8].gene, ev[8].gait, ev[8].power) == ("gait", 0, 7, ev[6].power)
    assert res.docks == 1 and res.steps == 7 and res.end == END_STEP_LIMIT


def test_no_docking_check_during_the_charging_routine() -> None:
    table = ZERO_TABLE  # backing up does not move: the robot stays on the dock
    bits = chrom(gene("00", B(4, 0), G(7), G(7), G(7)), *[STILL] * 7, STILL)
    res, ev = trace(bits, (460, 250, 90), table=table, start_power=3.9, max_steps=30)
    assert res.docks == 1 and sum(e.kind == "charge" for e in ev) == 1
    assert res.steps == 30 and res.end == END_STEP_LIMIT


def test_charging_routine_can_end_in_the_kill_zone() -> None:
    table = ZERO_TABLE.copy()
    table[15] = (0.0, -60.0, 0.0)  # backing up steps 60 left: facing east, that is north
    bits = chrom(gene("00", B(4, 0), G(7), G(7), G(7)))
    res, ev = trace(bits, (460, 250, 90), table=table, start_power=3.9)
    # Backup poses y = 310, 370, 430 reach squares (9, 6), (9, 7), (9, 8); y = 490 is in
    # square (9, 9)'s contact zone but also in the kill zone: not counted.
    assert res.end == END_KILL_ZONE and res.steps == 5 and res.docks == 1
    assert res.reached == frozenset({69, 79, 89})
    assert ev[-1].mode == "charging" and ev[-2].pose == pytest.approx((460, 490, 90))


def test_dock_only_in_navigation_section() -> None:
    res, _ = trace(chrom(STILL), (460, 250, 90), start_power=4.5, max_steps=5)
    assert res.docks == 0 and res.end == END_STEP_LIMIT


def test_navigation_mode_docking_ends_the_run() -> None:
    res, ev = trace(chrom(STILL, n=8), (460, 250, 90), mode="navigation", table=PAPER_TABLE)
    assert res.end == END_DOCKED and res.steps == 1 and res.docks == 1
    assert ev[-1].kind == "end" and ev[-1].text == "end: docked"


def test_kill_zone_ends_and_square_not_counted() -> None:
    # Start in square (0, 1)'s contact zone at x = 30; gait 0 walks west into x ≈ 18.4, which is
    # in the same contact zone but also in the kill zone.
    bits = chrom(gene("00", G(0), G(0), G(0), G(0)))
    res, ev = trace(bits, (30, 75, 270), table=PAPER_TABLE)
    assert res.end == END_KILL_ZONE and res.steps == 1
    assert res.squares == 0 and res.reached == frozenset()
    assert geo.square_index(*res.final_pose[:2]) == 10  # square (0, 1)
    assert res.track.shape == (2, 3) and tuple(res.track[0]) == (30.0, 75.0, 270.0)


def test_power_empty_ends_and_gait_7_is_free() -> None:
    res, ev = trace(chrom(gene("00", G(0), G(0), G(0), G(0))), (250, 250, 0), start_power=2.75)
    assert res.end == END_POWER_EMPTY and res.steps == 3  # 2.7291, 2.7082, 2.6873 < 2.7
    assert gaits(ev)[-1].power == pytest.approx(2.75 - 3 * COST)
    res, ev = trace(chrom(STILL), (250, 250, 0), start_power=2.71, max_steps=50)
    assert res.end == END_STEP_LIMIT and res.steps == 50
    assert {e.power for e in ev} == {2.71}


def test_step_limit_defaults() -> None:
    res, _ = trace(chrom(STILL), (250, 250, 0))
    assert (res.end, res.steps) == (END_STEP_LIMIT, 600)
    res, _ = trace(chrom(STILL, n=8), (250, 250, 0), mode="navigation")
    assert (res.end, res.steps) == (END_STEP_LIMIT, 100)


def test_squares_counted_once_with_inner() -> None:
    # Walk north along x = 75 (column 1) with a table whose gait 0 is 25 straight ahead.
    table = ZERO_TABLE.copy()
    table[0] = (25.0, 0.0, 0.0)
    res, ev = trace(chrom(gene("00", G(0), G(0), G(0), G(0))), (75, 50, 0), table=table)
    # Poses y = 75, 100, 125, ..., 450, then 475 (reaches square (1, 9)), then 500: kill zone.
    assert res.end == END_KILL_ZONE
    assert res.reached == frozenset(1 + 10 * j for j in range(1, 10))
    assert res.squares == 9 and res.inner_squares == 8
    assert [e.new_square for e in gaits(ev)][:3] == [11, -1, 21]


def test_bad_mode_and_gene_count() -> None:
    with pytest.raises(ValueError, match="mode"):
        run(chrom(STILL), TableWorld(ZERO_TABLE, 250, 250, 0), mode="walk")
    with pytest.raises(ValueError, match="16-gene"):
        run(chrom(STILL, n=8), TableWorld(ZERO_TABLE, 250, 250, 0), mode="coverage")


def test_other_world_settings_are_honoured() -> None:
    world = WorldSettings(kill_margin=60.0)
    bits = chrom(gene("00", G(0), G(0), G(0), G(0)))
    res = run(bits, TableWorld(PAPER_TABLE, 80, 250, 270, world), mode="coverage", settings=world)
    assert res.end == END_KILL_ZONE and res.steps == 2  # x ≈ 68.4, then 56.8 < 60
