"""Energy per gait from physics and the power models: the servo model against hand-worked
values, standing costs less than walking, ½CV², the gait table's energy columns, and the
``table`` power model in the kernel and the interpreter (``paper`` costs as a table reproduce
the paper model bit for bit)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from calibration.energy import HS311, ServoDatasheet, reference_voltage, voltage_drop
from calibration.measure import measure_gaits
from evolve import evaluate
from evolve.interpreter import END_POWER_EMPTY, run
from evolve.settings import WorldSettings, with_table_power
from evolve.table import (
    PAPER_TABLE,
    GaitTable,
    GaitTableError,
    load_table,
    table_to_json,
    with_power_model,
)
from evolve.world import TableWorld
from servobot.cli import main as servobot

WORLD = WorldSettings()
PAPER_AS_TABLE = with_table_power(WORLD, [0.0 if g == 7 else 0.0209 for g in range(16)])
"""The paper's costs written as a table: 0.0209 V for every gait but gait 7, which the paper
charges nothing (the table model charges gait 7 its own measured dV)."""


def test_servo_model_hand_worked() -> None:
    s = ServoDatasheet(supply_v=5.0, stall_torque_nm=0.5, no_load_speed_rad_s=10.0,
                       idle_current_a=0.01)  # fmt: skip
    assert s.motor_constant == pytest.approx(0.5)  # 5 V / 10 rad/s
    assert s.resistance_ohm == pytest.approx(5.0)  # 5 V * 0.5 / 0.5 N·m: stall current 1 A
    idle = 5.0 * 0.01
    # at stall the supply gives V * I_stall; at no load and full speed only the idle current
    assert s.power_w(np.array(0.5), np.array(0.0)) == pytest.approx(idle + 5.0)
    assert s.power_w(np.array(0.0), np.array(10.0)) == pytest.approx(idle)
    # half torque at half speed: copper 5 * 0.5² = 1.25 W + mechanical 0.25 * 5 = 1.25 W
    assert s.power_w(np.array(0.25), np.array(5.0)) == pytest.approx(idle + 2.5)
    # back-driven hard: no energy flows back into the capacitors
    assert s.power_w(np.array(0.1), np.array(-10.0)) == pytest.approx(idle)
    with pytest.raises(ValueError, match="stall_torque_nm"):
        ServoDatasheet(stall_torque_nm=0.0)


def test_hs311_datasheet_values() -> None:
    assert HS311.stall_torque_nm == pytest.approx(0.2942, abs=1e-4)  # 3.0 kg·cm
    assert HS311.no_load_speed_rad_s == pytest.approx(math.radians(60) / 0.19)
    assert HS311.supply_v / HS311.resistance_ohm == pytest.approx(0.338, abs=1e-3)


def test_voltage_drop_empties_the_bank_in_as_many_cycles_as_half_cv_squared() -> None:
    energy = 12.0  # J per cycle
    dv = float(voltage_drop(energy, WORLD))
    cycles_linear = (WORLD.charged_power_v - WORLD.empty_power_v) / dv
    half_cv2 = 0.5 * WORLD.capacitance_f * (WORLD.charged_power_v**2 - WORLD.empty_power_v**2)
    assert cycles_linear == pytest.approx(half_cv2 / energy)
    assert reference_voltage(WORLD) == pytest.approx(3.85)


@pytest.fixture(scope="module")
def measured() -> tuple[np.ndarray, np.ndarray]:
    return measure_gaits(gaits=(0, 7, 6, 15), cycles=2, seed=2)


def test_standing_costs_less_than_walking_but_more_than_idling(measured) -> None:
    values, std = measured
    energy = values[:, 3]
    idle_j = 12 * HS311.supply_v * HS311.idle_current_a * 1.6  # 12 servos, one 1.6 s cycle
    for g in (0, 6, 15):
        assert energy[7] < 0.5 * energy[g]
        assert std[g, 3] > 0.0  # servo noise: a real per-cycle spread
    assert energy[7] > idle_j  # the lift servos hold the body up


def test_energy_columns_round_trip_through_the_table_file(tmp_path) -> None:
    energy = np.column_stack(
        [np.arange(16.0), np.full(16, 0.1), np.arange(16.0) / 600, np.zeros(16)]
    )
    doc = table_to_json(PAPER_TABLE, energy=energy, cycles=3)
    assert set(doc["gaits"][5]) >= {"energy_J", "energy_J_std", "dV", "dV_std"}
    path = tmp_path / "t.json"
    path.write_text(json.dumps(doc))
    table = load_table(path)
    np.testing.assert_array_equal(table.energy, energy)
    np.testing.assert_array_equal(table.dv, energy[:, 2])
    assert load_table("paper").dv is None
    doc["gaits"][3]["dV"] = -1.0
    path.write_text(json.dumps(doc))
    with pytest.raises(GaitTableError, match="finite and >= 0"):
        load_table(path)
    del doc["gaits"][4]["dV"]
    path.write_text(json.dumps(doc))
    with pytest.raises(GaitTableError, match="row 4 is malformed"):
        load_table(path)


def test_power_model_choice_and_bad_settings() -> None:
    paper = load_table("paper")
    assert with_power_model(WORLD, "paper", paper).gait_costs_v() == PAPER_AS_TABLE.gait_costs_v()
    with pytest.raises(GaitTableError, match="needs a gait table with measured dV"):
        with_power_model(WORLD, "table", paper)
    with pytest.raises(ValueError, match="needs gait_dv"):
        dataclasses.replace(WORLD, power_model="table").gait_costs_v()
    with pytest.raises(ValueError, match="must be 'paper' or 'table'"):
        dataclasses.replace(WORLD, power_model="battery").gait_costs_v()
    with pytest.raises(ValueError, match="gaits \\[2\\]"):
        with_table_power(WORLD, [0.02] * 2 + [float("nan")] + [0.02] * 13).gait_costs_v()


def _random_population(seed: int, n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    genomes = rng.integers(0, 2, size=(n, 16, 30), dtype=np.uint8)
    starts = np.column_stack([rng.uniform(350, 450, 3), rng.uniform(175, 325, 3),
                              rng.uniform(0, 360, 3)])  # fmt: skip
    return genomes, starts


def _outputs(ev) -> tuple[np.ndarray, ...]:
    return ev.squares, ev.inner_squares, ev.steps, ev.docks, ev.end, ev.final_pose


def test_table_power_with_the_paper_costs_reproduces_the_paper_bit_for_bit() -> None:
    genomes, starts = _random_population(21)
    for mode in ("coverage", "navigation"):
        g = genomes if mode == "coverage" else genomes[:, :8]
        a = evaluate(g, starts, table=PAPER_TABLE, mode=mode, settings=WORLD)
        b = evaluate(g, starts, table=PAPER_TABLE, mode=mode, settings=PAPER_AS_TABLE)
        for x, y in zip(_outputs(a), _outputs(b), strict=True):
            np.testing.assert_array_equal(x, y)
    for i in range(40):  # the interpreter too, the power after every event included
        seen = []
        for w in (WORLD, PAPER_AS_TABLE):
            powers: list[float] = []
            r = run(genomes[i], TableWorld(PAPER_TABLE, *starts[0], w), mode="coverage",
                    settings=w, on_event=lambda e, p=powers: p.append(e.power))  # fmt: skip
            seen.append((r.squares, r.steps, r.docks, r.end, r.final_pose, powers))
        assert seen[0] == seen[1]


def test_kernel_equals_interpreter_under_measured_costs() -> None:
    rng = np.random.default_rng(4)
    world = with_table_power(WORLD, rng.uniform(0.0, 0.06, 16))
    genomes, starts = _random_population(22, n=150)
    ev = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage", settings=world)
    for i in range(genomes.shape[0]):
        for s in range(starts.shape[0]):
            r = run(genomes[i], TableWorld(PAPER_TABLE, *starts[s], world), mode="coverage",
                    settings=world)  # fmt: skip
            got = (ev.squares[i, s], ev.steps[i, s], ev.docks[i, s], ev.end[i, s])
            assert got == (r.squares, r.steps, r.docks, r.end), (i, s)


def test_costlier_gaits_empty_the_bank_sooner() -> None:
    genomes, starts = _random_population(23)
    cheap = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage", settings=WORLD)
    dear = evaluate(genomes, starts, table=PAPER_TABLE, mode="coverage",
                    settings=with_table_power(WORLD, [0.05] * 16))  # fmt: skip
    assert (dear.end == END_POWER_EMPTY).sum() > (cheap.end == END_POWER_EMPTY).sum()
    assert dear.steps.sum() < cheap.steps.sum()


def test_evolve_cli_power_table(tmp_path, capsys) -> None:
    energy = np.column_stack([np.full(16, 10.0), np.zeros(16), np.full(16, 0.03), np.zeros(16)])
    path = tmp_path / "gait_table.json"
    path.write_text(json.dumps(table_to_json(PAPER_TABLE, energy=energy)))
    tiny = ["--populations", "1", "--population-size", "4", "--generations", "1", "--no-progress"]
    out = tmp_path / "run"
    args = ["evolve", "navigation", *tiny, "--out", str(out), "--table", str(path)]
    assert servobot([*args, "--power", "table"]) == 0
    saved = json.loads((out / "navigation" / "settings.json").read_text())["WorldSettings"]
    assert saved["power_model"] == "table" and saved["gait_dv"] == [0.03] * 16
    paper = ["evolve", "navigation", *tiny, "--out", str(tmp_path / "p"), "--power", "table"]
    assert servobot(paper) == 2  # the paper's table has no measured dV
    assert "needs a gait table with measured dV" in capsys.readouterr().err


def test_gait_table_dataclass_has_no_energy_by_default() -> None:
    assert GaitTable(PAPER_TABLE.copy()).dv is None


def test_retest_finalists_under_costlier_gaits(tmp_path, capsys) -> None:
    from evolve.codec import write_chromosome
    from evolve.retest import main, retest

    rng = np.random.default_rng(5)
    (tmp_path / "coverage").mkdir()
    for k in range(3):
        write_chromosome(tmp_path / "coverage" / f"best_pop{k}.txt",
                         rng.integers(0, 2, size=(16, 30), dtype=np.uint8))  # fmt: skip
    paper = load_table("paper")
    cheap = retest(tmp_path, paper, WORLD, starts=30)
    dear = retest(tmp_path, paper, with_table_power(WORLD, [0.06] * 16), starts=30)
    assert [r["finalist"] for r in cheap] == ["best_pop0", "best_pop1", "best_pop2"]
    assert sum(r["power_empty"] for r in dear) > sum(r["power_empty"] for r in cheap)
    assert sum(r["squares"] for r in dear) < sum(r["squares"] for r in cheap)
    assert main([str(tmp_path), "--starts", "30"]) == 0
    assert "mean inner coverage" in capsys.readouterr().out
    assert main([str(tmp_path), "--power", "table"]) == 2  # the paper's table has no dV
