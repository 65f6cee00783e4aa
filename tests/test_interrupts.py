"""Interrupted runs: real signals to real commands (a few short subprocess runs), and the
recordings that an interrupted or failed run must not leave at their final path."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from conftest import sigint_as_in_a_terminal
from test_stages import _files

from evolve.codec import parse_chromosome
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE
from infra.command import Interrupted, run_command
from infra.io import OutputError
from servo_mj.world import physics_world
from servobot.cli import main as servobot
from servobot.recording import Recording
from servobot.validation import lone as validation

ROOT = Path(__file__).resolve().parents[1]
GENE = "01 0100000 0100000 0100000 0100000\n"


def _signal_when(args: list[str], ready: str, sig: int, cwd: Path) -> tuple[int, str]:
    """Run ``python -m servobot ARGS``, send ``sig`` once a file matching the glob ``ready``
    exists (relative to ``cwd``), and return (exit code, stderr)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "servobot", *args],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        preexec_fn=sigint_as_in_a_terminal,
    )  # fmt: skip
    t0 = time.monotonic()
    while not list(cwd.glob(ready)):
        assert proc.poll() is None, f"finished before {ready} appeared: {proc.stderr.read()}"
        assert time.monotonic() - t0 < 120
        time.sleep(0.02)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err


def test_ctrl_c_keeps_checkpoints_and_resume_is_bit_identical(tmp_path, capsys):
    args = ["navigation", "--populations", "1", "--population-size", "16",
            "--generations", "160", "--seed", "3", "--no-progress"]  # fmt: skip
    cut = tmp_path / "cut"
    code, err = _signal_when(
        ["evolve", *args, "--out", str(cut)], "navigation/checkpoints/pop0.npz", signal.SIGINT,
        cut,
    )  # fmt: skip
    assert code == 130, err
    assert "Traceback" not in err
    assert f"kept: the checkpoints in {cut}/navigation/checkpoints" in err
    assert err.rstrip().endswith(
        f"resume with: servobot evolve {' '.join(args)} --out {cut} --resume"
    )
    assert not (cut / "navigation" / "best.txt").exists()
    assert servobot(["evolve", *args, "--out", str(cut), "--resume"]) == 0
    assert servobot(["evolve", *args, "--out", str(tmp_path / "ref")]) == 0
    assert _files(cut) == _files(tmp_path / "ref")


NOTE = lambda: Interrupted("nothing", "servobot x --again")  # noqa: E731


def test_an_interrupt_a_library_turned_into_another_error_still_ends_as_interrupted(
    ctrl_c_raises, capsys
):
    def body() -> int:  # numpy's structured np.unique makes a Ctrl-C a TypeError
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            raise TypeError("Cannot compare structured arrays") from None
        return 0

    assert run_command("servobot x", body, NOTE) == 130
    assert "interrupted; kept: nothing" in capsys.readouterr().err


def test_a_swallowed_interrupt_is_delivered_again(ctrl_c_raises, capsys):
    class Swallowed:  # an exception in __del__ cannot be raised: Python prints "ignored"
        def __del__(self) -> None:
            signal.raise_signal(signal.SIGINT)

    def body() -> int:
        Swallowed()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:  # a numba compile going on after the callback
            pass
        return 0

    t0 = time.monotonic()
    assert run_command("servobot x", body, NOTE) == 130
    assert time.monotonic() - t0 < 10
    assert "Exception ignored" not in capsys.readouterr().err


def test_ctrl_c_ignored_from_birth_stays_ignored():
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)  # a background job
    try:
        seen = []
        assert run_command("servobot x", lambda: seen.append(signal.getsignal(2)), NOTE) == 0
        assert seen == [signal.SIG_IGN] and signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)


def test_an_interrupt_escaping_exec_of_source_does_not_kill_the_process_at_exit(tmp_path):
    """CPython notes a KeyboardInterrupt that escapes exec() of source text (numba compiles
    so) and kills itself with SIGINT at exit even though the command handled it: exit -2."""
    (tmp_path / "interrupted_in_exec.py").write_text(
        "import sys\n"
        "from infra.command import Interrupted, run_command\n"
        "body = lambda: exec('import signal; signal.raise_signal(signal.SIGINT)')\n"
        "sys.exit(run_command('servobot x', body, lambda: Interrupted('nothing', 'again')))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-m", "interrupted_in_exec"], cwd=tmp_path, capture_output=True,
        text=True, env={**os.environ, "PYTHONPATH": str(ROOT)},
        preexec_fn=sigint_as_in_a_terminal,
    )  # fmt: skip
    assert proc.returncode == 130, proc.stderr
    assert "servobot x: interrupted; kept: nothing; resume with: again" in proc.stderr


def test_ctrl_c_stops_parallel_validation_without_partial_recordings(tmp_path):
    chromosome = tmp_path / "c.txt"
    chromosome.write_text(GENE * 16)
    out = tmp_path / "val"
    args = ["validate", str(chromosome), "--starts", "4", "--steps", "40", "--workers", "2",
            "--rrd", "--out", str(out), "--no-progress"]  # fmt: skip
    code, err = _signal_when(args, ".run*.partial.rrd", signal.SIGINT, out)
    assert code == 130, err
    assert "Traceback" not in err and "resume with: servobot validate" in err
    names = sorted(p.name for p in out.iterdir())
    assert [n for n in names if n.startswith(".") and n != ".lock"] == []  # no temp file
    assert "report.json" not in names
    for rrd in out.glob("run*.rrd"):  # only complete recordings of finished runs
        paths = {c.entity_path for c in rr.chunk.RrdReader(str(rrd)).stream().collect().stream()}
        assert "/world/track/physics" in paths


def test_an_interrupted_run_leaves_no_recording(tmp_path, monkeypatch):
    class Interrupting(physics_world.PhysicsWorld):
        def step(self, gait: int) -> None:
            raise KeyboardInterrupt

    monkeypatch.setattr(physics_world, "PhysicsWorld", Interrupting)
    with pytest.raises(KeyboardInterrupt):
        validation.validate(
            parse_chromosome(GENE * 16), np.array([[400.0, 250.0, 0.0]]), table=PAPER_TABLE,
            workers=1, max_steps=5, out_dir=tmp_path, rrd=True,
        )  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == [".lock", "settings.json"]


def test_a_recording_that_cannot_be_renamed_leaves_no_temporary_file(tmp_path):
    target = tmp_path / "taken"
    rec = Recording(target)
    rec.log_arena(WorldSettings())
    target.mkdir()  # something took the final path meanwhile
    (target / "x").write_text("")
    with pytest.raises(OutputError, match="cannot write .*taken"):
        rec.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
