"""Cooperative coevolution of a colony's sections (``evolve.coevolution``,
``ColonySettings.sections = "team"``): the cooperative fitness on a hand-made pair, the
partners each generation meets, resume bit for bit, a process pool, the stage's files, and
bad input named."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER, G, chrom, gene
from test_colony_stage import assert_resumes_bit_for_bit
from test_stages import _files

from evolve import evaluate, evaluate_colony
from evolve.codec import format_chromosome, parse_chromosome, read_chromosome
from evolve.coevolution import TeamRun, evaluate_team, role_stage
from evolve.colony_stage import colony_stage, run_colony_stage
from evolve.interpreter import END_KILL_ZONE
from evolve.population import StageError, evaluate_sections, stage_seeds
from evolve.settings import ColonySettings, GASettings, SettingsError, WorldSettings
from evolve.starts import colony_starts
from evolve.table import load_table
from infra.errors import InputError
from infra.executors import ProcessExecutor

WORLD = WorldSettings()
TABLE = load_table("paper")
NAV = parse_chromosome(LIGHT_FOLLOWER)
TEAM = ColonySettings(sections="team")
TINY = GASettings(populations=2, population_size=8, generations=18, starts_per_generation=4,
                  test_starts=6, seed=5)  # fmt: skip
"""18 generations: checkpoints at 0 and 16, saves at 0, 1 and 18."""
WALK = chrom(gene("00", G(0), G(0), G(0), G(0)), n=8)
"""A section that walks gait 0 (nearly straight, 11.6 units a cycle) for ever."""
STAND = chrom(n=8)
"""A section that stands still for ever (gait 7: no motion, no power in the paper's model)."""


def test_the_cooperative_fitness_of_a_hand_made_pair():
    """Two robots far apart: WALK from (400, 250) curves (−1.3° a cycle) into the kill zone
    after 21 cycles, its x falling steadily to 329.5, so it never reaches square (2, 2) of
    STAND at (125, 125), whose first step marks that square (its centre within 19 of the
    square's). The pair's colony reaches the walker's squares alone + 1, whichever robot is
    evaluated and whichever the partner; the shared colony of WALK is another number."""
    pair = ColonySettings(robots=2)
    stage = colony_stage(WORLD, pair, NAV)
    starts = np.array([[[400.0, 250.0, 0.0], [125.0, 125.0, 0.0]]])
    lone = evaluate(stage.genomes(WALK[None]), starts[:, 0], table=TABLE.values,
                    mode="coverage")  # fmt: skip
    assert lone.end[0, 0] == END_KILL_ZONE and lone.steps[0, 0] == 21
    assert lone.final_pose[0, 0, 0] == pytest.approx(329.5, abs=0.1)
    want = lone.squares[0, 0] + 1
    walker_stage = role_stage(stage, np.stack([STAND, STAND]), 0)
    stander_stage = role_stage(stage, np.stack([WALK, WALK]), 1)
    as_walker = evaluate_sections(WALK[None], starts, walker_stage, TABLE, WORLD)[0]
    as_stander = evaluate_sections(STAND[None], starts, stander_stage, TABLE, WORLD)[0]
    team = evaluate_team(np.stack([WALK, STAND]), starts, stage, TABLE, WORLD)
    assert as_walker[0, 0] == as_stander[0, 0] == team.squares[0, 0] == want
    assert team.inner_squares[0, 0] == lone.inner_squares[0, 0] + 1  # (2, 2) is inner
    shared = evaluate_colony(stage.genomes(WALK[None]), starts, table=TABLE.values,
                             mode="coverage", colony=pair)  # fmt: skip
    assert shared.squares[0, 0] != want


@pytest.fixture(scope="module")
def team_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("team")
    return out, run_colony_stage(out, navigation=NAV, table=TABLE, ga=TINY, colony=TEAM)


def test_each_generation_meets_the_team_of_the_last(team_run):
    """Generation g's team is its best evaluated colony: the partners it ran with, robot r*
    carrying the best of the population whose best scored highest. Population r's
    individuals in generation g + 1 run with robot j ≠ r carrying row j of that team
    (redone independently from the saved files), and each population keeps its best."""
    out, _ = team_run
    folder = out / "colony"
    stage = colony_stage(WORLD, TEAM, NAV)
    for t in (0, 1):
        gen0 = np.load(folder / f"populations/pop{t}_gen0000.npz")
        gen1 = np.load(folder / f"populations/pop{t}_gen0001.npz")
        fit, pops = gen0["fitness"], gen0["populations"]
        top = int(np.argmax(fit.max(axis=1)))
        want = pops[:, 0].copy()  # generation 0's partners: each population's individual 0
        want[top] = pops[top][np.argmax(fit[top])]
        np.testing.assert_array_equal(gen0["team"], want)
        for r in range(3):
            np.testing.assert_array_equal(gen1["populations"][r][0], pops[r][np.argmax(fit[r])])
            ev = evaluate_colony(
                stage.genomes(gen1["populations"][r]), gen1["starts"], table=TABLE.values,
                mode="coverage", partners=stage.genomes(gen0["team"]), role=r,
            )  # fmt: skip
            np.testing.assert_allclose(ev.squares.mean(axis=1), gen1["fitness"][r])
        ev = evaluate_colony(
            stage.genomes(pops[1]), gen0["starts"], table=TABLE.values, mode="coverage",
            partners=stage.genomes(pops[:, 0]), role=1,
        )  # fmt: skip
        np.testing.assert_allclose(ev.squares.mean(axis=1), fit[1])


def test_the_team_stage_files_and_final_test(team_run):
    out, summary = team_run
    folder = out / "colony"
    assert summary["settings"]["ColonySettings"]["sections"] == "team"
    test_seq, _ = stage_seeds(TINY.seed, "colony", TINY.populations)
    starts = colony_starts(np.random.Generator(np.random.PCG64(test_seq)), TINY.test_starts,
                           WORLD, TEAM)  # fmt: skip
    for t in (0, 1):
        team = np.stack([read_chromosome(folder / f"best_pop{t}_robot{r}.txt") for r in range(3)])
        np.testing.assert_array_equal(team[:, 8:], np.broadcast_to(NAV, (3, 8, 30)))
        ev = evaluate_colony(team[:1], starts, table=TABLE.values, mode="coverage",
                             partners=team, role=0)  # fmt: skip
        final = summary["final_test"][t]
        assert final["colony_inner_percent"] == pytest.approx(100 * ev.inner_squares[0].mean() / 64)
        assert final["colony_inner_percent"] == pytest.approx(summary["final_inner_percent"][t])
        assert final["docks_per_robot"] == pytest.approx(ev.docks[0].mean())
        hist = np.loadtxt(folder / f"history_pop{t}_robot2.csv", delimiter=",", skiprows=1)
        assert hist.shape == (TINY.generations + 1, 5)
        assert (folder / f"figure10_pop{t}.png").stat().st_size > 10_000


def test_resume_after_interruption_equals_uninterrupted_run(team_run, tmp_path):
    assert_resumes_bit_for_bit(team_run[0], tmp_path, "pop1_team.npz", ga=TINY, colony=TEAM)


def test_teams_in_a_process_pool_give_the_same_files(team_run, tmp_path):
    ref, _ = team_run
    run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, colony=TEAM,
                     executor=ProcessExecutor(2))  # fmt: skip
    assert _files(ref / "colony") == _files(tmp_path / "colony")


def test_a_corrupt_team_checkpoint_is_named(tmp_path):
    stage = colony_stage(WORLD, TEAM, NAV)
    _, seeds = stage_seeds(0, "colony", 1)
    kw = dict(robots=3, seed_seq=seeds[0], table=TABLE, ga=TINY, world=WORLD,
              settings_text="s", resume=True)  # fmt: skip
    ckpt = tmp_path / "checkpoints" / "pop0_team.npz"
    ckpt.parent.mkdir()
    ckpt.write_bytes(b"not a zip")
    with pytest.raises(StageError, match="pop0_team.npz: corrupt team checkpoint"):
        TeamRun(0, stage, tmp_path, **kw)
    run = TeamRun(0, stage, tmp_path, **(kw | {"resume": False}))
    run.step()  # generation 0 writes the checkpoint
    TeamRun(0, stage, tmp_path, **kw)  # reads back
    with pytest.raises(StageError, match="different settings"):
        TeamRun(0, stage, tmp_path, **(kw | {"settings_text": "other"}))


def test_sections_setting_is_checked_and_recorded_only_when_team():
    with pytest.raises(SettingsError, match="sections must be one of 'shared', 'team'"):
        ColonySettings(sections="each")
    assert "sections" not in ColonySettings().to_dict()
    assert ColonySettings(sections="team").to_dict()["sections"] == "team"
    assert dataclasses.replace(TEAM, sections="shared") == ColonySettings()


def test_the_cli_takes_sections_for_the_colony_only(tmp_path, capsys):
    from servobot.cli import main

    common = ["--populations", "1", "--generations", "2", "--population-size", "4",
              "--starts-per-generation", "2", "--out", str(tmp_path)]  # fmt: skip
    assert main(["evolve", "coverage", "--sections", "team", *common]) == 2
    assert "--sections is an option of the colony stage" in capsys.readouterr().err
    assert main(["evolve", "colony", "--team-from", str(tmp_path), *common]) == 2
    assert "--team-from is an option of the colony stage with --sections team" in (
        capsys.readouterr().err
    )
    nav = tmp_path / "nav.txt"
    nav.write_text(LIGHT_FOLLOWER)
    assert main(["evolve", "colony", "--sections", "team", "--navigation", str(nav),
                 *common]) == 0  # fmt: skip
    summary = json.loads((tmp_path / "colony/summary.json").read_text())
    assert summary["settings"]["ColonySettings"]["sections"] == "team"
    assert (tmp_path / "colony/best_pop0_robot2.txt").exists()


def test_a_team_in_physics_each_robot_runs_its_own_chromosome(tmp_path):
    """Robot 0 carries the DOCKER, robot 1 a chromosome that stands still, side by side
    facing the station on low power: in both worlds robot 0 docks and robot 1 neither moves
    nor docks, where in the shared DOCKER colony robot 1 walks to the station too and waits
    there; the report and the recording carry the team."""
    from test_colony_validate import AT_STATION, LOW, STEPS
    from test_physics_colony import DOCKER
    from test_recording import Rrd

    from servobot.validation.colony import validate_colony

    team = np.stack([DOCKER, chrom()])
    rep = validate_colony(team, AT_STATION, table=TABLE.values, world=LOW, workers=1,
                          max_steps=STEPS, out_dir=tmp_path, rrd=True)  # fmt: skip
    (run,) = rep["runs"]
    assert run["error"] is None
    for world in ("table", "physics"):
        docker, still = run[world]["robots"]
        assert docker["docks"] >= 1 and still["docks"] == 0, world
        np.testing.assert_allclose(still["final_pose"][:2], AT_STATION[0, 1, :2], atol=1.5)
    assert "# robot 1\n" in rep["chromosome"]
    ev = evaluate_colony(team[:1], AT_STATION, table=TABLE.values, mode="coverage", settings=LOW,
                         start_power=LOW.start_power_v, max_steps=STEPS,
                         colony=ColonySettings(robots=2), partners=team, role=0)  # fmt: skip
    assert run["table"]["colony"]["squares"] == ev.squares[0, 0]
    assert [b["docks"] for b in run["table"]["robots"]] == ev.docks[0, 0].tolist()
    text = Rrd(tmp_path / "run0.rrd").static_column("/__properties/chromosome", "text")[0][0]
    assert text == rep["chromosome"]
    shared = validate_colony(DOCKER, AT_STATION, table=TABLE.values, world=LOW, workers=1,
                             max_steps=STEPS)  # fmt: skip
    for world in ("table", "physics"):  # robot 1 walks to the station and is refused there
        assert shared["runs"][0][world]["robots"][1]["station_waits"] > 0, world
        assert run[world]["robots"][1]["station_waits"] == 0, world


@pytest.mark.parametrize(
    ("files", "robots", "message"),
    [
        (2, "3", "give 1 file or 3, one per robot"),
        (3, None, "give 1 file (a team needs --robots)"),
    ],
)
def test_validate_refuses_a_team_of_the_wrong_size(tmp_path, capsys, files, robots, message):
    from servobot.cli import main

    paths = []
    for r in range(files):
        paths.append(tmp_path / f"r{r}.txt")
        paths[-1].write_text(format_chromosome(np.concatenate([chrom(n=8), NAV])))
    extra = [] if robots is None else ["--robots", robots]
    assert main(["validate", *map(str, paths), *extra, "--out", str(tmp_path / "v")]) == 2
    assert message in capsys.readouterr().err


def test_a_team_started_from_a_shared_run(tmp_path):
    """``--team-from``: team t's every population starts as the shared run's final population
    t, best first, and every robot's first partner is that best; the source is recorded by
    its SHA-256, so a resume from other populations is refused; bad sources are named."""
    from evolve.coevolution import shared_populations

    ga = dataclasses.replace(TINY, generations=2)
    run_colony_stage(tmp_path / "shared", navigation=NAV, table=TABLE, ga=ga)
    initial = shared_populations(tmp_path / "shared", ga)
    final = np.load(tmp_path / "shared/colony/checkpoints/pop1_final.npz")
    np.testing.assert_array_equal(initial[1][0], final["best"])
    assert sorted(map(bytes, initial[1])) == sorted(map(bytes, final["population"]))
    run_colony_stage(tmp_path / "team", navigation=NAV, table=TABLE, ga=ga, colony=TEAM,
                     team_from=initial)  # fmt: skip
    gen0 = np.load(tmp_path / "team/colony/populations/pop1_gen0000.npz")
    for r in range(3):
        np.testing.assert_array_equal(gen0["populations"][r], initial[1])
    stage = colony_stage(WORLD, TEAM, NAV)
    ev = evaluate_colony(
        stage.genomes(initial[1]), gen0["starts"], table=TABLE.values, mode="coverage",
        partners=stage.genomes(np.repeat(initial[1][:1], 3, axis=0)), role=2,
    )  # fmt: skip
    np.testing.assert_allclose(ev.squares.mean(axis=1), gen0["fitness"][2])
    doc = json.loads((tmp_path / "team/colony/settings.json").read_text())
    assert len(doc["team_from_sha256"]) == 64
    other = initial.copy()
    other[0, 0, 0, 0] ^= 1
    with pytest.raises(InputError, match="team_from_sha256"):
        run_colony_stage(tmp_path / "team", navigation=NAV, table=TABLE, ga=ga, colony=TEAM,
                         team_from=other, resume=True)  # fmt: skip
    with pytest.raises(StageError, match="pop0_final.npz: no such file; --team-from needs"):
        shared_populations(tmp_path / "team", ga)
    with pytest.raises(StageError, match="a population of 8, but this team stage's"):
        shared_populations(tmp_path / "shared", dataclasses.replace(ga, population_size=10))
    with pytest.raises(StageError, match="only for a team of sections"):
        run_colony_stage(tmp_path / "x", navigation=NAV, table=TABLE, ga=ga, team_from=initial)
