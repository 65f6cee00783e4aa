"""The executors (``infra.executors``): the same seeds give the same records, bit for bit, on
serial, a process pool and Ray — for validation runs, calibration walks and evolving
populations — and a worker that dies is retried once, then recorded as ``Failed``.

One local Ray instance of 2 CPUs serves the whole module (it takes seconds to start)."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from run_folder import result_files

from calibration.measure import measure_all
from evolve import stages
from evolve.anytime import AnytimeSettings
from evolve.codec import parse_chromosome
from evolve.settings import GASettings
from evolve.table import load_table
from infra.executors import (
    WORKER_DIED,
    BatchError,
    Failed,
    Ok,
    ProcessExecutor,
    RayExecutor,
    SerialExecutor,
    make_executor,
    run_in_order,
    values_or_raise,
)
from servobot.anytime.run import run_anytime
from servobot.cli import evolve as evolve_cli
from servobot.validation.lone import validate

TABLE = load_table("paper")
# Gene 0 forever: gait 8, branch to gene 1 when both object sensors see something; gene 1:
# 3× rotate (gait 14) then back: a controller that reads the rangefinders at every step.
BRANCHY = parse_chromosome(
    "00 0100000 1011001 0100000 1011001\n"
    "11 0111000 0111000 0111000 1000000\n" + "01 0100000 0100000 0100000 0100000\n" * 14
)
STARTS = np.array([[420.0, 120.0, 80.0], [300.0, 300.0, 45.0]])


@pytest.fixture(scope="module")
def executors():
    """Serial, a pool of 2 processes and a local Ray of 2 CPUs (shut down after the module)."""
    local_ray = RayExecutor(2)
    ray = local_ray.connect()
    # Functions of this test module travel by value: Ray's workers cannot import it by name.
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        yield {"serial": SerialExecutor(), "process": ProcessExecutor(2), "ray": local_ray}
    finally:
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
        ray.shutdown()


# --------------------------------------------------------------------------- same records
def _without_wall_times(obj):
    if isinstance(obj, dict):
        return {k: _without_wall_times(v) for k, v in obj.items() if "wall" not in k}
    if isinstance(obj, list):
        return [_without_wall_times(v) for v in obj]
    return obj


def test_validation_records_identical_on_every_executor(executors, tmp_path):
    docs, tracks = {}, {}
    for name, ex in executors.items():
        validate(BRANCHY, STARTS, table=TABLE, max_steps=6, seed=5, executor=ex,
                 out_dir=tmp_path / name)  # fmt: skip
        docs[name] = _without_wall_times(json.loads((tmp_path / name / "report.json").read_text()))
        with np.load(tmp_path / name / "tracks.npz") as z:
            tracks[name] = {k: z[k].tobytes() for k in z.files}
    assert all(r["error"] is None and r["physics"]["steps"] == 6 for r in docs["serial"]["runs"])
    assert docs["serial"] == docs["process"] == docs["ray"]
    assert tracks["serial"] == tracks["process"] == tracks["ray"]
    assert len(tracks["serial"]) == 4


def test_calibration_walks_identical_on_every_executor(executors):
    walks = {
        name: measure_all((2, 13), executor=ex, cycles=2, settle_cycles=0, seed=3)
        for name, ex in executors.items()
    }
    for name in ("process", "ray"):
        assert walks[name].keys() == {2, 13}
        for g in (2, 13):
            np.testing.assert_array_equal(walks[name][g], walks["serial"][g])


def test_populations_identical_on_every_executor(executors, tmp_path):
    """A stage's populations evolved here (live progress) or as runs of any executor: the
    same files, and the same progress records once each population is done."""
    ga = GASettings(populations=2, population_size=10, generations=6, test_starts=8, seed=2)
    heard: dict[str, list] = {}
    runs = {"here": None, **executors}
    for name, ex in runs.items():
        heard[name] = []
        stages.run_navigation(tmp_path / name, table=TABLE, ga=ga, executor=ex,
                              on_generation=heard[name].append)  # fmt: skip
    files = {name: result_files(tmp_path / name) for name in runs}
    assert "navigation/populations/pop1_gen0006.npz" in files["here"]
    key = lambda r: (r["population"], r["generation"])  # noqa: E731
    for name in executors:
        assert files[name] == files["here"], name
        assert sorted(heard[name], key=key) == sorted(heard["here"], key=key), name
    assert len(heard["here"]) == 2 * 7


def test_anytime_identical_on_every_executor(executors, tmp_path):
    """Anytime learning's physics punctuations and final test on any executor: the same
    records, tables, chromosomes and summary (wall times aside)."""
    nav = np.zeros((8, 30), dtype=np.uint8)
    ga = GASettings(populations=2, population_size=8, generations=2, test_starts=2, seed=4)
    settings = AnytimeSettings(method="model", every=2, top=2, physics_starts=1,
                               physics_steps=3, final_starts=1, min_samples=1)  # fmt: skip
    files = {}
    for name, ex in executors.items():
        run_anytime(tmp_path / name, navigation=nav, table=TABLE, ga=ga, settings=settings,
                    executor=ex)  # fmt: skip
        files[name] = {
            rel: _without_wall_times(json.loads(v) if isinstance(v, bytes) else v)
            if rel.endswith(".json") else v
            for rel, v in result_files(tmp_path / name / "anytime").items()
        }  # fmt: skip
    assert "tables/gen0002.json" in files["serial"]
    assert files["serial"] == files["process"] == files["ray"]


# --------------------------------------------------------------------------- crashes
def _square_or_die(item: tuple[int, str]) -> int:
    """2: the worker dies outright (as on a segfault); 5: it dies on the first try only
    (a marker file remembers); 3: raises."""
    x, marker = item
    if x == 2 or (x == 5 and not os.path.exists(marker)):
        Path(marker).touch()
        os._exit(3)
    if x == 3:
        raise ValueError("three is bad")
    return x * x


@pytest.mark.parametrize("name", ["process", "ray"])
def test_a_dying_worker_is_retried_once_then_failed(executors, tmp_path, name):
    items = [(x, str(tmp_path / f"died_{x}")) for x in (0, 1, 2, 3, 4, 5)]
    out = run_in_order(executors[name], _square_or_die, items)
    assert [out[i] for i in (0, 1, 4)] == [Ok(0), Ok(1), Ok(16)]
    assert out[2] == Failed(WORKER_DIED)
    assert isinstance(out[3], Failed) and out[3].message == "ValueError: three is bad"
    assert out[5] == Ok(25)  # died once, the retry succeeded
    assert (tmp_path / "died_5").exists()


def _die_beside_a_started_run(item: tuple[int, str]) -> int:
    """0: waits until run 1 has started, then its worker dies (the pool breaks and kills run
    1's worker mid-run); 1: dies on its first try that gets past a 5 s pause (a marker file
    remembers), so a break during the pause is no try of its own."""
    x, folder = item
    d = Path(folder)
    if x == 0:
        deadline = time.monotonic() + 60
        while not (d / "started_1").exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        os._exit(3)
    (d / "started_1").touch()
    if not (d / "died_1").exists():
        time.sleep(5)
        (d / "died_1").touch()
        os._exit(3)
    return 1


def test_a_run_killed_by_another_runs_death_keeps_both_retries(tmp_path):
    """Two runs had started when the pool broke: which worker died is unknown, so each gets
    two tries alone; run 1, killed mid-run by run 0's death, then dies once on its own and
    succeeds on its retry (it was recorded as a worker death when it had one try)."""
    out = run_in_order(ProcessExecutor(2), _die_beside_a_started_run,
                       [(0, str(tmp_path)), (1, str(tmp_path))])  # fmt: skip
    assert out[0] == Failed(WORKER_DIED)
    assert out[1] == Ok(1)
    assert (tmp_path / "died_1").exists()


def test_serial_confines_a_raise_to_its_item():
    out = run_in_order(SerialExecutor(), _square_or_die, [(0, ""), (3, ""), (4, "")])
    assert out[0] == Ok(0) and out[2] == Ok(16)
    assert isinstance(out[1], Failed) and "three is bad" in out[1].detail


def test_values_or_raise_names_every_failed_run():
    outcomes = [Ok(1), Failed("PhysicsError: boom"), Ok(3), Failed("worker died")]
    assert values_or_raise(outcomes[::2]) == [1, 3]
    with pytest.raises(BatchError, match=r"2 of 4 runs failed: gait b: PhysicsError: boom; "
                       r"gait d: worker died") as err:  # fmt: skip
        values_or_raise(outcomes, ["gait a", "gait b", "gait c", "gait d"])
    assert set(err.value.failures) == {1, 3}


def test_a_failed_population_is_a_stage_error(tmp_path):
    ga = GASettings(populations=2, population_size=10, generations=2, test_starts=4)

    class Broken(SerialExecutor):
        def imap(self, fn, items):
            for i, _ in enumerate(items):
                yield i, Failed("MemoryError: out of memory") if i == 1 else Ok(None)

    with pytest.raises(stages.StageError, match="population 1: MemoryError.*--resume"):
        stages.run_navigation(tmp_path, table=TABLE, ga=ga, executor=Broken())


# --------------------------------------------------------------------------- specs
def test_make_executor_specs():
    assert isinstance(make_executor("serial"), SerialExecutor)
    assert isinstance(make_executor(None, 1), SerialExecutor)
    pool = make_executor(None, 3)
    assert isinstance(pool, ProcessExecutor) and pool.workers == 3
    assert make_executor("process", 1).workers == 1
    local = make_executor("ray", 2)
    assert isinstance(local, RayExecutor) and (local.address, local.workers) == (None, 2)
    assert make_executor("ray:10.0.0.5:6379").address == "10.0.0.5:6379"
    for bad in ("threads", "ray:", "Process", ""):
        with pytest.raises(ValueError, match="serial, process, ray or ray:ADDRESS"):
            make_executor(bad)
    with pytest.raises(ValueError, match="workers must be at least 1"):
        make_executor("process", 0)


def test_cli_refuses_an_unknown_executor(capsys):
    with pytest.raises(SystemExit) as exc:
        evolve_cli.main(["navigation", "--executor", "gpu"])
    assert exc.value.code == 2
    assert "serial, process, ray or ray:ADDRESS" in capsys.readouterr().err
