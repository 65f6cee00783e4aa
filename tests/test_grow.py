"""A stage grown by more populations (``evolve.grow``) equals the larger stage run afresh."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest
from run_folder import result_files

from evolve import grow, stages
from evolve.checkpoint import write_npz
from evolve.settings import GASettings
from evolve.table import load_table
from infra.rundir import RunDirError

TABLE = load_table("paper")
ONE = GASettings(populations=1, population_size=10, generations=6, test_starts=8, seed=5)
TWO = dataclasses.replace(ONE, populations=2)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """(a one-population navigation stage, the same stage with two populations)."""
    root = tmp_path_factory.mktemp("grow")
    stages.run_navigation(root / "one", table=TABLE, ga=ONE)
    stages.run_navigation(root / "two", table=TABLE, ga=TWO)
    return root / "one", root / "two"


def test_grown_stage_resumed_equals_the_larger_stage_run_afresh(runs, tmp_path):
    one, two = runs
    run = shutil.copytree(one, tmp_path / "run")
    with pytest.raises(RunDirError, match="GASettings.populations: 1 there, 2 here"):
        stages.run_navigation(run, table=TABLE, ga=TWO, resume=True)
    assert grow.main([str(run / "navigation"), "--populations", "2"]) == 0
    seen = []
    stages.run_navigation(run, table=TABLE, ga=TWO, resume=True, on_generation=seen.append)
    assert {i["population"] for i in seen} == {1}  # population 0 kept from its checkpoint
    assert result_files(run) == result_files(two)
    assert result_files(run) != result_files(one)


def test_growing_again_or_to_fewer_and_bad_folders(runs, tmp_path, capsys):
    one, _ = runs
    stage = shutil.copytree(one / "navigation", tmp_path / "navigation")
    assert grow.grow(stage, 3) == (1, 1)
    assert grow.grow(stage, 3) == (3, 0)  # already grown: nothing rewritten
    assert json.loads((stage / "settings.json").read_text())["GASettings"]["populations"] == 3
    assert grow.main([str(stage), "--populations", "2"]) == 2
    assert "holds 3 populations; --populations must be ≥ 3, got 2" in capsys.readouterr().err

    # a checkpoint of another run: refused by name, nothing written
    ckpt = stage / "checkpoints" / "pop0_final.npz"
    with np.load(ckpt) as z:
        data = {k: z[k] for k in z.files}
    write_npz(ckpt, **(data | {"settings": np.str_('{"other": 1}')}))
    record = (stage / "settings.json").read_bytes()
    with pytest.raises(grow.GrowError, match=r"pop0_final\.npz: checkpoint written with settings"):
        grow.grow(stage, 4)
    assert (stage / "settings.json").read_bytes() == record

    assert grow.main([str(tmp_path / "absent"), "--populations", "2"]) == 2
    assert "absent" in capsys.readouterr().err
    other = tmp_path / "validate"
    other.mkdir()
    (other / "settings.json").write_text(json.dumps({"command": "validate"}))
    with pytest.raises(grow.GrowError, match="a 'validate' run; only evolve navigation and"):
        grow.grow(other, 2)
