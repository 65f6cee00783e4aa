"""Issue 19 (folders, settings, resume, messages): the newer commands keep the reliability
promises. A run folder belongs to one command as well as one run; every setting is checked
against the others before work; resume names the record that fails; no message misleads.

Each case runs in-process (``servobot.cli.main(argv)``) with tiny settings and asserts exit 2,
no traceback, a message naming the option or file, and nothing written or changed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from infra.rundir import RECORD_FILE, RunDirError, run_folder
from servobot.cli import main as servobot

GENE = "01 0100000 0100000 0100000 0100000\n"


def _run(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    try:
        code = servobot([str(a) for a in argv])
    except SystemExit as exc:  # argparse
        code = exc.code
    return code, capsys.readouterr().err


def _bytes(folder: Path) -> dict[Path, bytes]:
    """Every file under ``folder`` (the lock aside) and its bytes."""
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file() and p.name != ".lock"}


def _refused(argv: list[str], capsys: pytest.CaptureFixture, *names: str) -> str:
    code, err = _run(argv, capsys)
    assert code == 2, err
    assert "Traceback" not in err, err
    for name in names:
        assert name in err, err
    return err


@pytest.fixture(scope="module")
def chrom16(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("inputs") / "c16.txt"
    path.write_text(GENE * 16)
    return path


# --------------------------------------------------------------------------- one command a folder


def test_a_folder_records_its_command_and_refuses_another_even_with_force(tmp_path):
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], command="validate"):
        (tmp_path / "a.txt").write_text("a")
    assert json.loads((tmp_path / RECORD_FILE).read_text()) == {"command": "validate", "seed": 1}
    before = _bytes(tmp_path)
    for force in (False, True):
        with pytest.raises(RunDirError, match="holds a 'servobot validate' run .* not a 'servobot "
                           "compare' one; nothing in it was changed"):  # fmt: skip
            with run_folder(tmp_path, {"tables": []}, owned=["b.txt"], command="compare",
                            force=force):  # fmt: skip
                pass
    assert _bytes(tmp_path) == before
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], command="validate", resumable=False):
        pass  # the same command and settings: redone


def test_an_old_record_without_a_command_is_judged_by_its_files(tmp_path):
    (tmp_path / RECORD_FILE).write_text(json.dumps({"seed": 1}))
    (tmp_path / "a.txt").write_text("a")
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], command="evolve navigation",
                    resume=True) as claim:  # fmt: skip
        assert claim.state == "resumed"
    assert json.loads((tmp_path / RECORD_FILE).read_text())["command"] == "evolve navigation"
    (tmp_path / RECORD_FILE).write_text(json.dumps({"seed": 1}))
    with pytest.raises(RunDirError, match=r"seed: 1 there, 2 here"):
        with run_folder(tmp_path, {"seed": 2}, owned=["a.txt"], command="evolve navigation"):
            pass


@pytest.mark.parametrize("record", [b"{not json", b"[1, 2]", b"\xff\xfe\x00"])
def test_a_corrupt_record_is_named_not_called_other_settings(tmp_path, record):
    (tmp_path / RECORD_FILE).write_bytes(record)
    for owned in (["a.txt"], ["b.txt"]):  # with and without this run's files
        (tmp_path / "a.txt").write_text("a")
        with pytest.raises(RunDirError, match=rf"ownership record that cannot be read \({tmp_path}"
                           rf"/{RECORD_FILE}: ") as exc:  # fmt: skip
            with run_folder(tmp_path, {"seed": 1}, owned=owned, command="validate"):
                pass
        assert "other settings" not in str(exc.value)
        assert (tmp_path / RECORD_FILE).read_bytes() == record
    with run_folder(tmp_path, {"seed": 1}, owned=["a.txt"], force=True) as claim:
        assert claim.state == "forced"


def test_compare_refuses_a_validation_folder_and_validate_a_compare_folder(
    chrom16, tmp_path, capsys
):
    val, cmp = tmp_path / "val", tmp_path / "cmp"
    code, err = _run(["validate", chrom16, "--starts", "1", "--steps", "1", "--workers", "1",
                      "--no-progress", "--out", val], capsys)  # fmt: skip
    assert code == 0, err
    assert json.loads((val / RECORD_FILE).read_text())["command"] == "validate"
    assert _run(["compare", "paper", "paper", "--labels", "a", "b", "--out", cmp], capsys)[0] == 0
    before_val, before_cmp = _bytes(val), _bytes(cmp)
    for force in ([], ["--force"]):
        _refused(["compare", "paper", "paper", "--labels", "a", "b", "--out", val, *force],
                 capsys, str(val), "'servobot validate' run")  # fmt: skip
        _refused(["validate", chrom16, "--starts", "1", "--steps", "1", "--workers", "1",
                  "--no-progress", "--out", cmp, *force], capsys, str(cmp),
                 "'servobot compare' run")  # fmt: skip
    assert _bytes(val) == before_val and _bytes(cmp) == before_cmp


# --------------------------------------------------------------------------- settings vs settings

TINY = ["--populations", "1", "--population-size", "4", "--generations", "2", "--no-progress"]


@pytest.mark.parametrize("robots", ["8", "9", "40"])
def test_colony_robots_that_jam_the_start_region_are_refused_before_work(
    chrom16, tmp_path, capsys, robots
):
    out = tmp_path / "out"
    err = _refused(["evolve", "colony", "--robots", robots, "--navigation", chrom16, *TINY,
                    "--out", out], capsys, f"--robots {robots}", "at most 7 robots",
                   "cannot place robot")  # fmt: skip
    assert "--robots 7 or fewer" in err
    assert not out.exists()


def test_colony_robots_that_fit_run(chrom16, tmp_path):
    from evolve.settings import ColonySettings, WorldSettings
    from evolve.starts import colony_capacity

    assert colony_capacity(WorldSettings(), ColonySettings(robots=3)) == 3
    assert colony_capacity(WorldSettings(), ColonySettings(robots=7)) == 7


@pytest.mark.parametrize(
    "argv",
    [
        ["evolve", "navigation", "--populations", "1000000000"],
        ["evolve", "navigation", "--generations", "1000000000000000000"],
        ["validate", "{c16}", "--starts", "1000000000"],
        ["calibrate", "--cycles", "1000000000"],
    ],
)
def test_a_refusal_for_size_leaves_no_empty_out_folder(chrom16, tmp_path, capsys, argv):
    out = tmp_path / "new" / "out"
    argv = [a.replace("{c16}", str(chrom16)) for a in argv]
    _refused([*argv, "--out", out], capsys)
    assert not (tmp_path / "new").exists()
    out.mkdir(parents=True)  # a folder that was there stays
    _refused([*argv, "--out", out], capsys)
    assert out.is_dir()
