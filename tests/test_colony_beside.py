"""The colony stage that learns one robot's coverage section beside fixed partners
(``ColonySettings.sections = "beside"``, ``--partners``, ``--beside-robot``; issue 17, a
coverer learned for its team, a liver beside a coverer): a hand-made pair, the fitness every
generation meets redone independently, the finalists' files and final test, a first
generation started from a given section, a middle robot between two different partners,
resume bit for bit, and bad input named."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER
from test_coevolution import STAND, WALK
from test_colony_stage import NAV, TABLE, TINY, WORLD, assert_resumes_bit_for_bit

from evolve import evaluate, evaluate_colony
from evolve.codec import read_chromosome, write_chromosome
from evolve.colony_stage import colony_stage, coverage_section, run_colony_stage
from evolve.interpreter import END_KILL_ZONE
from evolve.population import StageError, evaluate_sections, stage_seeds
from evolve.settings import ColonySettings
from evolve.starts import colony_starts

BESIDE = ColonySettings(sections="beside")


def test_the_last_robot_beside_a_hand_made_partner():
    """Two robots far apart (see ``test_coevolution``'s hand-made pair): robot 0 carries the
    partner, robot 1 the individual. WALK from (400, 250) curves into the kill zone after 21
    cycles without reaching square (2, 2), which STAND at (125, 125) marks on its first step:
    the colony reaches the walker's squares alone + 1, whichever of the two is the partner."""
    pair = ColonySettings(robots=2, sections="beside")
    starts = np.array([[[125.0, 125.0, 0.0], [400.0, 250.0, 0.0]]])
    walker = colony_stage(WORLD, pair, NAV, partners=STAND)
    lone = evaluate(walker.genomes(WALK[None]), starts[:, 1], table=TABLE.values, mode="coverage")
    assert lone.end[0, 0] == END_KILL_ZONE and lone.steps[0, 0] == 21
    got = evaluate_sections(WALK[None], starts, walker, TABLE, WORLD)[0]
    assert got[0, 0] == lone.squares[0, 0] + 1
    # Swapped: the walker is the partner on robot 0's pose, the individual stands on robot 1's.
    swapped = starts[:, ::-1].copy()
    stander = colony_stage(WORLD, pair, NAV, partners=WALK)
    assert evaluate_sections(STAND[None], swapped, stander, TABLE, WORLD)[0][0, 0] == got[0, 0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A tiny shared colony run, then the last robot learned beside its finalist 0."""
    root = tmp_path_factory.mktemp("colony_beside")
    run_colony_stage(root / "shared", navigation=NAV, table=TABLE, ga=TINY)
    partner = coverage_section(root / "shared/colony/best_pop0.txt", NAV)
    beside = run_colony_stage(root / "beside", navigation=NAV, table=TABLE, ga=TINY,
                              colony=BESIDE, partners=partner)  # fmt: skip
    return root, beside, partner


def _team(partner, last):
    """(3, 16, 30): robots 0 and 1 the partner's chromosome, robot 2 ``last`` (8 or 16 genes)."""
    full = np.concatenate([partner, NAV])
    last = last if last.shape[0] == 16 else np.concatenate([last, NAV])
    return np.stack([full, full, last])


def test_every_generation_runs_robot_2_beside_the_partner(runs):
    """Generation 1's fitness redone independently: each individual as robot 2 of the colony
    whose robots 0 and 1 carry the partner, from the generation's starts."""
    root, _, partner = runs
    for k in range(TINY.populations):
        gen1 = np.load(root / f"beside/colony/populations/pop{k}_gen0001.npz")
        pop = gen1["population"]
        for i in (0, 3):
            ev = evaluate_colony(_team(partner, pop[i])[None, 2], gen1["starts"],
                                 table=TABLE.values, mode="coverage",
                                 partners=_team(partner, pop[i]), role=2)  # fmt: skip
            assert ev.squares[0].mean() == pytest.approx(gen1["fitness"][i])


def test_the_finalists_files_and_final_test(runs):
    root, summary, partner = runs
    folder = root / "beside/colony"
    settings = json.loads((folder / "settings.json").read_text())
    assert settings["ColonySettings"]["sections"] == "beside"
    assert settings["partner_section"] == ["".join(map(str, g)) for g in partner.tolist()]
    assert_finalists(folder, summary, lambda best: _team(partner, best), robot=2)


def assert_finalists(folder, summary, team_of, robot):
    """Each finalist's file (robot ``robot``'s section + the stage's navigation) and its final
    test redone: the colony ``team_of(best)`` from the stage's colony test starts, and the
    finalist alone from each start's robot-0 pose."""
    test_seq, _ = stage_seeds(TINY.seed, "colony", TINY.populations)
    starts = colony_starts(np.random.Generator(np.random.PCG64(test_seq)), TINY.test_starts,
                           WORLD, BESIDE)  # fmt: skip
    for k in range(TINY.populations):
        path = folder / f"best_pop{k}.txt"
        best = read_chromosome(path)
        np.testing.assert_array_equal(best[8:], NAV)
        assert f"robot {robot}'s coverage section (learned beside" in path.read_text()
        team = team_of(best)
        ev = evaluate_colony(team[None, 0], starts, table=TABLE.values, mode="coverage",
                             partners=team, role=0)  # fmt: skip
        lone = evaluate(best[None], np.ascontiguousarray(starts[:, 0]), table=TABLE.values,
                        mode="coverage")  # fmt: skip
        final = summary["final_test"][k]
        assert final["colony_inner_percent"] == pytest.approx(100 * ev.inner_squares[0].mean() / 64)
        assert final["colony_inner_percent"] == pytest.approx(summary["final_inner_percent"][k])
        assert final["live_at_end_per_run"] == pytest.approx(ev.live[0].sum(axis=1).mean())
        assert final["one_robot_inner_percent"] == pytest.approx(
            100 * lone.inner_squares[0].mean() / 64
        )


def test_resume_is_bit_for_bit_and_another_partner_is_refused(runs, tmp_path):
    from infra.errors import InputError

    root, _, partner = runs
    assert_resumes_bit_for_bit(root / "beside", tmp_path, "pop1.npz", colony=BESIDE,
                               partners=partner)  # fmt: skip
    other = partner.copy()
    other[0, 0] ^= 1
    with pytest.raises(InputError, match="partner_section"):
        run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, colony=BESIDE,
                         partners=other, resume=True)  # fmt: skip


def test_the_first_generation_starts_as_the_given_section(runs, tmp_path):
    """``first``: every individual of generation 0 carries it, so generation 0's best is it and
    its fitness is that colony's, redone independently; recorded as ``initial_section``."""
    root, _, partner = runs
    first = coverage_section(root / "shared/colony/best_pop1.txt", option="--first")
    ga = dataclasses.replace(TINY, populations=1, generations=2)
    run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=ga, colony=BESIDE,
                     partners=partner, first=first)  # fmt: skip
    gen0 = np.load(tmp_path / "colony/populations/pop0_gen0000.npz")
    assert (gen0["population"] == first).all()
    team = _team(partner, first)
    ev = evaluate_colony(team[None, 0], gen0["starts"], table=TABLE.values, mode="coverage",
                         partners=team, role=0)  # fmt: skip
    np.testing.assert_allclose(gen0["fitness"], ev.squares[0].mean())
    settings = json.loads((tmp_path / "colony/settings.json").read_text())
    assert settings["initial_section"] == ["".join(map(str, g)) for g in first.tolist()]


def test_bad_partners_are_named(runs, tmp_path):
    root, _, partner = runs
    with pytest.raises(StageError, match="given exactly when the colony stage learns one robot's"):
        run_colony_stage(tmp_path / "a", navigation=NAV, table=TABLE, ga=TINY, partners=partner)
    with pytest.raises(StageError, match="given exactly when the colony stage learns one robot's"):
        run_colony_stage(tmp_path / "b", navigation=NAV, table=TABLE, ga=TINY, colony=BESIDE)
    with pytest.raises(StageError, match=r"the partners. section must be an \(8, 30\) array"):
        colony_stage(WORLD, BESIDE, NAV, partners=partner[:7])
    write_chromosome(tmp_path / "eight.txt", NAV)
    with pytest.raises(StageError, match="eight.txt: 8 genes, but --partners takes"):
        coverage_section(tmp_path / "eight.txt", NAV)
    other_nav = np.concatenate([partner, 1 - NAV])
    write_chromosome(tmp_path / "other.txt", other_nav)
    with pytest.raises(StageError, match="other.txt: its navigation section .* differs"):
        coverage_section(tmp_path / "other.txt", NAV)
    with pytest.raises(StageError, match="eight.txt: 8 genes, but --first takes"):
        coverage_section(tmp_path / "eight.txt", option="--first")
    np.testing.assert_array_equal(
        coverage_section(tmp_path / "other.txt", option="--first"), partner
    )  # any navigation: only genes 0–7 are taken
    with pytest.raises(StageError, match="a first section is given only to the colony stage"):
        colony_stage(WORLD, ColonySettings(), NAV, first=partner)
    with pytest.raises(StageError, match=r"the first section must be an \(8, 30\) array of bits"):
        colony_stage(WORLD, BESIDE, NAV, partners=partner, first=partner[:, :29])


def test_the_command_line(runs, tmp_path, capsys):
    from servobot.cli import main

    root, _, partner = runs
    nav = tmp_path / "nav.txt"
    nav.write_text(LIGHT_FOLLOWER)
    common = ["--populations", "1", "--generations", "2", "--population-size", "4",
              "--starts-per-generation", "2", "--navigation", str(nav),
              "--no-progress"]  # fmt: skip
    shared = str(root / "shared/colony/best_pop0.txt")
    assert main(["evolve", "colony", "--sections", "beside", *common,
                 "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    assert "--sections beside needs --partners FILE" in capsys.readouterr().err
    assert main(["evolve", "colony", "--partners", shared, *common,
                 "--out", str(tmp_path / "y")]) == 2  # fmt: skip
    assert "--partners is an option of the colony stage with --sections beside" in (
        capsys.readouterr().err
    )
    assert main(["evolve", "colony", "--first", shared, *common,
                 "--out", str(tmp_path / "w")]) == 2  # fmt: skip
    assert "--first is an option of the navigation and coverage stages and of the colony" in (
        capsys.readouterr().err
    )
    out = tmp_path / "z"
    assert main(["evolve", "colony", "--sections", "beside", "--partners", shared,
                 "--first", shared, *common, "--out", str(out)]) == 0  # fmt: skip
    settings = json.loads((out / "colony/settings.json").read_text())
    assert (
        settings["partner_section"]
        == settings["initial_section"]
        == ["".join(map(str, g)) for g in partner.tolist()]
    )
    np.testing.assert_array_equal(read_chromosome(out / "colony/best_pop0.txt")[8:], NAV)


def test_robot_0_beside_a_hand_made_partner():
    """The hand-made pair with the learned robot first (``robot=0``, the partner given as the
    other robot's section): WALK as robot 0 from (400, 250), STAND as robot 1 at (125, 125),
    reaches the walker's squares alone + 1, as with the walker last."""
    pair = ColonySettings(robots=2, sections="beside")
    starts = np.array([[[400.0, 250.0, 0.0], [125.0, 125.0, 0.0]]])
    walker = colony_stage(WORLD, pair, NAV, partners=STAND[None], robot=0)
    lone = evaluate(walker.genomes(WALK[None]), starts[:, 0], table=TABLE.values, mode="coverage")
    got = evaluate_sections(WALK[None], starts, walker, TABLE, WORLD)[0]
    assert got[0, 0] == lone.squares[0, 0] + 1


@pytest.fixture(scope="module")
def middle(runs, tmp_path_factory):
    """Robot 1 learned beside robot 0 = shared finalist 0 and robot 2 = shared finalist 1."""
    root = runs[0]
    others = np.stack([coverage_section(root / f"shared/colony/best_pop{k}.txt", NAV)
                       for k in (0, 1)])  # fmt: skip
    out = tmp_path_factory.mktemp("colony_beside_middle")
    summary = run_colony_stage(out, navigation=NAV, table=TABLE, ga=TINY, colony=BESIDE,
                               partners=others, robot=1)  # fmt: skip
    return out, summary, others


def test_a_middle_robot_beside_two_different_partners(middle):
    """Generation 1's fitness redone as robot 1 between the two partners' sections; the
    finalists' files, final test (its lone robot the learned one) and the record."""
    out, summary, others = middle
    folder = out / "colony"

    def team(section):
        full = [np.concatenate([s, NAV]) for s in (others[0], section[:8], others[1])]
        return np.stack(full)

    gen1 = np.load(folder / "populations/pop0_gen0001.npz")
    for i in (0, 5):
        t = team(gen1["population"][i])
        ev = evaluate_colony(t[None, 1], gen1["starts"], table=TABLE.values, mode="coverage",
                             partners=t, role=1)  # fmt: skip
        assert ev.squares[0].mean() == pytest.approx(gen1["fitness"][i])
    settings = json.loads((folder / "settings.json").read_text())
    assert settings["beside_robot"] == 1 and "partner_section" not in settings
    assert settings["partner_sections"] == [["".join(map(str, g)) for g in s.tolist()]
                                            for s in others]  # fmt: skip
    assert_finalists(folder, summary, team, robot=1)


def test_a_middle_robot_resumes_and_refuses_other_partners(middle, tmp_path):
    from infra.errors import InputError

    out, _, others = middle
    assert_resumes_bit_for_bit(out, tmp_path, "pop1.npz", colony=BESIDE, partners=others,
                               robot=1)  # fmt: skip
    for kw, field in ((dict(partners=others[::-1], robot=1), "partner_sections"),
                      (dict(partners=others, robot=0), "beside_robot")):  # fmt: skip
        with pytest.raises(InputError, match=field):
            run_colony_stage(tmp_path, navigation=NAV, table=TABLE, ga=TINY, colony=BESIDE,
                             resume=True, **kw)  # fmt: skip


def test_bad_learned_robots_are_named(runs):
    partner = runs[2]
    for robot in (3, -1, True, 1.0):
        with pytest.raises(StageError, match=rf"learned robot must be one of 0 … 2 .*{robot!r}"):
            colony_stage(WORLD, BESIDE, NAV, partners=partner, robot=robot)
    with pytest.raises(StageError, match="3 partners' sections for a colony of 3: give one for "
                                         "each of the other 2 robots"):  # fmt: skip
        colony_stage(WORLD, BESIDE, NAV, partners=np.stack([partner] * 3))
    with pytest.raises(StageError, match=r"the partner 1's section must be an \(8, 30\)"):
        colony_stage(WORLD, BESIDE, NAV, partners=np.stack([partner, 2 * partner]))
    with pytest.raises(StageError, match="a learned robot is named only for the colony stage"):
        colony_stage(WORLD, ColonySettings(), NAV, robot=0)


def test_the_command_line_names_a_learned_robot(runs, middle, tmp_path, capsys):
    from servobot.cli import main

    root = runs[0]
    nav = tmp_path / "nav.txt"
    nav.write_text(LIGHT_FOLLOWER)
    files = ",".join(str(root / f"shared/colony/best_pop{k}.txt") for k in (0, 1))
    common = ["--populations", "1", "--generations", "2", "--population-size", "4",
              "--starts-per-generation", "2", "--navigation", str(nav),
              "--no-progress"]  # fmt: skip
    assert main(["evolve", "colony", "--beside-robot", "1", *common,
                 "--out", str(tmp_path / "x")]) == 2  # fmt: skip
    assert "--beside-robot is an option of the colony stage with --sections beside" in (
        capsys.readouterr().err
    )
    out = tmp_path / "z"
    assert main(["evolve", "colony", "--sections", "beside", "--partners", files,
                 "--beside-robot", "1", *common, "--out", str(out)]) == 0  # fmt: skip
    settings = json.loads((out / "colony/settings.json").read_text())
    assert settings["beside_robot"] == 1
    recorded = json.loads((middle[0] / "colony/settings.json").read_text())
    assert settings["partner_sections"] == recorded["partner_sections"]
    assert "robot 1's coverage section" in (out / "colony/best_pop0.txt").read_text()


def test_the_saved_bests_screen(runs, middle, tmp_path, capsys):
    """``evolve.beside_screen``: every saved best of both tiny stages as its learned robot; the
    final generation's saved best of each population is its finalist, so its row is the stage's
    own final test; rows best first by run fitness; ``--save`` writes the chromosome."""
    from evolve.beside_screen import BesideScreenError, load_beside_run, main, screen
    from evolve.population import save_generations

    for out, summary, robot in ((runs[0] / "beside", runs[1], 2), (middle[0], middle[1], 1)):
        run = load_beside_run(out)
        assert run.role == robot
        rows = screen(run)
        assert len(rows) == TINY.populations * len(save_generations(TINY))
        fitness = [r["run_fitness"] for r in rows]
        assert fitness == sorted(fitness, reverse=True)
        by_name = {r["name"]: r for r in rows}
        for k, final in enumerate(summary["final_test"]):
            row = by_name[f"pop{k}_gen{TINY.generations:04d}"]
            for key in ("colony_inner_percent", "live_at_end_per_run", "run_fitness",
                        "one_robot_inner_percent"):  # fmt: skip
                assert row[key] == pytest.approx(final[key])
    name = f"pop1_gen{TINY.generations:04d}"
    assert main([str(middle[0]), "--save", name, str(tmp_path / "s.txt")]) == 0
    assert capsys.readouterr().out == f"wrote {tmp_path / 's.txt'}\n"
    np.testing.assert_array_equal(read_chromosome(tmp_path / "s.txt"),
                                  read_chromosome(middle[0] / "colony/best_pop1.txt"))  # fmt: skip
    assert main([str(middle[0]), "--top", "3"]) == 0
    out = capsys.readouterr().out
    assert "as robot 1 of 3" in out and len(out.strip().splitlines()) == 4
    assert main([str(middle[0]), "--save", "pop9_gen0001", str(tmp_path / "x.txt")]) == 2
    assert "no saved best 'pop9_gen0001'" in capsys.readouterr().err
    with pytest.raises(BesideScreenError, match="not a 'beside' stage"):
        load_beside_run(runs[0] / "shared")
