"""Fuzzing every parser of user files with hypothesis: chromosome text, gait-table JSON, gait
parameters, poses files, settings files (run-folder records, stage markers), checkpoints, robot
model files (MJCF) and executor specs.
Whatever the bytes, a parser returns a valid result or raises its named error (an
``InputError`` whose message names the file) — never anything else."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from evolve.codec import ChromosomeError, parse_chromosome, read_chromosome
from evolve.handoff import read_poses
from evolve.population import PopulationRun, StageError
from evolve.settings import GASettings, WorldSettings
from evolve.stages import navigation_stage
from evolve.table import MAX_STEP_CM, MAX_TURN_DEG, PAPER_TABLE, load_table, table_to_json
from infra.errors import InputError
from infra.executors import ExecutorSpec, ExecutorSpecError, parse_spec
from infra.io import read_json
from infra.rundir import RECORD_FILE, RunDirError, run_folder
from servo_mj.robot.gaits import MAX_TARGET_RAD, GaitLibrary
from servo_mj.robot.model import CheckedModel, check_model
from servo_mj.robot.variant import VariantParams, variant_xml
from servobot.reproduce.run import DONE, read_done

FUZZ = settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
GENE = "01 0100000 0100000 0100000 0100000"

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=12,
)
"""Any JSON value."""
raw_numbers = st.sampled_from(
    ["NaN", "Infinity", "-Infinity", "1e400", "-1e999", "1" + "0" * 5000, "2.7", "1.7e308",
     "-0.0", "true", '"3"', "null", "[]", "{}"]
)  # fmt: skip
"""JSON number texts a hostile or broken file may hold where a number belongs."""


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


def _paths(doc: object, prefix: tuple = ()) -> list[tuple]:
    """Every element's path (keys and indices) in a JSON document, containers included."""
    out = [prefix]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _paths(v, (*prefix, i))
    return out


def _replace(doc: object, path: tuple, value: object) -> object:
    """``doc`` with the element at ``path`` replaced by ``value``."""
    if not path:
        return value
    head, rest = path[0], path[1:]
    if isinstance(doc, dict):
        return {**doc, head: _replace(doc[head], rest, value)}
    return doc[:head] + [_replace(doc[head], rest, value)] + doc[head + 1 :]


def _mutated_json(doc: object) -> st.SearchStrategy[str]:
    """Texts of ``doc`` with one element (anywhere) replaced by any JSON value, any finite
    number, or a raw number text that JSON parsers differ on."""
    paths = st.sampled_from(_paths(doc))
    values = json_values | st.floats(allow_nan=False, allow_infinity=False) | st.integers()
    marker = "__RAW__"
    replaced = st.builds(lambda p, v: json.dumps(_replace(doc, p, v)), paths, values)
    raw = st.builds(
        lambda p, r: json.dumps(_replace(doc, p, marker)).replace(f'"{marker}"', r),
        paths,
        raw_numbers,
    )
    return replaced | raw


def _named(exc: BaseException, path: Path) -> None:
    assert isinstance(exc, InputError), repr(exc)
    assert str(path) in str(exc), str(exc)


# --------------------------------------------------------------------------- chromosomes


chromosome_texts = st.one_of(
    st.text(max_size=300),
    st.text(alphabet="01 #\n\r\t\x0bx\u00a0", max_size=700),
    st.lists(st.sampled_from([GENE, GENE[:-1], GENE + "0", "# note", "", GENE + " # c"]),
             max_size=20).map("\n".join),
)  # fmt: skip


@FUZZ
@given(text=chromosome_texts)
def test_chromosome_text_parses_or_names_the_line(text):
    try:
        bits = parse_chromosome(text, name="fuzz.txt")
    except ChromosomeError as exc:
        assert str(exc).startswith("fuzz.txt")
        assert 0 <= exc.line <= len(text.splitlines())
        return
    assert bits.shape in ((8, 30), (16, 30)) and bits.dtype == np.uint8
    assert set(np.unique(bits)) <= {0, 1}


@FUZZ
@given(data=st.binary(max_size=600) | chromosome_texts.map(lambda t: t.encode("utf-8")),
       bom=st.booleans())  # fmt: skip
def test_chromosome_files_of_any_bytes(scratch, data, bom):
    path = scratch / "chromosome.txt"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + data)
    try:
        bits = read_chromosome(path)
    except Exception as exc:  # noqa: BLE001 - the assertion is on its type
        _named(exc, path)
        return
    assert bits.shape in ((8, 30), (16, 30))


# --------------------------------------------------------------------------- poses files

pose_fields = st.sampled_from(["1", "250.5", "-3", "nan", "inf", "1e400", "x", "", " 7 ", "1,2"])
poses_texts = st.one_of(
    st.text(max_size=200),
    st.lists(st.lists(pose_fields, max_size=6).map(",".join), max_size=8).map(
        lambda rows: "\n".join(["x,y,h,power", *rows])
    ),
    st.lists(st.sampled_from(["x,y,h", "h,x,y,note", "400,250,90", "1,2", "", "a,b,c"]),
             max_size=8).map("\n".join),
)  # fmt: skip


@FUZZ
@given(text=poses_texts, bom=st.booleans())
def test_poses_files_read_or_name_the_file(scratch, text, bom):
    path = scratch / "poses.csv"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode("utf-8"))
    try:
        poses, powers = read_poses(path)
    except Exception as exc:  # noqa: BLE001 - the assertion is on its type
        _named(exc, path)
        return
    assert poses.ndim == 2 and poses.shape[1] == 3 and len(poses) >= 1
    assert np.isfinite(poses).all()
    assert powers is None or (powers.shape == (len(poses),) and np.isfinite(powers).all())


# --------------------------------------------------------------------------- gait tables

TABLE_DOC = table_to_json(PAPER_TABLE, np.full((16, 3), 0.1), cycles=3)


@FUZZ
@given(text=_mutated_json(TABLE_DOC) | st.binary(max_size=200).map(lambda b: b.decode("latin-1")))
def test_gait_table_files_load_or_name_the_file(scratch, text):
    path = scratch / "table.json"
    path.write_text(text, encoding="utf-8")
    try:
        table = load_table(path)
    except Exception as exc:  # noqa: BLE001
        _named(exc, path)
        return
    v = table.values
    assert v.shape == (16, 3) and np.isfinite(v).all()
    assert (np.abs(v[:, :2]) <= MAX_STEP_CM).all() and (np.abs(v[:, 2]) < MAX_TURN_DEG).all()


# --------------------------------------------------------------------------- gait parameters

PARAMS_DOC = GaitLibrary.load().to_dict()


@FUZZ
@given(text=_mutated_json(PARAMS_DOC))
def test_gait_parameter_files_load_or_name_the_file(scratch, text):
    path = scratch / "params.json"
    path.write_text(text, encoding="utf-8")
    try:
        lib = GaitLibrary.load(path)
    except Exception as exc:  # noqa: BLE001
        _named(exc, path)
        return
    for g in range(16):
        frames = lib.frames(g)
        assert np.isfinite(frames).all() and np.abs(frames).max() <= MAX_TARGET_RAD


# --------------------------------------------------------------------------- settings files


@FUZZ
@given(data=st.binary(max_size=200) | _mutated_json({"GASettings": {"seed": 0}}).map(str.encode))
def test_run_folder_records_of_any_bytes(scratch, data):
    folder = scratch / "run"
    folder.mkdir(exist_ok=True)
    (folder / "result.txt").write_text("a result of the run in this folder")
    (folder / RECORD_FILE).write_bytes(data)
    want = {"GASettings": {"seed": 0}}
    try:
        with run_folder(folder, want, owned=["result.txt"], resume=True) as claim:
            assert claim.state == "resumed"
    except RunDirError as exc:
        _named(exc, folder)
        assert (folder / RECORD_FILE).read_bytes() == data  # refused: untouched
        return
    assert json.loads((folder / RECORD_FILE).read_text()) == want


KEY = {"calibration_cycles": 20, "seed": 0}
DONE_DOC = {"settings": KEY, "wall_s": 1.5, "finished_utc": "2024-01-01T00:00:00", "info": {}}


@FUZZ
@given(data=st.binary(max_size=200) | _mutated_json(DONE_DOC).map(str.encode))
def test_stage_markers_of_any_bytes(scratch, data):
    folder = scratch / "stage"
    folder.mkdir(exist_ok=True)
    (folder / DONE).write_bytes(data)
    try:
        doc = read_done(folder, KEY)
    except Exception as exc:  # noqa: BLE001
        _named(exc, folder)
        return
    assert doc["settings"] == KEY and math.isfinite(doc["wall_s"])


@FUZZ
@given(data=st.binary(max_size=300))
def test_json_reader_of_any_bytes(scratch, data):
    path = scratch / "any.json"
    path.write_bytes(data)
    try:
        read_json(path, what="settings file")
    except Exception as exc:  # noqa: BLE001
        _named(exc, path)


# --------------------------------------------------------------------------- anytime records

ANYTIME_GA = GASettings(populations=2, population_size=8, generations=4, test_starts=2)
SECTION = [GENE] * 8


def _punctuation(method: str) -> dict:
    """A punctuation record as ``evolve.anytime`` writes it (2 populations, top 2, M = 2)."""
    tested = [
        {"population": k, "rank": r, "index": r, "section": SECTION, "table_fitness": 10.0 + r,
         "physics_fitness": 5.0, "table_squares": [10, 11], "physics_squares": [5, 5],
         "physics_inner_squares": [3, 3], "physics_ends": ["steps", "steps"], "errors": [],
         "ratio": 0.5}
        for k in range(2) for r in range(2)
    ]  # fmt: skip
    return {
        "generation": 2, "method": method, "starts": [[400.0, 250.0, 10.0], [380.0, 200.0, 0.0]],
        "noise_seed": 7, "tested": tested,
        "bias": {"0": 0.5, "1": 0.25} if method == "bias" else None,
        "table_error": {"F": 1.0, "T": 0.5, "dH": None, "cycles": 40},
        "table_in_use": PAPER_TABLE.tolist(),
        "residual_sum": [[-10.0, 2.0, 1.0]] * 16, "residual_count": [40] * 16,
        "physics_cycles": 80, "physics_runs": 8, "physics_errors": 0, "physics_wall_s": 1.5,
    }  # fmt: skip


@FUZZ
@given(
    method=st.sampled_from(["bias", "model", "none"]),
    data=st.data(),
)
def test_anytime_punctuation_records_of_any_mutation(scratch, method, data):
    """What ``servobot anytime --resume`` replays: a record passes ``load_records`` only if
    every use of it on replay works (biases, the corrected table, the summary)."""
    from evolve.anytime import (
        AnytimeSettings,
        load_records,
        model_table,
        pooled_residuals,
        population_bias,
    )
    from evolve.table import GaitTable
    from servobot.anytime.report import best_curve, punctuation_entry

    text = data.draw(st.binary(max_size=200).map(lambda b: b.decode("latin-1"))
                     | _mutated_json(_punctuation(method)))  # fmt: skip
    folder = scratch / "anytime"
    (folder / "punctuations").mkdir(parents=True, exist_ok=True)
    path = folder / "punctuations" / "gen0002.json"
    path.write_text(text)
    settings = AnytimeSettings(method=method, every=2, top=2, physics_starts=2, min_samples=20)
    base = GaitTable(PAPER_TABLE)
    try:
        records = load_records(folder, (2, 4), ANYTIME_GA, settings, base)
    except Exception as exc:  # noqa: BLE001
        _named(exc, path)
        return
    sections = np.zeros((8, 8, 30), dtype=np.uint8)
    for k in range(2):
        f = population_bias(records, k, 2).factors(sections) if method == "bias" else np.ones(8)
        assert np.isfinite(f).all() and (f >= 0).all() and (f <= 200).all()
    total, count = pooled_residuals(records, 4)
    assert np.isfinite(total).all() and (count >= 0).all()
    table = model_table(base, records, 4, settings).values
    assert np.isfinite(table).all()
    entry = punctuation_entry(records[2])
    assert entry["generation"] == 2
    json.dumps(best_curve(list(records.values())), allow_nan=False)


SUMMARY = {
    "method": "none", "best_by_generation": {"generations": [2, 4],
    "physics_fitness": [5.0, None], "table_fitness": [10.0, 12.5]},
    "final": {"physics_inner_percent": 12.5, "table_inner_percent": 30.0},
    "settings": {"GASettings": {"seed": 0}},
}  # fmt: skip


@FUZZ
@given(data=st.binary(max_size=200) | _mutated_json(SUMMARY).map(str.encode))
def test_anytime_baseline_summaries_of_any_bytes(scratch, data):
    """``--baseline``: a summary passes ``check_summary`` only if the figure can draw it."""
    from servobot.anytime.report import _label
    from servobot.anytime.run import check_summary

    path = scratch / "summary.json"
    path.write_bytes(data)
    try:
        doc = check_summary(read_json(path, what="anytime summary"), path, method="none")
    except Exception as exc:  # noqa: BLE001
        _named(exc, path)
        return
    curve = doc["best_by_generation"]
    for k in ("generations", "physics_fitness", "table_fitness"):
        values = np.array([np.nan if v is None else v for v in curve[k]], dtype=np.float64)
        assert values.shape == (len(curve["generations"]),)
    assert isinstance(_label(doc), str)


# --------------------------------------------------------------------------- checkpoints

GA = GASettings(populations=1, population_size=4, generations=3, test_starts=2)
WORLD = WorldSettings()
SETTINGS_TEXT = '{"fuzz": true}'


CHECKPOINT = {
    "population": np.zeros((GA.population_size, 8, 30), np.uint8),
    "generation": np.int64(0),
    "rng_state": np.str_(json.dumps(np.random.PCG64(1).state)),
    "history": np.zeros((0, 5)),
    "settings": np.str_(SETTINGS_TEXT),
}
"""A valid checkpoint of generation 0 (the fuzzed ones change one array)."""
ODD = [
    np.zeros((2, 8, 30), np.uint8), np.full((4, 8, 30), 2, np.uint8), np.float64(1.5),
    np.int64(-1), np.int64(99), np.int64(2**62), np.array([np.nan, 1.0]), np.zeros((1, 5)),
    np.str_("{not json"), np.str_("[1, 2]"), np.array(["a", "b"]), None,
]  # fmt: skip
"""What may stand in a checkpoint's array (None: the array is missing)."""


def _resume(folder: Path) -> PopulationRun:
    return PopulationRun(0, navigation_stage(WORLD), folder, seed_seq=np.random.SeedSequence(1),
                         table=PAPER_TABLE, ga=GA, world=WORLD, settings_text=SETTINGS_TEXT,
                         resume=True)  # fmt: skip


@FUZZ
@given(key=st.sampled_from(sorted(CHECKPOINT)), odd=st.sampled_from(ODD))
def test_checkpoint_arrays_resume_or_name_the_file(scratch, key, odd):
    folder = scratch / "population"
    ckpt = folder / "checkpoints" / "pop0.npz"
    ckpt.parent.mkdir(parents=True, exist_ok=True)
    arrays = {k: v for k, v in (CHECKPOINT | {key: odd}).items() if v is not None}
    np.savez_compressed(ckpt, **arrays)
    try:
        run = _resume(folder)
    except StageError as exc:
        _named(exc, ckpt)
        return
    assert run.generation == 0 and run.pop.shape == (GA.population_size, 8, 30)


@FUZZ
@given(data=st.binary(max_size=400), cut=st.floats(0.0, 1.0))
def test_checkpoint_files_of_any_bytes_or_truncated(scratch, data, cut):
    folder = scratch / "population"
    ckpt = folder / "checkpoints" / "pop0.npz"
    ckpt.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    np.savez_compressed(buf, **CHECKPOINT)
    raw = buf.getvalue()
    ckpt.write_bytes(data if data else raw[: int(cut * (len(raw) - 1))])
    with pytest.raises(StageError) as info:
        _resume(folder)
    _named(info.value, ckpt)


# --------------------------------------------------------------------------- robot models

MJCF = variant_xml(VariantParams(torso_mass_kg=0.9))
"""A valid one-file ServoBot model (a variant); the fuzzed ones mutate its text."""
MJCF_TOKENS = st.sampled_from(
    ["<", ">", "/>", "</body>", "<body>", '"', "=", "&amp;", "&x;", "<!--", "-->", "nan", "-1",
     "1e400", "<include file=\"/etc/passwd\"/>", '<include file="../x.xml"/>',
     '<include file="missing.xml"/>', "<!DOCTYPE m [<!ENTITY x \"y\">]>", "\x00", "\ufeff",
     "<actuator/>", '<position joint="LF_thrust"/>', "<html>", "\u00e9"]
)  # fmt: skip


def _mutate(text: str, where: float, cut: int, insert: str) -> str:
    i = int(where * len(text))
    return text[:i] + insert + text[i + cut :]


model_texts = st.one_of(
    st.builds(_mutate, st.just(MJCF), st.floats(0.0, 1.0), st.integers(0, 200),
              st.lists(MJCF_TOKENS | st.text(max_size=6), max_size=3).map("".join)),
    st.builds(  # an attribute value replaced
        lambda n, v: MJCF.replace('="', f'="{v} ', 1 + n).replace(f'="{v} ', '="', n),
        st.integers(0, 400), st.sampled_from(["nan", "-1", "1e400", "", "x", "0 0", "1e-300"]),
    ),
)  # fmt: skip


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=model_texts.map(lambda t: t.encode("utf-8", "surrogatepass")) | st.binary(max_size=300))
def test_model_files_load_or_name_the_file(scratch, data):
    """Any mutated MJCF text or bytes: a checked ServoBot model or an ``InputError`` naming
    the file (never MuJoCo's own ValueError, a parser's error or a crash)."""
    path = scratch / "robot.xml"
    path.write_bytes(data)
    try:
        checked = check_model(path, option="--model")
    except Exception as exc:  # noqa: BLE001
        _named(exc, path)
        return
    assert isinstance(checked, CheckedModel) and len(checked.sha256) == 64


# --------------------------------------------------------------------------- executor specs

hosts = st.from_regex(r"[a-z0-9]([a-z0-9-]{0,10}[a-z0-9])?(\.[a-z0-9]{1,5}){0,2}", fullmatch=True)
specs = st.one_of(
    st.text(max_size=30),
    st.text(max_size=30).map("ray:".__add__),
    st.builds(lambda h, p, c: f"ray:{'ray://' if c else ''}{h}:{p}", hosts,
              st.integers(-5, 70000) | st.text(max_size=5), st.booleans()),
    st.sampled_from(["serial", "process", "ray", "ray:auto", "ray:[::1]:6379", "ray:[::1]"]),
)  # fmt: skip


@FUZZ
@given(spec=specs)
def test_executor_specs_parse_or_name_the_problem(spec):
    """Any text: a checked spec that prints back as itself, or ``ExecutorSpecError`` (an
    ``InputError`` and a ``ValueError``) naming it."""
    try:
        parsed = parse_spec(spec)
    except ExecutorSpecError as exc:
        assert isinstance(exc, InputError) and isinstance(exc, ValueError)
        assert repr(spec) in str(exc) or spec in str(exc), str(exc)
        return
    assert isinstance(parsed, ExecutorSpec) and str(parsed) == spec
    assert parse_spec(str(parsed)) == parsed
    if parsed.port is not None:
        assert 1 <= parsed.port <= 65535 and parsed.host
