"""Every command, bad inputs of every kind: exit 2, a message naming the file or option, no
traceback, and nothing written. Each case runs in-process (``servobot.cli.main(argv)``).

Kinds: input files that are a folder, a device, empty, binary, UTF-16, not UTF-8, too large,
or hold non-finite / out-of-bound numbers; numbers out of range (negative seeds, sizes whose
memory or time no machine has); output places that are a file, a folder, under /proc or under
a file; run folders holding another run or in use by another process.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
from pathlib import Path

import pytest

from evolve.table import PAPER_TABLE, table_to_json
from infra.rundir import RECORD_FILE
from servobot.cli import main as servobot

GENE = "01 0100000 0100000 0100000 0100000\n"
ROOT_USER = hasattr(os, "geteuid") and os.geteuid() == 0


def _table_doc(**row0: object) -> str:
    doc = table_to_json(PAPER_TABLE)
    doc["gaits"][0].update(row0)
    return json.dumps(doc)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One file of every bad kind (and good ones to pair them with)."""
    d = tmp_path_factory.mktemp("inputs")
    f = {
        "dir": d / "a_folder",
        "empty": d / "empty.txt",
        "binary": d / "binary.bin",
        "latin1": d / "latin1.txt",
        "utf16": d / "utf16.txt",
        "big": d / "big.txt",
        "chrom16": d / "c16.txt",
        "chrom8": d / "c8.txt",
        "chrom7": d / "c7.txt",
        "inf_table": d / "inf.json",
        "huge_table": d / "huge.json",
        "float_gait": d / "gait27.json",
        "big_F": d / "bigF.json",
        "string_F": d / "stringF.json",
        "list_json": d / "list.json",
        "deep_json": d / "deep.json",
        "bad_params": d / "params.json",
        "deep_meta": d / "deep_meta.json",
        "bias_run": d / "bias_run",
        "devnull": Path(os.devnull),
    }
    f["dir"].mkdir()
    f["empty"].write_text("")
    f["binary"].write_bytes(bytes(range(256)) * 4)
    f["latin1"].write_bytes(("# café\n" + GENE * 16).encode("latin-1"))
    f["utf16"].write_text(GENE * 16, encoding="utf-16")
    with open(f["big"], "wb") as fh:  # sparse: 65 MB on paper, nothing on disk
        fh.truncate(65 * 2**20)
    f["chrom16"].write_text(GENE * 16)
    f["chrom8"].write_text(GENE * 8)
    f["chrom7"].write_text(GENE * 7)
    f["inf_table"].write_text(_table_doc(F=1.0).replace('"F": 1.0', '"F": Infinity'))
    f["huge_table"].write_text(_table_doc(gait=0).replace('"gait": 0', '"gait": 1e400'))
    f["float_gait"].write_text(_table_doc(gait=0).replace('"gait": 0', '"gait": 2.7'))
    f["big_F"].write_text(_table_doc(F=1.7e308))
    f["string_F"].write_text(_table_doc(F="11.6"))
    f["list_json"].write_text("[1, 2, 3]")
    f["deep_json"].write_text("[" * 100_000 + "]" * 100_000)
    f["bad_params"].write_text(json.dumps({"gaits": [{"gait": 0}], "stride_rad": 0.47}))
    deep = '{"a": ' * 900 + "1" + "}" * 900  # parses, but would exhaust recursive walkers
    f["deep_meta"].write_text(_table_doc()[:-1] + f', "provenance": {deep}}}')
    (f["bias_run"] / "anytime").mkdir(parents=True)
    summary = {"method": "bias", "best_by_generation": {}, "final": {}}
    (f["bias_run"] / "anytime" / "summary.json").write_text(json.dumps(summary))
    return f


# (argv with {placeholders}, what the message must name)
Case = tuple[list[str], str]


def _file_cases(*argv: str, what: str, then: tuple[str, ...] = ()) -> list[Case]:
    """A folder and a binary file as the ``what`` file that ``argv`` ends wanting (then
    ``then``)."""
    return [
        ([*argv, "{dir}", *then], f"a_folder: is a folder, not a {what}"),
        ([*argv, "{binary}", *then], "binary.bin: holds binary data"),
    ]


def _text_cases(*argv: str, empty: str, then: tuple[str, ...] = ()) -> list[Case]:
    """An empty file (``empty``: what its message names), Latin-1, UTF-16, a file too large
    and a device as the text file that ``argv`` ends wanting (then ``then``)."""
    return [
        ([*argv, "{empty}", *then], empty),
        ([*argv, "{latin1}", *then], "latin1.txt: is not UTF-8 text (byte 0xe9"),
        ([*argv, "{utf16}", *then], "utf16.txt: is UTF-16 text"),
        ([*argv, "{big}", *then], "big.txt: is 68,157,440 bytes, too large"),
        ([*argv, "{devnull}", *then], "/dev/null: is not a regular file"),
    ]


OUT_OF_RANGE = {
    "--seed": ("-1", "--seed must be an integer ≥ 0, got -1"),
    "--starts": ("1000000000", "--starts 1000000000"),
    "--steps": ("1000000000000", "--steps 1000000000000"),
    "--workers": ("1000000", "--workers must be an integer between 1"),
}
"""A value out of range of each option several commands share, and what its message names."""


def _range_cases(*argv: str, options: tuple[str, ...]) -> list[Case]:
    """Each of ``options`` out of range (``OUT_OF_RANGE``) after ``argv``."""
    return [([*argv, o, OUT_OF_RANGE[o][0]], OUT_OF_RANGE[o][1]) for o in options]


GA_CASES: list[Case] = [
    (["--populations", "1000000000"], "1000000000 populations"),
    (["--population-size", "1000000000"], "1000000000 individuals"),
    (["--generations", "1000000000000000000"], "1000000000000000000 gen"),
    (["--generations", "0"], "--generations must be ≥ 1"),
    (["--seed", "-1"], "--seed must be ≥ 0"),
]
"""The GA budget options out of range (``servobot.cli.options.add_ga_options``)."""


def _ga_cases(*argv: str) -> list[Case]:
    """``GA_CASES`` after ``argv``: for every command that evolves (``ga_settings``)."""
    return [([*argv, *bad], message) for bad, message in GA_CASES]


def _out_cases(*argv: str) -> list[Case]:
    """A file and a place under /proc as the ``--out`` folder, after ``argv``."""
    return [
        ([*argv, "--out", "{chrom16}"], "is a file, not a folder"),
        ([*argv, "--out", "/proc/servobot-x"], "/proc/servobot-x: cannot write there"),
    ]


START = ("--start", "250", "250", "0")
"""A start pose of ``servobot trace``."""
CASES = {
    "evolve": [
        *_file_cases("navigation", "--table", what="gait-table file"),
        *_text_cases("navigation", "--table", empty="empty.txt: not valid JSON"),
        (["navigation", "--table", "{inf_table}"], "non-finite number Infinity"),
        (["navigation", "--table", "{huge_table}"], "number 1e400 is too large"),
        (["navigation", "--table", "{float_gait}"], "gait must be an integer 0-15, got 2.7"),
        (["navigation", "--table", "{big_F}"], "gait 0 has F = 1.7e+308, beyond the physical"),
        (["navigation", "--table", "{string_F}"], "F must be a number, got '11.6'"),
        (["navigation", "--table", "{list_json}"], "not a gait-table file"),
        (["navigation", "--table", "{deep_json}"], "deep.json: not a valid gait-table file"),
        *_ga_cases("navigation"),
        *_out_cases("navigation"),
        (["navigation", "--out", "{chrom16}/sub"], "c16.txt/sub: cannot write there (Not a"),
        *_file_cases("coverage", "--navigation", what="chromosome file"),
        (["coverage", "--navigation", "{chrom7}"], "expected 8 or 16 genes, found 7"),
        (["colony", "--robots", "0", "--navigation", "{chrom8}"], "--robots must be an integer"),
        (["navigation", "--robots", "3"], "--robots is an option of the colony stage"),
        (["coverage", "--nav-start-power", "3.99"], "--nav-start-power is an option of the nav"),
        (["navigation", "--nav-start-power", "0"], "start_power_v must be a voltage > 0"),
        (["navigation", "--nav-dock-tol", "0"], "dock_heading_tol_deg must be an angle"),
        *_file_cases("navigation", "--nav-starts", what="poses file"),
        (["navigation", "--nav-starts", "{chrom8}"], "c8.txt: line 1: the header lacks column"),
        (["coverage", "--nav-starts", "{chrom8}"], "--nav-starts is an option of the navigati"),
        (["coverage", "--nav-dock-tol", "20"], "--nav-dock-tol is an option of the navigation"),
        (["colony", "--navigation", "{binary}"], "binary.bin: holds binary data"),
    ],
    "anytime": [
        ([], "the following arguments are required: --navigation"),
        *_file_cases("--navigation", what="chromosome file"),
        (["--navigation", "{chrom7}"], "expected 8 or 16 genes, found 7"),
        (["--navigation", "{chrom8}", "--table", "{inf_table}"], "non-finite number Infinity"),
        (["--navigation", "{chrom8}", "--method", "fast"], "argument --method: invalid choice"),
        (["--navigation", "{chrom8}", "--every", "0"], "--every must be an integer ≥ 1, got 0"),
        (["--navigation", "{chrom8}", "--top", "0"], "--top must be an integer ≥ 1, got 0"),
        (["--navigation", "{chrom8}", "--physics-starts", "-2"], "--physics-starts must be an"),
        (["--navigation", "{chrom8}", "--physics-steps", "0"], "--physics-steps must be an"),
        (["--navigation", "{chrom8}", "--final-starts", "0"], "--final-starts must be an"),
        (["--navigation", "{chrom8}", "--physics-steps", "1000000000000"], "physics runs"),
        *_ga_cases("--navigation", "{chrom8}"),
        *_range_cases("--navigation", "{chrom8}", options=("--workers",)),
        (["--navigation", "{chrom8}", "--executor", "cloud"], "executor must be serial"),
        (["--navigation", "{chrom8}", "--model", "{dir}"], "--model {dir}: is a folder, not a"),
        (["--navigation", "{chrom8}", "--baseline", "{dir}"], "no such anytime summary"),
        (["--navigation", "{chrom8}", "--baseline", "{bias_run}"], "must be a --method none run"),
        *_out_cases("--navigation", "{chrom8}"),
    ],
    "trace": [
        *_file_cases(what="chromosome file", then=START),
        *_text_cases(empty="expected 8 or 16 genes, found 0", then=START),
        (["{chrom8}", "--start", "nan", "250", "0"], "--start must be finite"),
        (["{chrom8}", "--start", "250", "250", "1e400"], "--start must be finite"),
        (["{chrom8}", "--start", "250", "250", "0", "--steps", "10000000000000"], "--steps"),
        (["{chrom8}", "--start", "250", "250", "0", "--table", "{inf_table}"], "Infinity"),
        (["{chrom8}", "--start", "250", "250", "0", "--rrd", "{dir}"], "--rrd"),
        (["{chrom8}", "--start", "250", "250", "0", "--rrd", "/proc/x/t.rrd"], "--rrd"),
        (
            ["{chrom8}", "--start", "250", "250", "0", "--rrd", "{dir}/" + "x" * 250 + ".rrd"],
            "File name too long",
        ),  # fmt: skip
    ],
    "validate": [
        *_file_cases(what="chromosome file"),
        (["{latin1}"], "latin1.txt: is not UTF-8 text"),
        (["{chrom8}", "--robots", "2"], "needs a full 16-gene chromosome"),
        (["{chrom16}", "--blocking", "slide"], "--blocking is an option of a colony"),
        (["{chrom16}", "--robots", "2", "--blocking", "bounce"], "invalid choice: 'bounce'"),
        (["{chrom16}", "--poses", "{chrom16}"], "--poses: only for an 8-gene navigation section"),
        *_file_cases("{chrom8}", "--poses", what="poses file"),
        (["{chrom8}", "--poses", "{chrom8}"], "the header lacks column(s) x, y, h"),
        *_range_cases("{chrom16}", options=("--seed", "--starts", "--steps", "--workers")),
        (["{chrom16}", "--seed", "-1", "--start", "400", "250", "90"], "--seed must be"),
        (["{chrom16}", "--noise", "1e300"], "--noise must be a number between 0 and"),
        (["{chrom16}", "--noise", "nan"], "--noise must be a number between 0 and"),
        (["{chrom16}", "--table", "{huge_table}"], "number 1e400 is too large"),
        (["{chrom16}", "--table", "{deep_meta}"], "nested more than 64 deep"),
        *_out_cases("{chrom16}"),
        (["{chrom16}", "--robots", "0"], "--robots must be an integer ≥ 1, got 0"),
        (["{chrom16}", "--robots", "-3"], "--robots must be an integer ≥ 1, got -3"),
        (["{chrom16}", "--robots", "400"], "--robots 400: cannot place robot"),
        (["{chrom16}", "--robots", "1000000000", "--starts", "2"], "--robots 1000000000"),
        (["{chrom16}", "--robots", "2", "--start", "300", "300", "0"], "2 at a time"),
        (
            "{chrom16} --robots 2 --start 300 300 0 --start 310 300 0".split(),
            "robots 0 and 1 are 10 units apart",
        ),
        (
            "{chrom16} --robots 2 --start 300 300 0 --start 10 300 0".split(),
            "start 0, robot 1: start (10, 300) lies in the kill zone",
        ),
    ],
    "robustness": [
        *_file_cases(what="chromosome file"),
        (["{chrom16}", "--worlds", "shipped,moon"], "'moon' is neither a built-in world"),
        (["{chrom16}", "--worlds", "{dir}"], "a_folder' is neither a built-in world"),
        *_range_cases("{chrom16}", options=("--seed", "--starts", "--steps", "--workers")),
        (["{chrom16}", "--executor", "cloud"], "executor must be serial"),
        (["{chrom16}", "--table", "{inf_table}"], "non-finite number Infinity"),
        *_out_cases("{chrom16}"),
    ],
    "calibrate": [
        *_file_cases("--params", what="gait-parameter file"),
        (["--params", "{inf_table}"], "non-finite number Infinity"),
        (["--params", "{list_json}"], "not a gait-parameter file"),
        (["--params", "{bad_params}"], "params.json: malformed gait-parameter file"),
        (["--cycles", "1000000000"], "would run for at least"),
        (["--fit", "--fit-evals", "1000000000"], "would run for at least"),
        (["--noise", "inf"], "--noise must be a number between 0 and"),
        *_range_cases(options=("--seed", "--workers")),
        *_out_cases(),
        (["--rrd", "{dir}"], "--rrd"),
        (["--fit", "--params-out", "{dir}"], "--params-out"),
    ],
    "reproduce": [
        *_range_cases(options=("--seed",)),
        (["--workers", "0"], "--workers must be an integer between 1"),
        (["--validate-starts", "1000000000"], "the reproduction's budgets need"),
        *_out_cases(),
        (["--model", "{dir}"], "--model {dir}: is a folder, not a robot model file"),
        (["--envelope", "{list_json}"], "list.json: an envelope is a JSON object"),
        (["--envelope", "{binary}"], "binary.bin"),
    ],
    "variant": [
        (["--torso-mass", "-1", "--out", "{dir}/v.xml"], "--torso-mass must be a finite number"),
        (["--leg-length", "nan", "--out", "{dir}/v.xml"], "--leg-length must be a finite number"),
        (["--out", "{dir}"], "--out"),
        *_file_cases("--show", what="model file"),
        (["--show", "{chrom16}"], "c16.txt: MuJoCo cannot compile it"),
    ],
    "compare": [
        (["paper"], "compare needs two or more gait tables, got 1"),
        (["paper", "{inf_table}"], "non-finite number Infinity"),
        (["paper", "{dir}"], "is a folder, not a gait-table file"),
        (["paper", "paper", "--labels", "a"], "1 labels for 2 tables"),
        (["paper", "paper", "--out", "{chrom16}"], "is a file, not a folder"),
    ],
}
PARAMS = [(cmd, argv, msg) for cmd, cases in CASES.items() for argv, msg in cases]


def _run(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    try:
        code = servobot(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    return code, capsys.readouterr().err


def _fill(command: str, argv: list[str], files: dict[str, Path], tmp: Path) -> list[str]:
    """``argv`` with the files filled in and, for a command with one, an ``--out`` in ``tmp``."""
    args = [a.format(**{k: str(v) for k, v in files.items()}) for a in argv]
    if command not in ("trace", "variant") and "--out" not in args:
        args += ["--out", str(tmp / "out")]
    return [command, *args]


@pytest.mark.parametrize(("command", "argv", "message"), PARAMS, ids=[
    f"{c}-{i}" for c, cases in CASES.items() for i in range(len(cases))
])  # fmt: skip
def test_bad_input_exits_2_naming_the_problem(command, argv, message, files, tmp_path, capsys):
    code, err = _run(_fill(command, argv, files, tmp_path), capsys)
    assert code == 2, err
    assert message.format(**{k: str(v) for k, v in files.items()}) in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists() or not any(
        p.name != ".lock" for p in (tmp_path / "out").rglob("*") if p.is_file()
    )


def test_bom_and_crlf_are_accepted(files, tmp_path, capsys):
    bom = tmp_path / "bom.txt"
    bom.write_bytes(b"\xef\xbb\xbf" + (GENE * 8).replace("\n", "\r\n").encode())
    code, _ = _run(["trace", str(bom), "--start", "250", "250", "0", "--steps", "2"], capsys)
    assert code == 0
    table = tmp_path / "bom.json"
    table.write_bytes(b"\xef\xbb\xbf" + json.dumps(table_to_json(PAPER_TABLE)).encode())
    code, err = _run(
        ["trace", str(bom), "--start", "250", "250", "0", "--steps", "2", "--table", str(table)],
        capsys,
    )
    assert code == 0, err


@pytest.mark.skipif(ROOT_USER, reason="root reads and writes regardless of permissions")
def test_unreadable_input_and_read_only_out(files, tmp_path, capsys):
    secret = tmp_path / "secret.txt"
    secret.write_text(GENE * 8)
    secret.chmod(0)
    code, err = _run(["trace", str(secret), "--start", "250", "250", "0"], capsys)
    assert code == 2 and "permission denied" in err and "Traceback" not in err
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    code, err = _run(["evolve", "navigation", "--out", str(ro / "x")], capsys)
    assert code == 2 and "cannot write there" in err


# --------------------------------------------------------------------------- run folders

TINY = ["--populations", "1", "--population-size", "4", "--generations", "2", "--no-progress"]


def test_a_folder_of_another_run_is_refused_before_anything_is_touched(tmp_path, capsys):
    out = str(tmp_path)
    assert _run(["evolve", "navigation", *TINY, "--out", out], capsys)[0] == 0
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    for extra in ([], ["--resume"]):
        code, err = _run(["evolve", "navigation", *TINY, "--seed", "7", "--out", out, *extra],
                         capsys)  # fmt: skip
        assert code == 2 and "GASettings.seed: 0 there, 7 here" in err and "--force" in err
        assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    # the same settings without --resume: refused too (finished work is never redone by
    # accident), with --resume: a no-op
    code, err = _run(["evolve", "navigation", *TINY, "--out", out], capsys)
    assert code == 2 and "already holds this run" in err
    assert _run(["evolve", "navigation", *TINY, "--out", out, "--resume"], capsys)[0] == 0
    # --force clears only the run's files: a user's file stays
    note = tmp_path / "navigation" / "my-notes.txt"
    note.write_text("keep me")
    args = ["evolve", "navigation", *TINY, "--seed", "7", "--out", out, "--force"]
    assert _run(args, capsys)[0] == 0
    assert note.read_text() == "keep me"
    record = json.loads((tmp_path / "navigation" / RECORD_FILE).read_text())
    assert record["GASettings"]["seed"] == 7


def _hold_lock(folder: str, ready, release) -> None:
    from infra.rundir import folder_lock

    with folder_lock(Path(folder)):
        ready.set()
        release.wait(30)


def test_a_folder_in_use_is_refused(tmp_path, capsys):
    folder = tmp_path / "navigation"
    folder.mkdir()
    ctx = mp.get_context("spawn")
    ready, release = ctx.Event(), ctx.Event()
    holder = ctx.Process(target=_hold_lock, args=(str(folder), ready, release))
    holder.start()
    try:
        assert ready.wait(60)
        code, err = _run(["evolve", "navigation", *TINY, "--out", str(tmp_path)], capsys)
        assert code == 2 and "is in use by another run (pid" in err and "Traceback" not in err
        assert not (folder / RECORD_FILE).exists()
    finally:
        release.set()
        holder.join(30)
    assert _run(["evolve", "navigation", *TINY, "--out", str(tmp_path)], capsys)[0] == 0


def test_validation_of_other_inputs_is_refused_and_force_leaves_no_stale_recording(
    tmp_path, capsys
):
    chromosome = tmp_path / "c.txt"
    chromosome.write_text(GENE * 16)
    out = tmp_path / "val"
    args = ["validate", str(chromosome), "--steps", "2", "--workers", "1", "--rrd",
            "--no-progress", "--out", str(out)]  # fmt: skip
    two = ["--start", "400", "250", "90", "--start", "380", "200", "0"]
    assert _run([*args, *two], capsys)[0] == 0
    assert (out / "run1.rrd").exists()
    one = ["--start", "400", "250", "90"]
    code, err = _run([*args, *one], capsys)
    assert code == 2 and "holds a run made with other settings (starts:" in err
    assert (out / "run1.rrd").exists() and (out / "report.json").exists()
    assert _run([*args, *one, "--force"], capsys)[0] == 0
    assert sorted(p.name for p in out.glob("run*.rrd")) == ["run0.rrd"]  # run1.rrd was stale
    assert len(json.loads((out / "report.json").read_text())["runs"]) == 1
