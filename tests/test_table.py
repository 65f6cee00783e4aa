"""Gait tables: Figure 4 built in, calibration files round-trip, malformed files are rejected."""

import json

import numpy as np
import pytest

from evolve.table import (
    PAPER_TABLE,
    GaitTableError,
    load_table,
    table_from_json,
    table_to_json,
    validate_table,
)
from infra.io import atomic_write_json


def test_paper_table_matches_figure4_spot_values():
    # Hand-copied from the paper's Figure 4, independent of the literal in evolve/table.py.
    assert tuple(PAPER_TABLE[3]) == (8.4, -4.3, -15.8)
    assert tuple(PAPER_TABLE[11]) == (5.3, 4.0, 16.7)
    assert tuple(PAPER_TABLE[15]) == (-12.4, 0.5, -1.8)
    assert tuple(PAPER_TABLE[7]) == (0.0, 0.0, 0.0)
    # Left gaits turn left (dH < 0), right gaits right, sharper with the number.
    assert np.all(np.diff(PAPER_TABLE[0:7, 2]) < 0)
    assert np.all(np.diff(PAPER_TABLE[8:15, 2]) > 0)


def test_paper_table_is_read_only():
    with pytest.raises(ValueError):
        PAPER_TABLE[0, 0] = 1.0


def test_calibration_file_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    values = PAPER_TABLE + rng.normal(0, 0.1, PAPER_TABLE.shape)
    std = np.abs(rng.normal(0, 0.1, PAPER_TABLE.shape))
    path = atomic_write_json(tmp_path / "gait_table.json", table_to_json(values, std, cycles=7))
    table = load_table(path)
    np.testing.assert_array_equal(table.values, values)
    np.testing.assert_array_equal(table.std, std)
    assert json.loads(path.read_text())["gaits"][4]["cycles"] == 7


def test_load_paper_by_name():
    np.testing.assert_array_equal(load_table("paper").values, PAPER_TABLE)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["gaits"].pop(5), r"missing gaits \[5\]"),
        (lambda d: d["gaits"].append(dict(d["gaits"][0])), "gait 0 appears twice"),
        (lambda d: d["gaits"][2].pop("dH"), "row 2 is malformed"),
        (lambda d: d["gaits"][3].update(gait=16), "outside 0-15"),
        (lambda d: d.update(robot="khepera"), "robot 'khepera'"),
        (lambda d: d.update(units={"F": "m", "T": "m", "dH": "rad"}), "units"),
        (lambda d: d["gaits"][1].update(F=float("nan")), "gait 1 has a non-finite F"),
        (lambda d: d.pop("gaits"), "no 'gaits' list"),
    ],
)
def test_malformed_files_are_rejected_with_the_problem_named(mutate, message):
    doc = table_to_json(PAPER_TABLE)
    mutate(doc)
    with pytest.raises(GaitTableError, match=message):
        table_from_json(doc)


def test_wrong_shape_and_bad_json(tmp_path):
    with pytest.raises(GaitTableError, match=r"shape \(16, 3\)"):
        validate_table(np.zeros((15, 3)))
    bad = tmp_path / "t.json"
    bad.write_text("{not json")
    with pytest.raises(GaitTableError, match="not valid JSON"):
        load_table(bad)
    with pytest.raises(GaitTableError, match="no such gait-table file"):
        load_table(tmp_path / "missing.json")


def test_atomic_write_keeps_old_file_when_writer_fails(tmp_path):
    from infra.io import atomic_write

    path = tmp_path / "out.txt"
    path.write_text("old")

    def failing(p):
        p.write_text("half")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write(path, failing)
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]
