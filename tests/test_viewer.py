"""The recordings in the real rerun viewer (headless, ``tests/viewer.py``): a validation run, a
colony run and a calibration, made here, load without a data error or warning, open on the
timeline both worlds share (a calibration, one world, on ``sim_time``), and draw something.

Skipped, naming the reason, where the viewer cannot run (no Vulkan driver: on Debian
``apt-get install -y mesa-vulkan-drivers``, which ``.ci/run`` does when it can).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evolve.codec import parse_chromosome
from evolve.settings import ColonySettings, WorldSettings
from evolve.table import PAPER_TABLE
from servo_mj.world.arena import ArenaSettings
from tests.test_recording import ALWAYS_GAIT_8
from tests.viewer import HeadlessViewer, data_problems, pixel_std, vulkan_missing

WHY = vulkan_missing()
pytestmark = pytest.mark.skipif(WHY is not None, reason=f"the rerun viewer cannot run: {WHY}")

OPENS_ON = {"validation": "step", "colony": "colony_step", "calibration": "sim_time"}
"""The timeline each kind of recording opens on."""


def kind_of(timelines: set[str]) -> str:
    """Which recording the viewer holds, by its timelines."""
    if "colony_step" in timelines:
        return "colony"
    return "calibration" if "cycle" in timelines else "validation"


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> dict[str, Path]:
    """Small recordings of each kind: 5 steps of a lone run, 3 colony steps of 3 robots, the
    16 calibration walks of one cycle each."""
    from calibration.calibrate import calibrate
    from calibration.measure import CalibrationSettings
    from servobot.recording import Recording, calibration_recorder, log_calibration_result
    from servobot.validation.colony import ColonyJob, run_colony_start
    from servobot.validation.lone import StartJob, run_start

    tmp = tmp_path_factory.mktemp("viewer")
    bits, world, arena = parse_chromosome(ALWAYS_GAIT_8), WorldSettings(), ArenaSettings()
    table = np.asarray(PAPER_TABLE)
    lone = StartJob(
        index=0, bits=bits, start=(400.0, 250.0, 90.0), table=table, world=world, arena=arena,
        physics=None, max_steps=5, rrd_path=str(tmp / "lone" / "run0.rrd"),
    )  # fmt: skip
    assert run_start(lone)["error"] is None
    starts = ((400.0, 200.0, 90.0), (400.0, 300.0, 90.0), (250.0, 250.0, 0.0))
    colony = ColonyJob(
        index=0, bits=bits, start=starts, table=table, world=world, arena=arena,
        colony=ColonySettings(robots=3), physics=None, max_steps=3,
        rrd_path=str(tmp / "colony" / "run0.rrd"),
    )  # fmt: skip
    assert run_colony_start(colony)["error"] is None
    settings = CalibrationSettings(cycles=1, settle_cycles=0)
    cal = tmp / "calibration.rrd"
    with Recording.for_calibration(cal) as rec:
        res = calibrate(tmp / "cal", settings, workers=1, **calibration_recorder(rec, settings))
        log_calibration_result(rec, res)
    return {"validation": Path(lone.rrd_path), "colony": Path(colony.rrd_path), "calibration": cal}


def test_the_viewer_loads_each_recording_on_a_shared_timeline_and_draws_it(recordings, tmp_path):
    files = [recordings[k] for k in OPENS_ON]
    with HeadlessViewer(files, window="1280x800") as viewer:
        recs = viewer.recordings()
        assert len(recs) == 3
        shown = {}
        for rec in recs:
            kind = kind_of({t.name for t in rec.timelines})
            shown[kind] = viewer.show(rec, str(tmp_path / kind), at=(0.6,), settle_s=1.5,
                                      views=("arena",))  # fmt: skip
        logs = viewer.logs()
    print(f"viewer: loaded 3 recordings in {viewer.load_s:.1f} s; screenshots in {tmp_path}")
    assert set(shown) == set(OPENS_ON)
    for kind, s in shown.items():
        assert s.opens_on == OPENS_ON[kind], kind
        assert not s.reports, (kind, s.reports)  # no view failed to visualize
        names = {name for name, _ in s.views}
        assert "arena" in names, kind
        if kind != "calibration":  # a calibration follows each gait in its own tab
            assert any(n.startswith("follow") for n in names), kind
        window, *views = s.screenshots
        assert pixel_std(window) > 0.05, kind
        arena = [v for v in views if v.endswith("_arena.png")]
        assert arena and pixel_std(arena[0]) > 0.03, (kind, views)  # the scene is drawn
    assert data_problems(logs) == []
