"""Anytime learning (``evolve.anytime``, ``servobot.anytime.run``, ``servobot anytime``).

The rules on hand-made cases (the fitness bias, the table correction); the lockstep loop with
a fake physics (fast: no MuJoCo) — table-only equals ``servobot evolve coverage``, biases and
corrections are fed back, a resumed run replays its punctuations without physics; then the
command end to end with real, very short physics runs, and its resume.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from run_folder import result_files

from evolve import ga as gaops
from evolve import stages
from evolve.anytime import (
    AnytimeError,
    AnytimeSettings,
    Bias,
    PhysicsRun,
    behaviour,
    bias_rule,
    corrected_table,
    evolve_anytime,
    model_table,
    population_bias,
    predict_disparity,
    punctuation_generations,
    section_keys,
    table_error,
)
from evolve.envelope import DEFAULT, NONE
from evolve.population import PopulationRun
from evolve.settings import GASettings, WorldSettings
from evolve.table import PAPER_TABLE, load_table
from infra.executors import SerialExecutor
from servobot.anytime.run import run_anytime
from servobot.cli import main as servobot

TABLE = load_table("paper")
WORLD = WorldSettings()
NAV = np.zeros((8, 30), dtype=np.uint8)  # all-zero genes: gait 0 forever
STAGE = stages.coverage_stage(WORLD, NAV)
GA = GASettings(populations=2, population_size=8, generations=20, test_starts=4, seed=5)


class Interrupt(Exception):
    """Raised from a callback to simulate a killed run."""


def _sections(n: int, seed: int = 0) -> np.ndarray:
    return gaops.random_sections(np.random.default_rng(seed), n)


def _no_walls(obj):
    """``obj`` without wall-time entries (the only numbers that differ between runs)."""
    if isinstance(obj, dict):
        return {k: _no_walls(v) for k, v in obj.items() if "wall" not in k and k != "resumed"}
    if isinstance(obj, list):
        return [_no_walls(v) for v in obj]
    return obj


def _files(folder):
    """Every result file, JSON without wall times, PNG left out."""
    out = {}
    for rel, v in result_files(folder).items():
        if rel.endswith(".json"):
            v = _no_walls(v if isinstance(v, dict) else json.loads(v))
        out[rel] = v
    return out


# --------------------------------------------------------------------------- the bias rule


def test_ten_in_table_five_in_physics_is_a_bias_of_one_half_and_changes_the_elite():
    """A scores 10 in the table and 5 in physics: b = 0.5. B (9 and 9): b = 1. The untested
    get the mean, 0.75. Biased: A 5, B 9, an untested C of table fitness 8 → 6; B is the elite
    (unbiased, A would be)."""
    b, mean = bias_rule([10.0, 9.0], [5.0, 9.0])
    assert b.tolist() == [0.5, 1.0] and mean == 0.75
    pop = _sections(3)
    a, bb, c = section_keys(pop)
    bias = Bias({a: 0.5, bb: 1.0}, mean)
    fitness = np.array([10.0, 9.0, 8.0])
    biased = fitness * bias.factors(pop)
    assert biased.tolist() == [5.0, 9.0, 6.0]
    ga = GASettings()
    assert (gaops.next_generation(pop, fitness, np.random.default_rng(0), ga)[0] == pop[0]).all()
    assert (gaops.next_generation(pop, biased, np.random.default_rng(0), ga)[0] == pop[1]).all()


def test_one_tested_genome_cannot_bias_selection():
    """With T = 1 the tested genome's b is also the mean: every individual is scaled alike,
    and roulette on fitness^1.5 (and the elite) are scale-invariant — the next generation is
    bit for bit the unbiased one. Hence T ≥ 2 for method bias."""
    pop = _sections(16, seed=1)
    fitness = np.random.default_rng(2).uniform(1.0, 30.0, 16)
    b, mean = bias_rule([fitness[3]], [0.4 * fitness[3]])
    bias = Bias({section_keys(pop[3:4])[0]: float(b[0])}, mean)
    ga = GASettings()
    plain = gaops.next_generation(pop, fitness, np.random.default_rng(7), ga)
    biased = gaops.next_generation(pop, fitness * bias.factors(pop), np.random.default_rng(7), ga)
    np.testing.assert_array_equal(plain, biased)


def test_bias_guards_a_table_fitness_of_zero_and_failed_physics():
    b, mean = bias_rule([0.0, 4.0, 6.0], [3.0, 2.0, np.nan])
    assert np.isnan(b[0]) and b[1] == 0.5 and np.isnan(b[2]) and mean == 0.5
    b, mean = bias_rule([0.0], [5.0])
    assert np.isnan(b[0]) and mean == 1.0  # nothing measured: no bias


def test_a_tested_genome_keeps_its_bias_wherever_it_survives():
    pop = _sections(4, seed=3)
    bias = Bias({section_keys(pop[2:3])[0]: 2.0}, 0.5)
    later = np.stack([pop[2], pop[0], pop[2], pop[1]])  # moved (as elite) and copied
    assert bias.factors(later).tolist() == [2.0, 0.5, 2.0, 0.5]
    assert Bias().factors(pop).tolist() == [1.0] * 4  # before any punctuation


# --------------------------------------------------------------------------- the correction


def test_a_table_corrected_from_a_known_residual_moves_by_that_residual():
    base = np.asarray(PAPER_TABLE, dtype=float)
    r0, r8 = np.array([-0.5, 0.25, 1.5]), np.array([0.125, -0.75, -2.0])
    total = np.zeros((16, 3))
    count = np.zeros(16, dtype=int)
    total[0], count[0] = 30 * r0, 30  # gait 0: 30 cycles, each off by r0
    total[8], count[8] = 20 * r8, 20
    total[3], count[3] = 19 * np.ones(3), 19  # gait 3: fewer than min_samples
    out = corrected_table(base, total, count, min_samples=20)
    np.testing.assert_array_equal(out[0], base[0] + r0)
    np.testing.assert_array_equal(out[8], base[8] + r8)
    keep = [g for g in range(16) if g not in (0, 8)]
    np.testing.assert_array_equal(out[keep], base[keep])
    # pooled over punctuations: two records of gait 0 with residuals r0 and 3·r0 → 2·r0
    rec = {"residual_sum": total.tolist(), "residual_count": count.tolist()}
    rec2 = {"residual_sum": (total * 3).tolist(), "residual_count": count.tolist()}
    settings = AnytimeSettings(method="model", min_samples=20)
    values = model_table(TABLE, {2: rec, 4: rec2}, 4, settings).values
    np.testing.assert_allclose(values[0], base[0] + 2 * r0, atol=1e-12)
    assert model_table(TABLE, {2: rec}, 1, settings) is TABLE  # not yet: the base table
    assert model_table(TABLE, {2: rec}, 2, dataclasses.replace(settings, method="bias")) is TABLE


def test_table_error_is_against_the_table_in_use():
    base = np.asarray(PAPER_TABLE, dtype=float)
    res = np.array([[1.0, -2.0, 4.0], [1.0, 0.0, 0.0]])  # physics − base, gaits 0 and 0
    in_use = base.copy()
    in_use[0] += [1.0, -1.0, 2.0]
    err = table_error(np.array([0, 0]), res, base, in_use)
    assert err == {"F": 0.0, "T": 1.0, "dH": 2.0, "cycles": 2}


def test_disparity_is_the_mean_of_the_nearest_tested_behaviours():
    archive = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [5.0, 5.0]])
    disparity = np.array([2.0, 4.0, 6.0, 100.0])
    queries = np.array([[0.1, 0.1], [5.0, 5.0], [4.0, 4.0]])
    np.testing.assert_array_equal(predict_disparity(archive, disparity, queries, 1), [2, 100, 100])
    near3 = (100 + 4 + 6) / 3  # (5, 5), then (1, 0) and (0, 1), equally near
    np.testing.assert_allclose(predict_disparity(archive, disparity, queries, 3),
                               [4, near3, near3], rtol=1e-15)  # fmt: skip
    assert predict_disparity(archive, disparity, queries, 9).tolist() == [28.0] * 3  # all four
    tie = predict_disparity(np.array([[1.0], [-1.0]]), np.array([1.0, 3.0]), np.zeros((1, 1)), 1)
    assert tie.tolist() == [1.0]  # equally near: the earlier entry
    assert predict_disparity(np.zeros((0, 0)), np.zeros(0), queries, 3).tolist() == [0.0] * 3


def test_a_behaviour_describes_how_each_run_ends():
    """Per start: squares / 100, inner / 64, end x, y / 500, kill zone, power empty, docks / 10."""
    ev = dataclasses.make_dataclass("Ev", ["squares", "inner_squares", "final_pose", "end",
                                           "docks"])(  # fmt: skip
        np.array([[50, 10]]), np.array([[32, 0]]), np.array([[[250.0, 125.0, 90.0],
        [0.0, 500.0, 0.0]]]), np.array([[1, 2]]), np.array([[5, 0]]),
    )  # fmt: skip
    want = [0.5, 0.5, 0.5, 0.25, 1, 0, 0.5, 0.1, 0, 0, 1, 0, 1, 0]
    np.testing.assert_array_equal(behaviour(ev, WORLD), [want])


def test_settings_refuse_what_cannot_run():
    for bad in (dict(method="fast"), dict(every=0), dict(top=0), dict(physics_starts=-1),
                dict(physics_steps=0), dict(final_starts=0), dict(min_samples=0),
                dict(neighbours=0), dict(descriptor_starts=0),
                dict(station_margin_cm=float("nan"))):  # fmt: skip
        with pytest.raises(AnytimeError, match=next(iter(bad)).split("_")[0]):
            AnytimeSettings(**bad)
    assert punctuation_generations(20, 8) == (8, 16)
    assert punctuation_generations(16, 8) == (8, 16)


# ---------------------------------------------------------------- the loop (fake physics)


class FakePhysics:
    """A 'robot' whose runs score a fixed fraction of the table world's squares (genomes with
    an odd first bit score half), and whose every cycle of gait 0 is 0.5 cm short."""

    def __init__(self):
        self.calls: list[int] = []

    def __call__(self, genomes, starts, seed, base):
        from evolve.evaluation import evaluate

        self.calls.append(len(genomes))
        ev = evaluate(genomes, starts, table=base, mode="coverage", max_steps=30)
        runs = []
        for c, genome in enumerate(genomes):
            factor = 0.5 if genome[0, 0] else 1.0
            for m in range(len(starts)):
                sq = int(ev.squares[c, m] * factor)
                runs.append(PhysicsRun(sq, sq // 2, None, np.zeros(3, dtype=np.int64),
                                       np.tile([-0.5, 0.0, 0.0], (3, 1))))  # fmt: skip
        return runs


def _evolve(folder, method="bias", *, ga=GA, resume=False, tester=None, envelope=NONE, **kw):
    settings = AnytimeSettings(method=method, every=2, top=2, physics_starts=2, physics_steps=30,
                               min_samples=1)  # fmt: skip
    stage = dataclasses.replace(STAGE, extra_settings=(settings,), envelope=envelope)
    return evolve_anytime(
        folder, stage=stage, table=TABLE, ga=ga, world=WORLD, settings=settings,
        test_in_physics=tester or FakePhysics(), settings_text="tiny", resume=resume, **kw,
    )  # fmt: skip


def test_method_none_evolves_exactly_as_evolve_coverage(tmp_path):
    """The control arm measures but feeds nothing back: its populations are the coverage
    stage's with the same seed, generation by generation."""
    ga = dataclasses.replace(GA, generations=6)
    result = _evolve(tmp_path / "none", "none", ga=ga)
    stages.run_coverage(tmp_path / "cov", navigation=NAV, table=TABLE, ga=ga)
    for r in result.results:
        with np.load(tmp_path / f"cov/coverage/checkpoints/pop{r.index}_final.npz") as z:
            np.testing.assert_array_equal(r.best, z["best"])
            np.testing.assert_array_equal(r.history, z["history"])
    assert [rec["generation"] for rec in result.records] == [2, 4, 6]
    assert all(rec["bias"] is None for rec in result.records)


def test_bias_is_fed_back_and_recorded(tmp_path):
    result = _evolve(tmp_path, "bias")
    rec = result.records[0]
    assert len(rec["tested"]) == 2 * 2 and rec["physics_runs"] == 8
    for t in rec["tested"]:
        want = 0.5 if t["section"][0][0] == "1" else 1.0
        if t["table_fitness"] > 0:
            assert t["ratio"] == pytest.approx(want, abs=0.2)  # squares are whole numbers
    for k in (0, 1):
        bias = population_bias({r["generation"]: r for r in result.records}, k, 2)
        assert bias.mean == rec["bias"][str(k)]
    none = _evolve(tmp_path / "none", "none")
    assert [r.best.tolist() for r in result.results] != [r.best.tolist() for r in none.results]


def test_transfer_archives_disparities_and_selects_on_predicted_physics(tmp_path):
    """Every tested genome's behaviour and disparity (table − physics, the same M starts) are
    recorded; genomes the fake physics halves lose fitness to the prediction, so transfer
    learns other controllers than the control; a damaged behaviour is refused on resume."""
    result = _evolve(tmp_path, "transfer")
    for rec in result.records:
        for t in rec["tested"]:
            assert len(t["descriptor"]) == 7 * AnytimeSettings().descriptor_starts
            assert t["disparity"] == t["table_fitness"] - t["physics_fitness"]
            if t["section"][0][0] == "0":  # physics = table for these
                assert t["disparity"] == 0.0
    assert any(t["disparity"] > 0 for rec in result.records for t in rec["tested"])
    none = _evolve(tmp_path / "none", "none")
    assert [r.history.tolist() for r in result.results] != [
        r.history.tolist() for r in none.results
    ]
    path = tmp_path / "punctuations/gen0002.json"
    rec = json.loads(path.read_text())
    rec["tested"][0]["descriptor"][0] = -1.0
    path.write_text(json.dumps(rec))
    with pytest.raises(AnytimeError, match=r"tested\[0\]\.descriptor"):
        _evolve(tmp_path, "transfer", resume=True)


def test_model_corrects_the_table_and_saves_it(tmp_path):
    result = _evolve(tmp_path, "model")
    assert result.table.values[0, 0] == PAPER_TABLE[0, 0] - 0.5  # every gait-0 cycle short
    np.testing.assert_array_equal(result.table.values[1:], PAPER_TABLE[1:])
    tables = sorted((tmp_path / "tables").glob("gen*.json"))
    assert [p.name for p in tables] == [f"gen{g:04d}.json" for g in range(2, 21, 2)]
    assert load_table(tables[-1]).values[0, 0] == PAPER_TABLE[0, 0] - 0.5
    first, second = result.records[0], result.records[1]
    assert first["table_error"]["F"] == 0.5  # against the paper's table
    assert second["table_error"]["F"] == 0.0  # against the corrected one
    assert first["table_in_use"] == PAPER_TABLE.tolist()


def test_resume_replays_its_punctuations_without_physics(tmp_path):
    """Killed at generation 18 (checkpoints at 16), resumed: the same files as an
    uninterrupted run, and physics runs only for the punctuations not yet recorded."""
    ref = _evolve(tmp_path / "ref", "bias")

    def kill_at(rec):
        if rec["population"] == 1 and rec["generation"] == 18:
            raise Interrupt

    with pytest.raises(Interrupt):
        _evolve(tmp_path / "cut", "bias", on_generation=kill_at)
    tester = FakePhysics()
    cut = _evolve(tmp_path / "cut", "bias", resume=True, tester=tester)
    assert len(tester.calls) == 1  # generation 20 only (16 and 18 are on file)
    assert _files(tmp_path / "ref") == _files(tmp_path / "cut")
    assert _no_walls(ref.records) == _no_walls(cut.records)


@pytest.mark.parametrize("method", ["bias", "model", "transfer"])
def test_anytime_in_an_envelope_resumes_bit_for_bit(tmp_path, method):
    """Evolved in the envelope default (SPEC §9): the punctuations' table runs and the model's
    re-evaluations are keyed draws, so a resumed run replays to the same files; and the
    envelope changes what is learned."""
    ref = _evolve(tmp_path / "ref", method, envelope=DEFAULT)

    def kill_at(rec):
        if rec["population"] == 1 and rec["generation"] == 18:
            raise Interrupt

    with pytest.raises(Interrupt):
        _evolve(tmp_path / "cut", method, envelope=DEFAULT, on_generation=kill_at)
    cut = _evolve(tmp_path / "cut", method, envelope=DEFAULT, resume=True)
    assert _files(tmp_path / "ref") == _files(tmp_path / "cut")
    assert _no_walls(ref.records) == _no_walls(cut.records)
    plain = _evolve(tmp_path / "plain", method)
    assert [r.history.tolist() for r in ref.results] != [r.history.tolist() for r in plain.results]


def test_resume_with_populations_at_different_checkpoints(tmp_path, monkeypatch):
    """Killed after population 0 checkpointed generation 16 but before population 1 did:
    population 1 replays 0–15 alone from the records, then both go on in lockstep."""
    _evolve(tmp_path / "ref", "model")
    evaluate = PopulationRun.evaluate

    def dying(self):
        if self.k == 1 and self.generation == 16:
            raise Interrupt
        return evaluate(self)

    monkeypatch.setattr(PopulationRun, "evaluate", dying)
    with pytest.raises(Interrupt):
        _evolve(tmp_path / "cut", "model")
    monkeypatch.setattr(PopulationRun, "evaluate", evaluate)
    for k, g in ((0, 16), (1, 0)):
        with np.load(tmp_path / f"cut/checkpoints/pop{k}.npz") as z:
            assert int(z["generation"]) == g
    tester = FakePhysics()
    _evolve(tmp_path / "cut", "model", resume=True, tester=tester)
    assert len(tester.calls) == 3  # generations 16, 18, 20
    assert _files(tmp_path / "ref") == _files(tmp_path / "cut")


def test_a_record_that_does_not_replay_is_refused(tmp_path):
    def kill_at(rec):
        if rec["population"] == 1 and rec["generation"] == 3:
            raise Interrupt

    with pytest.raises(Interrupt):
        _evolve(tmp_path, "bias", on_generation=kill_at)
    path = tmp_path / "punctuations/gen0002.json"
    rec = json.loads(path.read_text())
    rec["tested"][0]["index"] += 1
    path.write_text(json.dumps(rec))
    with pytest.raises(AnytimeError, match="does not replay"):
        _evolve(tmp_path, "bias", resume=True)
    path.write_text("{}")
    with pytest.raises(AnytimeError, match="gen0002.json: not a punctuation record"):
        _evolve(tmp_path, "bias", resume=True)


# ------------------------------------------------------------------ end to end (physics)

TINY_CLI = ["--populations", "1", "--population-size", "8", "--generations", "4", "--every",
            "2", "--top", "1", "--physics-starts", "1", "--physics-steps", "3",
            "--final-starts", "2", "--executor", "serial", "--no-progress"]  # fmt: skip


@pytest.fixture(scope="module")
def nav_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("nav") / "nav.txt"
    path.write_text("01 0000000 0000000 0000000 0000000\n" * 8)
    return path


def test_servobot_anytime_end_to_end(nav_file, tmp_path, capsys):
    base, run = tmp_path / "none", tmp_path / "model"
    args = ["anytime", "--navigation", str(nav_file), *TINY_CLI]
    assert servobot([*args, "--method", "none", "--out", str(base)]) == 0
    envelope = [*args, "--method", "model", "--out", str(run), "--baseline", str(base),
                "--envelope", "default"]  # fmt: skip
    # in an envelope coverage trains on 30 starts per generation: not the baseline's GA
    assert servobot(envelope) == 2
    assert "GASettings.starts_per_generation: 10 there, 30 here" in capsys.readouterr().err
    code = servobot([*envelope, "--starts-per-generation", "10"])
    assert code == 0, capsys.readouterr().err
    assert "anytime (model): final bests on 2 fresh starts" in capsys.readouterr().out
    folder = run / "anytime"
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["method"] == "model" and summary["physics_runs"] == 2
    assert [p["generation"] for p in summary["punctuations"]] == [2, 4]
    tested = summary["punctuations"][0]["tested"][0]
    assert set(tested) >= {"population", "index", "table_fitness", "physics_fitness"}
    assert set(summary["punctuations"][0]["table_error"]) == {"F", "T", "dH", "cycles"}
    final = summary["final"]
    assert final["starts"] == 2 and final["physics_errors"] == 0
    assert {"table_inner_percent", "physics_inner_percent"} <= set(final)
    assert summary["physics_wall_s"] > 0 and summary["wall_s"] > summary["physics_wall_s"]
    for name in ("best_pop0.txt", "figure_anytime.png", "tables/gen0004.json",
                 "punctuations/gen0002.json", "final/pop0.json", "settings.json"):  # fmt: skip
        assert (folder / name).is_file(), name
    assert summary["baseline"] == str(base)
    settings = json.loads((folder / "settings.json").read_text())
    assert settings["AnytimeSettings"]["physics_steps"] == 3 and settings["model_sha256"]
    assert settings["Envelope"] == DEFAULT.to_dict()  # the populations evolved in it
    assert "Envelope" not in json.loads((base / "anytime" / "settings.json").read_text())
    transfer = tmp_path / "transfer"  # its own settings need not match the baseline's
    code = servobot([*args, "--method", "transfer", "--neighbours", "2", "--descriptor-starts",
                     "2", "--out", str(transfer), "--baseline", str(base)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    rec = json.loads((transfer / "anytime" / "punctuations" / "gen0002.json").read_text())
    assert len(rec["tested"][0]["descriptor"]) == 7 * 2
    kept = json.loads((transfer / "anytime" / "settings.json").read_text())["AnytimeSettings"]
    assert (kept["method"], kept["neighbours"], kept["descriptor_starts"]) == ("transfer", 2, 2)
    assert servobot([*args, "--method", "transfer", "--neighbours", "0",
                     "--out", str(tmp_path / "bad")]) == 2  # fmt: skip
    assert "--neighbours" in capsys.readouterr().err


def test_run_anytime_resumes_after_an_interrupt(nav_file, tmp_path):
    """Interrupted in its third generation, resumed: the same files as an uninterrupted run
    (wall times aside); the finished population's final test is kept, not rerun."""
    from evolve.codec import read_chromosome

    nav = read_chromosome(nav_file)
    kw = dict(navigation=nav, table=TABLE, executor=SerialExecutor(),
              ga=GASettings(populations=1, population_size=8, generations=4, test_starts=2),
              settings=AnytimeSettings(method="bias", every=2, top=2, physics_starts=1,
                                       physics_steps=3, final_starts=1))  # fmt: skip
    run_anytime(tmp_path / "ref", **kw)

    def kill_at(rec):
        if rec["generation"] == 3:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_anytime(tmp_path / "cut", on_generation=kill_at, **kw)
    assert not (tmp_path / "cut/anytime/summary.json").exists()
    ran = []
    run_anytime(tmp_path / "cut", resume=True, on_physics_run=lambda: ran.append(1), **kw)
    assert len(ran) == 2 + 1  # the punctuation at 4 (top 2) and the final test
    assert _files(tmp_path / "ref/anytime") == _files(tmp_path / "cut/anytime")
    ran.clear()
    run_anytime(tmp_path / "cut", resume=True, on_physics_run=lambda: ran.append(1), **kw)
    assert ran == []  # finished: nothing is run again


def test_bench_numbers_on_hand_made_summaries():
    """``servobot.anytime.bench``: the difference from the control, Spearman over the tested,
    and the wall time against the table-only run (the control's table time)."""
    from servobot.anytime.bench import numbers

    def run(method, phys, pairs, table_s, physics_s):
        tested = [{"table_fitness": a, "physics_fitness": b} for a, b in pairs]
        return {
            "method": method, "punctuations": [{"tested": tested}],
            "final": {"physics_inner_percent": phys, "table_inner_percent": 30.0, "gap_pp": 0.0},
            "physics_runs": 2 * len(pairs), "table_wall_s": table_s, "physics_wall_s": physics_s,
            "final_wall_s": 50.0,
        }  # fmt: skip

    pairs = [(10.0, 5.0), (20.0, 6.0), (30.0, 9.0), (40.0, 8.0)]
    arms = numbers({0: {"none": run("none", 30.0, pairs, 10.0, 40.0),
                        "bias": run("bias", 34.0, pairs, 10.0, 2.0)}})  # fmt: skip
    assert arms["bias"]["physics_vs_control_pp"] == 4.0
    assert arms["bias"]["spearman_pooled"] == pytest.approx(0.8)
    assert arms["bias"]["wall_vs_table_only"] == pytest.approx(1.2)  # (10 + 2) / 10
    assert arms["bias"]["wall_vs_table_only_with_final"] == pytest.approx(62 / 60)
    assert arms["bias"]["goal_met"] is True and arms["none"]["goal_met"] is None


def test_bench_evolves_every_method_in_its_envelope(nav_file, tmp_path, monkeypatch):
    """``--envelope`` reaches every arm's run (``none`` first, the others against it); a bad
    envelope file is refused before anything runs."""
    from evolve.envelope import EnvelopeError
    from servobot.anytime import bench

    calls = []
    monkeypatch.setattr(bench, "run_anytime", lambda folder, **kw: calls.append((folder, kw)))
    argv = ["--navigation", str(nav_file), "--out", str(tmp_path), "--methods", "bias",
            "--envelope", "default", "--executor", "serial"]  # fmt: skip
    bench.run_arms(bench.parse_args(argv))
    assert [f.name for f, _ in calls] == ["none", "bias"]
    assert calls[1][1]["settings"].neighbours == AnytimeSettings().neighbours
    assert all(kw["envelope"] == DEFAULT for _, kw in calls)
    bad = tmp_path / "bad.json"
    bad.write_text('{"scatter_scale": -1}')
    with pytest.raises(EnvelopeError, match="scatter_scale"):
        bench.run_arms(bench.parse_args(argv[:-4] + ["--envelope", str(bad)]))
