"""Physics runs that share their common gait cycles (``servo_mj.world.shared_physics``,
``servobot.validation.lone.run_shared_starts``, ``execute(share=True)``): the same poses,
sensors and records as separate runs, bit for bit, with each shared cycle simulated once."""

from __future__ import annotations

import numpy as np
import pytest
from chromosome_text import G, chrom, gene

from infra.executors import SerialExecutor
from servo_mj.robot.bot import PhysicsError
from servo_mj.world.physics_world import PhysicsWorld
from servo_mj.world.shared_physics import PhysicsTree
from servobot.validation.lone import (
    SHARE_GROUP_MAX,
    _batch,
    execute,
    plan_validation,
    run_shared_starts,
    run_start,
)

START = (250.0, 250.0, 30.0)


def _world() -> PhysicsWorld:
    return PhysicsWorld(*START, rng=np.random.default_rng((0, 3)))


def test_views_walk_as_separate_worlds_bit_for_bit() -> None:
    """Four gait sequences (two sharing their first cycles, one a repeat, one apart) stepped
    in turn through one tree give each separate world's poses and object sensors exactly;
    the tree simulates each distinct cycle once."""
    seqs = [[8, 8, 8, 2, 2], [8, 8, 2, 2, 2], [8, 8, 8, 2, 2], [15, 8, 8]]
    alone = []
    for seq in seqs:
        w, out = _world(), []
        for g in seq:
            w.step(g)
            out.append((w.pose(), w.object_sensors()))
        alone.append(out)
    tree = PhysicsTree(_world())
    views = [tree.view() for _ in seqs]
    shared: list[list] = [[] for _ in seqs]
    for k in range(max(map(len, seqs))):  # round robin: every step restores another branch
        for s, (seq, v) in enumerate(zip(seqs, views, strict=True)):
            if k < len(seq):
                v.step(seq[k])
                shared[s].append((v.pose(), v.object_sensors()))
    assert shared == alone
    assert tree.cycles_run == 5 + 3 + 0 + 3  # distinct (prefix, gait) nodes; 18 cycles walked
    assert views[0].light_sensors() == _lit(alone[0][-1][0])


def _lit(pose: tuple[float, float, float]) -> tuple[bool, bool]:
    from evolve import geometry
    from evolve.settings import WorldSettings

    return geometry.light_sensors(*pose, WorldSettings())


def test_a_failed_cycle_fails_every_view_that_takes_it_and_is_run_once(monkeypatch) -> None:
    tree = PhysicsTree(_world())
    calls = []
    step = tree.world.step

    def failing(gait: int) -> None:
        calls.append(gait)
        if gait == 15:
            raise PhysicsError("torso flipped during gait 15, cycle 1")
        step(gait)

    monkeypatch.setattr(tree.world, "step", failing)
    a, b = tree.view(), tree.view()
    a.step(8)
    b.step(8)
    for v in (a, b):
        with pytest.raises(PhysicsError, match="torso flipped"):
            v.step(15)
    c = tree.view()  # the world is usable after the failure: it restores the root
    c.step(2)
    assert calls == [8, 15, 2]
    fresh = _world()
    fresh.step(2)
    assert c.pose() == fresh.pose()


# Two coverage controllers that walk the same first cycles and then differ, one repeated.
A = chrom(gene("00", G(8), G(8), G(8), G(8)))
B = chrom(gene("00", G(8), G(8), G(2), G(2)))


def _plain(rec: dict) -> dict:
    """A record without its wall times (no two runs share them) and with tracks as lists."""
    out = {k: v for k, v in rec.items() if k != "tracks"}
    for side in ("table", "physics"):
        out[side] = {k: v for k, v in rec[side].items() if k != "wall_s"}
    out["tracks"] = {w: t.tolist() for w, t in rec["tracks"].items()}
    return out


def test_shared_starts_give_the_records_of_separate_runs() -> None:
    starts = np.array([START])
    jobs = tuple(plan_validation(bits, starts, table=np.zeros((16, 3)), max_steps=6).jobs[0]
                 for bits in (A, B, A))  # fmt: skip
    shared = run_shared_starts(jobs)
    assert [_plain(r) for r in shared] == [_plain(run_start(j)) for j in jobs]
    a, b = (r["tracks"]["physics"] for r in shared[:2])  # 2 cycles shared, then apart
    assert len(a) == 7 and np.array_equal(a[:3], b[:3]) and not np.array_equal(a[3], b[3])


def test_execute_groups_runs_by_start_and_world_and_keeps_the_reports() -> None:
    starts = np.array([START, (200.0, 300.0, 100.0)])
    plans = [plan_validation(bits, starts, table=np.zeros((16, 3)), max_steps=4)
             for bits in (A, B)]  # fmt: skip
    items, owners = _batch(plans, share=True)
    assert owners == [[(0, 0), (1, 0)], [(0, 1), (1, 1)]] and len(items) == 2
    assert len(_batch(plans, share=False)[0]) == 4
    many = plans * (SHARE_GROUP_MAX // 2 + 1)  # more runs per start than a group holds
    sizes = [len(o) for o in _batch(many, share=True)[1]]
    assert sizes == [SHARE_GROUP_MAX, 2, SHARE_GROUP_MAX, 2]  # start by start
    seen: list[tuple[int, int]] = []
    shared = execute(plans, SerialExecutor(), share=True,
                     on_record=lambda i, r: seen.append((i, r["index"])))  # fmt: skip
    alone = execute(plans, SerialExecutor())
    assert sorted(seen) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    for s, a in zip(shared, alone, strict=True):
        assert [_plain(r | {"tracks": {}}) for r in s["runs"]] == [
            _plain(r | {"tracks": {}}) for r in a["runs"]]  # fmt: skip


def test_anytime_physics_tests_share_cycles_with_the_same_results() -> None:
    """Anytime learning's physics runs (``measure_shared_runs``): squares, residuals and ends
    of separate runs."""
    import dataclasses

    from servobot.anytime.run import PunctuationJob, measure_run, measure_shared_runs

    starts = np.array([START])
    jobs = tuple(
        PunctuationJob(plan_validation(bits, starts, table=np.zeros((16, 3)),
                                       max_steps=6).jobs[0], 0.0)
        for bits in (A, B, A)
    )  # fmt: skip
    for a, b in zip(measure_shared_runs(jobs), map(measure_run, jobs), strict=True):
        for f in dataclasses.fields(a):
            x, y = getattr(a, f.name), getattr(b, f.name)
            assert np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y, f.name
        assert a.squares is not None and len(a.gaits) == 6


def test_the_benchmark_runs_and_finds_the_records_identical(tmp_path, capsys) -> None:
    from evolve.codec import format_chromosome
    from servobot.robustness import share_bench

    for name, bits in (("a", A), ("b", B), ("c", A)):
        (tmp_path / f"{name}.txt").write_text(format_chromosome(bits) + "\n")
    assert share_bench.main([str(tmp_path), "--start", "1", "--steps", "4"]) == 0
    out = capsys.readouterr().out
    assert "records identical" in out and "gait cycles walked 12, simulated shared 6" in out
