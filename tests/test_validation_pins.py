"""The files a validation writes, pinned: ``report.json``, ``report.md``, ``tracks.npz`` and
``settings.json`` of short lone (coverage, navigation with start powers, a run whose physics
blows up) and colony validations hash to what the code wrote before the lone and the colony
validation shared one path (issue 18 §4). Wall times are left out of the hashes (they differ
from run to run), and so is the npz's zip framing (it stamps the time): its arrays are hashed.

The pins were made with the MuJoCo and NumPy versions in ``MADE_WITH``; physics results may
differ in their last bits under others, so the test is skipped there. To pin new outputs on
purpose: ``python3 tests/test_validation_pins.py`` prints the digests.
"""

from __future__ import annotations

import hashlib
import json
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER

from evolve.codec import parse_chromosome
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from infra.executors import SerialExecutor
from servo_mj.robot.bot import PhysicsError
from servo_mj.world import physics_world
from servobot.validation.colony import validate_colony
from servobot.validation.lone import validate

MADE_WITH = {"mujoco": "3.17.0", "numpy": "2.4.6"}
FILES = ("report.json", "report.md", "tracks.npz", "settings.json")
TRACK_DECIMALS = 4
"""Decimals (cm, deg) of the hashed track poses: MuJoCo's last bits differ between CPUs of one
build (the navigation case's 15-step physics track differed in its last bits between two
x86-64 machines with the same MuJoCo and NumPy while its report was identical)."""
GENE_8 = "01 0100000 0100000 0100000 0100000\n"
BITS = parse_chromosome(GENE_8 * 16)
STARTS = np.array([[400.0, 200.0, 300.0], [300.0, 300.0, 45.0]])
SECTION = parse_chromosome(LIGHT_FOLLOWER)
COLONY_STARTS = np.array([[[440.0, 235.0, 90.0], [440.0, 266.0, 90.0]],
                          [[300.0, 300.0, 45.0], [200.0, 250.0, 180.0]]])  # fmt: skip
LOW = WorldSettings(start_power_v=3.95)

PINS = {
    # lone and blow_up report.json re-pinned in issue 16 (forty-fifth session): coverage records
    # gained ``handoffs`` (here empty); with that key left out they hash to the earlier pins
    "lone": {
        "report.json": "25780bc52a77b3bebf71505060c2bd3c11a33613f53f70a1168d9a8a5b28b8af",
        "report.md": "2a3ff3773fffbfc7b404a8d54b0b3c43b93af0a18d45384308e43b78e81b14eb",
        "tracks.npz": "53bca2cb309cafcb41db219092e09c6fadc43020934378833043696e4704408c",
        "settings.json": "17a4acf8ea0920f3d5ee1e784b108b3f91374c5faf340c9f3805355ef6468964",
    },
    "navigation": {
        "report.json": "b7eef16b7501813ec703ba454e3d4e8f51089a5f052f0bde147b2636a5d0fb39",
        "report.md": "781894143afdea571c1d5f71fb09488d72fe721a1d29cb8406a45e2a8aedec17",
        "tracks.npz": "c82f7837246a60465bbd5d3c5eccc32a128c35850936744ba79d8e4ed4badace",
        "settings.json": "5469e7a5c82543955942503f5f64a7c5b8b9f2112e752d61c51a0b44e7c4e139",
    },
    "blow_up": {
        "report.json": "bc55a5a9c109f8546379434abb23774412147d0beab7e22d382a26e5d058594a",
        "report.md": "1a83ff477ba34300bb7b9d98c93b9feae532e44a30ca35effd68670da40e7c5c",
        "tracks.npz": "cf3f4e37c5320735a228ef46f80fabcb4042df44a4bb774a5a1499fa7c709d24",
        "settings.json": "efa80b1a883e24bd0ee7ee5b00507686550ba4d41743db192448886e62f4a8c2",
    },
    # re-pinned in issue 17: the colony reports gained live_at_end_per_run, then ends_at_station
    # (nothing else moved)
    "colony": {
        "report.json": "7a0c6101a5c0ea814a76d4483da31d5c99695f1864dc6e81201e95e5113efb8a",
        "report.md": "0f9c86a3c4acb0d9e7fe5441846a4dae6c595fa7a2f43b372c5dea2ae62cfeac",
        "tracks.npz": "b412e55daefe102968990baba6507a56a2af4d9a5579957d6b062ce0d05d792c",
        "settings.json": "3759159297c235eb2b9c7605fb198edd95921b4b0d89f23caf8684ffa73f2d56",
    },
}


def _no_wall(obj: Any) -> Any:
    """``obj`` without its wall times (keys ``wall_s`` and ``mean_wall_s``)."""
    if isinstance(obj, dict):
        return {k: _no_wall(v) for k, v in obj.items() if k not in ("wall_s", "mean_wall_s")}
    if isinstance(obj, list):
        return [_no_wall(v) for v in obj]
    return obj


def digest(path: Path) -> str:
    """sha256 of a written file, its wall times left out (JSON: the keys, kept in their order;
    Markdown: the numbers; npz: each array's name, dtype, shape and bytes, in file order, the
    poses rounded to ``TRACK_DECIMALS`` as the report rounds its final poses)."""
    if path.suffix == ".npz":
        h = hashlib.sha256()
        with np.load(path) as npz:
            for name in npz.files:
                arr = npz[name]
                h.update(f"{name} {arr.dtype.str} {arr.shape}\n".encode())
                h.update(np.ascontiguousarray(np.round(arr, TRACK_DECIMALS)).tobytes())
        return h.hexdigest()
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".json":
        text = json.dumps(_no_wall(json.loads(text)), indent=2)
    else:
        text = re.sub(r"wall time [0-9.]+ s", "wall time T s", text)
        text = re.sub(r"[0-9.]+ s/run", "T s/run", text)
    return hashlib.sha256(text.encode()).hexdigest()


def _blow_up(monkeypatch: pytest.MonkeyPatch) -> None:
    """Start 1's physics (y 300) fails at its third cycle: its run keeps the table record, an
    error and the partial physics record."""
    original = physics_world.PhysicsWorld.step

    def step(self, gait):
        if self.cycles == 2 and self.pose()[1] > 250.0:
            raise PhysicsError("NaN in qvel (injected at the third cycle)")
        return original(self, gait)

    monkeypatch.setattr(physics_world.PhysicsWorld, "step", step)


def write_case(case: str, out: Path) -> dict[str, Any]:
    """Run one pinned validation into ``out``; returns its report."""
    meta = {"case": case}
    if case == "lone":
        return validate(BITS, STARTS, table=PAPER_TABLE, workers=1, max_steps=12, seed=3,
                        out_dir=out, meta=meta)  # fmt: skip
    if case == "navigation":
        return validate(SECTION, STARTS, table=PAPER_TABLE, executor=SerialExecutor(),
                        powers=[4.0, 2.9], max_steps=15, out_dir=out, meta=meta)  # fmt: skip
    if case == "blow_up":
        return validate(BITS, STARTS, table=PAPER_TABLE, executor=SerialExecutor(), max_steps=6,
                        out_dir=out, meta=meta)  # fmt: skip
    return validate_colony(BITS, COLONY_STARTS, table=PAPER_TABLE, world=LOW, workers=1,
                           max_steps=8, seed=2, out_dir=out, meta=meta)  # fmt: skip


def digests(case: str, out: Path) -> dict[str, str]:
    write_case(case, out)
    return {name: digest(out / name) for name in FILES}


@pytest.mark.skipif(
    {"mujoco": __import__("mujoco").__version__, "numpy": np.__version__} != MADE_WITH,
    reason=f"pins made with {MADE_WITH}",
)
@pytest.mark.parametrize("case", list(PINS))
def test_a_validation_writes_the_pinned_files(case, tmp_path, monkeypatch):
    if case == "blow_up":
        _blow_up(monkeypatch)
    assert digests(case, tmp_path) == PINS[case]


if __name__ == "__main__":  # print the digests to pin
    import tempfile

    for name in PINS:
        with tempfile.TemporaryDirectory() as tmp, pytest.MonkeyPatch.context() as mp:
            if name == "blow_up":
                _blow_up(mp)
            print(f'    "{name}": {json.dumps(digests(name, Path(tmp)), indent=8)},')
    sys.exit(0)
