"""The reliability building blocks, one guarantee per test: named-error readers, atomic writes
that Ctrl-C cannot tear, run-folder locks and ownership, size bounds, the CLI runner, and
workers that stop with the main process."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from evolve.checkpoint import write_npz
from evolve.population import stage_seeds
from evolve.table import PAPER_TABLE, GaitTableError, table_from_json, table_to_json
from infra.bounds import BoundsError, Limits, Need, check_int, check_need, check_number
from infra.command import Interrupted, Terminated, command_line, run_command
from infra.errors import InputError
from infra.executors import process_pool, spawning
from infra.io import (
    OutputError,
    ReadError,
    atomic_write,
    atomic_write_text,
    check_output_dir,
    check_output_file,
    parse_json,
    partial_path,
    read_json,
    read_text,
    remove_partials,
)
from infra.rundir import RECORD_FILE, RunDirError, folder_lock, run_folder
from servo_mj.robot.gaits import GaitLibrary, GaitParamsError

ROOT = Path(__file__).resolve().parents[1]


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") and p.name != ".lock")


# --------------------------------------------------------------------------- reading


def test_read_text_accepts_a_bom_and_names_every_unusable_file(tmp_path, monkeypatch):
    ok = tmp_path / "ok.txt"
    ok.write_bytes(b"\xef\xbb\xbfline\r\n")
    assert read_text(ok, what="x") == "line\r\n"
    cases = {
        tmp_path: "is a folder, not a chromosome file",
        tmp_path / "missing.txt": "no such chromosome file",
        Path(os.devnull): "is not a regular file",
    }
    for bad, content in [
        ("bin", b"01\x0001"),
        ("latin", b"caf\xe9"),
        ("u16", "x".encode("utf-16")),
    ]:
        (tmp_path / bad).write_bytes(content)
        cases[tmp_path / bad] = {"bin": "binary", "latin": "byte 0xe9 at offset 3",
                                 "u16": "UTF-16"}[bad]  # fmt: skip
    for path, message in cases.items():
        with pytest.raises(ReadError, match=message) as info:
            read_text(path, what="chromosome file")
        assert str(path) in str(info.value) and isinstance(info.value, InputError)
    real_open = open

    def no_permission(file, *a, **k):
        if str(file) == str(ok):
            raise PermissionError(errno.EACCES, "Permission denied", str(file))
        return real_open(file, *a, **k)

    monkeypatch.setattr("builtins.open", no_permission)
    with pytest.raises(ReadError, match="ok.txt: cannot read this x: permission denied"):
        read_text(ok, what="x")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"F": NaN}', "non-finite number NaN"),
        ('{"F": -Infinity}', "non-finite number -Infinity"),
        ('{"F": 1e400}', "number 1e400 is too large"),
        ('{"F": ' + "9" * 5000 + "}", "not a valid"),
        ("[" * 50_000 + "]" * 50_000, "nested too deeply"),
        ('{"a": ' * 65 + "1" + "}" * 65, "nested more than 64 deep"),
        ('{"F": 1', "not valid JSON"),
    ],
)
def test_json_is_parsed_strictly(text, message):
    with pytest.raises(ReadError, match=message):
        parse_json(text, "f.json", what="gait table")
    assert parse_json('{"F": 1.7e308, "n": [1, -0.0]}', "f.json", what="x")["F"] == 1.7e308


def test_read_json_can_raise_the_callers_error(tmp_path):
    with pytest.raises(GaitTableError, match="missing.json: no such gait-table file"):
        read_json(tmp_path / "missing.json", what="gait-table file", error=GaitTableError)


# --------------------------------------------------------------------------- writing


def test_ctrl_c_during_a_write_is_held_until_the_file_is_whole(tmp_path, ctrl_c_raises):
    path = tmp_path / "result.txt"

    def write(tmp: Path) -> None:
        with open(tmp, "w") as fh:
            fh.write("first half, ")
            signal.raise_signal(signal.SIGINT)  # Ctrl-C in the middle of the write
            fh.write("second half")

    with pytest.raises(KeyboardInterrupt):
        atomic_write(path, write)
    assert path.read_text() == "first half, second half"
    assert _hidden(tmp_path) == []


def test_ctrl_c_during_a_checkpoint_is_not_a_zipfile_error(tmp_path, monkeypatch, ctrl_c_raises):
    path = tmp_path / "pop0.npz"
    real = np.savez_compressed

    def interrupted(fh, **arrays):  # SIGINT arrives while numpy writes the zip
        signal.raise_signal(signal.SIGINT)
        real(fh, **arrays)

    monkeypatch.setattr(np, "savez_compressed", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_npz(path, population=np.ones((64, 8, 30), np.uint8))
    with np.load(path) as z:
        assert z["population"].sum() == 64 * 240
    assert _hidden(tmp_path) == []


def test_a_failed_write_names_the_file_and_keeps_the_old_one(tmp_path):
    path = tmp_path / "summary.json"
    path.write_text("old")

    def full_disk(tmp: Path) -> None:
        tmp.write_text("half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OutputError, match="summary.json: No space left on device"):
        atomic_write(path, full_disk)
    assert path.read_text() == "old" and _hidden(tmp_path) == []
    (tmp_path / "a_file").write_text("")
    with pytest.raises(OutputError, match="cannot write"):
        atomic_write_text(tmp_path / "a_file" / "x.txt", "x")
    with pytest.raises(OutputError, match="Is a directory"):
        atomic_write_text(tmp_path, "x")


def test_output_places_are_checked_before_work(tmp_path):
    (tmp_path / "f").write_text("")
    for bad, message in [
        (tmp_path / "f", "--out .*/f: is a file, not a folder"),
        (tmp_path / "f" / "sub", "cannot write there"),
        (Path("/proc/servobot-test"), "cannot write there"),
    ]:
        with pytest.raises(OutputError, match=message):
            check_output_dir(bad, option="--out")
    with pytest.raises(OutputError, match="--rrd .*: is a folder, not a file"):
        check_output_file(tmp_path, option="--rrd")
    assert check_output_file(tmp_path / "new" / "x.rrd", option="--rrd").parent.is_dir()
    assert _hidden(tmp_path / "new") == []


def test_partial_files_of_earlier_processes_are_swept(tmp_path):
    old, new = partial_path(tmp_path / "a.rrd"), partial_path(tmp_path / "b.rrd")
    assert old.name.startswith(".a.rrd.") and old.suffix == ".rrd"
    for p in (old, new):
        p.write_text("x")
    os.utime(old, (1.0, 1.0))  # written long before this process started
    assert remove_partials(tmp_path) == [old]
    assert new.exists()  # this process's own, perhaps still being written
    assert remove_partials(tmp_path, any_age=True) == [new]


# --------------------------------------------------------------------------- run folders


def test_run_folder_states_and_force_clears_only_owned_files(tmp_path):
    owned = ["result.txt", "sub/*.npz"]
    with run_folder(tmp_path, {"seed": 1}, owned=owned) as claim:
        assert claim.state == "new"
        (tmp_path / "result.txt").write_text("r")
        (tmp_path / "sub").mkdir()
        (tmp_path / "sub" / "a.npz").write_text("a")
    (tmp_path / "mine.txt").write_text("a user's file")
    with pytest.raises(RunDirError, match=r"seed: 1 there, 2 here\); nothing in it was changed"):
        with run_folder(tmp_path, {"seed": 2}, owned=owned):
            pass
    with pytest.raises(RunDirError, match="already holds this run"):
        with run_folder(tmp_path, {"seed": 1}, owned=owned):
            pass
    with run_folder(tmp_path, {"seed": 1}, owned=owned, resumable=False) as claim:
        assert claim.state == "resumed"
    with run_folder(tmp_path, {"seed": 2}, owned=owned, force=True) as claim:
        assert claim.state == "forced"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".lock", "mine.txt", RECORD_FILE]
    assert json.loads((tmp_path / RECORD_FILE).read_text()) == {"seed": 2}


def test_run_files_without_a_record_are_an_unknown_run(tmp_path):
    (tmp_path / "result.txt").write_text("r")
    with pytest.raises(RunDirError, match="no settings.json \\(an unknown run\\)"):
        with run_folder(tmp_path, {"seed": 1}, owned=["result.txt"], resume=True):
            pass
    assert not (tmp_path / RECORD_FILE).exists()


def test_an_interrupted_run_leaves_no_temporary_file_and_releases_the_lock(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with run_folder(tmp_path, {"a": 1}, owned=["*.rrd"]):
            partial_path(tmp_path / "run0.rrd").write_text("a worker's unfinished recording")
            raise KeyboardInterrupt
    assert _hidden(tmp_path) == []
    with run_folder(tmp_path, {"a": 1}, owned=["*.rrd"], resume=True):
        with pytest.raises(RunDirError, match=r"is in use by another run \(pid \d+"):
            with folder_lock(tmp_path):
                pass
    assert (tmp_path / ".lock").read_text() == ""  # nobody holds it


def test_the_os_releases_the_lock_of_a_killed_process(tmp_path):
    code = (
        "import sys, time\nfrom pathlib import Path\nfrom infra.rundir import folder_lock\n"
        f"with folder_lock(Path({str(tmp_path)!r})):\n    print('held', flush=True)\n"
        "    time.sleep(60)\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == b"held"
        with pytest.raises(RunDirError, match=f"pid {holder.pid}"):
            with folder_lock(tmp_path):
                pass
    finally:
        holder.kill()
        holder.wait(30)
    with folder_lock(tmp_path):
        pass


# --------------------------------------------------------------------------- bounds


def test_bounds_refuse_memory_and_time_no_machine_has():
    limits = Limits(memory_fraction=0.5, max_wall_s=3600.0)
    check_need(Need(1e6, 10.0), "small", limits=limits)
    with pytest.raises(BoundsError, match="big need about 1000.0 PB of memory"):
        check_need(Need(1e18, 1.0), "big", limits=limits)
    with pytest.raises(BoundsError, match="long would run for at least 2 hours"):
        check_need(Need(1.0, 7200.0), "long", limits=limits)
    assert Need(5, 1) + Need(3, 2) == Need(5, 3)  # stages in turn: memory peaks, time adds
    with pytest.raises(BoundsError, match="--cycles must be an integer ≥ 1, got True"):
        check_int(True, "--cycles", lo=1)
    with pytest.raises(BoundsError, match="--noise must be a number between 0 and 1 rad"):
        check_number(float("nan"), "--noise", lo=0.0, hi=1.0, unit=" rad")


def test_population_seeds_are_spawned_lazily_and_equal_spawn():
    test_seq, seqs = stage_seeds(3, "coverage", 1_000_000_000)  # instant, no memory
    assert len(seqs) == 1_000_000_000
    children = np.random.SeedSequence([3, 1]).spawn(4)
    assert (test_seq.generate_state(4) == children[0].generate_state(4)).all()
    for k in range(3):
        assert (seqs[k].generate_state(4) == children[k + 1].generate_state(4)).all()


def test_gait_tables_and_parameters_have_physical_bounds():
    for row, message in [
        ({"F": 1.7e308}, "F = 1.7e\\+308, beyond the physical bound"),
        ({"F": 116.0}, "F = 116, beyond"),  # Figure 4's 11.6 cm written in mm
        ({"dH": 180.0}, "\\|dH\\| < 180°"),
        ({"gait": 2.7}, "gait must be an integer 0-15, got 2.7"),
        ({"gait": True}, "gait must be an integer"),
        ({"T": "0.8"}, "T must be a number"),
        ({"F_std": -1.0}, "negative spread"),
    ]:
        doc = table_to_json(PAPER_TABLE, np.zeros((16, 3)))
        doc["gaits"][0].update(row)
        with pytest.raises(GaitTableError, match=message):
            table_from_json(doc)
    doc = GaitLibrary.load().to_dict()
    doc["gaits"][3]["left"] = 20.0  # 20 × 0.47 rad: past half a turn
    with pytest.raises(GaitParamsError, match="gait 3 commands a servo target of 9.41 rad"):
        GaitLibrary.from_dict(doc)
    doc = GaitLibrary.load().to_dict()
    doc["gaits"][3]["gait"] = 3.5
    with pytest.raises(GaitParamsError, match="3.5"):
        GaitLibrary.from_dict(doc)


# --------------------------------------------------------------------------- the runner


def test_runner_maps_endings_to_exit_codes_and_messages(capsys):
    note = lambda: Interrupted("the checkpoints", "servobot x --resume")  # noqa: E731

    def raise_(exc: BaseException):
        def body() -> int:
            raise exc

        return body

    assert run_command("servobot x", lambda: 0, note) == 0
    assert run_command("servobot x", raise_(InputError("bad --out")), note) == 2
    assert capsys.readouterr().err == "servobot x: error: bad --out\n"
    assert run_command("servobot x", raise_(MemoryError()), note) == 2
    assert run_command("servobot x", raise_(KeyboardInterrupt()), note) == 130
    err = capsys.readouterr().err
    assert "interrupted; kept: the checkpoints; resume with: servobot x --resume" in err
    assert run_command("servobot x", raise_(Terminated()), note) == 143
    with pytest.raises(ZeroDivisionError):  # a bug keeps its traceback
        run_command("servobot x", raise_(ZeroDivisionError()), note)
    before = signal.getsignal(signal.SIGTERM)

    def sigterm() -> int:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
        return 0

    assert run_command("servobot x", sigterm, note) == 143
    assert signal.getsignal(signal.SIGTERM) == before
    assert command_line("servobot e", ["--out", "a b"], "--resume") == (
        "servobot e --out 'a b' --resume"
    )
    assert command_line("servobot e", ["--resume"], "--resume") == "servobot e --resume"
    # resuming must not delete what --force started
    assert command_line("servobot e", ["--force"], "--resume", drop=["--force"]) == (
        "servobot e --resume"
    )


def _sleep_and_report(path: str) -> int:
    Path(path, str(os.getpid())).write_text(str(signal.getsignal(signal.SIGINT)))
    time.sleep(30)
    return os.getpid()


def test_workers_ignore_ctrl_c_and_are_stopped_with_the_main_process(tmp_path):
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with process_pool(2) as pool:
            with spawning():
                futures = [pool.submit(_sleep_and_report, str(tmp_path)) for _ in range(2)]
            while len(list(tmp_path.iterdir())) < 2:
                time.sleep(0.05)
            raise KeyboardInterrupt  # Ctrl-C in the main process
    assert time.perf_counter() - t0 < 20  # not the workers' 30 s
    for f in tmp_path.iterdir():
        assert f.read_text() == str(signal.SIG_IGN)
        with pytest.raises(ProcessLookupError):
            os.kill(int(f.name), 0)
    assert all(f.done() for f in futures)
