"""Recordings in the real rerun viewer, headless: open ``.rrd`` files, read what the viewer
shows (timelines, views, its own log) and save screenshots — the test helper of
``tests/test_viewer.py``, after ``/work/shared/tools/viewer_shot.py``.

The viewer is the native one shipped with the active rerun-sdk (``rerun_cli``), run with
``--headless`` and driven through ``rerun.experimental.ViewerClient``. It needs a Vulkan
driver; with no GPU, Mesa's software rasterizer (Debian: ``apt-get install -y
mesa-vulkan-drivers``). ``vulkan_missing()`` says why the viewer cannot run here, or None.

    python tests/viewer.py FILE.rrd ... --out PREFIX [--at 0.5 0.95]

saves ``PREFIX_<k>_tXX.png`` (the whole viewer) and ``PREFIX_<k>_tXX_<view>.png`` (each 3D
view) for the k-th file and prints what the viewer reported.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

IGNORED = (
    "Software rasterizer", "XDG_RUNTIME_DIR", "locale", "XSETTINGS", "XRandR", "Docker",
    "telemetry", "Telemetry", "not found for screenshot",
)  # fmt: skip
"""Viewer log lines about the machine, not the data (a software renderer, no desktop), and
about a screenshot asked of a view in a tab not on screen."""

ICD_DIRS = ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d")
"""Where Vulkan drivers (ICDs) announce themselves."""


def viewer_binary() -> Path | None:
    """The native viewer shipped with the active rerun-sdk, if any."""
    try:
        import rerun_cli
    except ImportError:
        return None
    path = Path(rerun_cli.__file__).parent / "rerun"
    return path if path.is_file() else None


def vulkan_missing() -> str | None:
    """Why the headless viewer cannot run here (no Vulkan driver, no viewer binary), or None."""
    if viewer_binary() is None:
        return "the rerun-sdk has no native viewer (rerun_cli)"
    icds = [f for d in ICD_DIRS for f in glob.glob(f"{d}/*.json")]
    if os.environ.get("VK_ICD_FILENAMES"):
        icds += os.environ["VK_ICD_FILENAMES"].split(os.pathsep)
    if not icds:
        return (
            "no Vulkan driver (no ICD in " + ", ".join(ICD_DIRS) + "); on Debian: "
            "apt-get install -y mesa-vulkan-drivers"
        )
    return None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def pixel_std(png: str | Path) -> float:
    """Standard deviation of a screenshot's pixel values (0–1): near 0 for a blank image."""
    from matplotlib.image import imread

    img = np.asarray(imread(str(png)), dtype=np.float64)
    return float(img[..., :3].std())


def data_problems(logs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The viewer's warnings and errors, without those about the machine (``IGNORED``)."""
    return [
        e for e in logs
        if str(e.get("level", "")).upper() in ("ERROR", "WARN", "WARNING")
        and not any(s in str(e) for s in IGNORED)
    ]  # fmt: skip


@dataclass
class Shown:
    """What the viewer showed of one recording."""

    name: str
    timelines: dict[str, tuple[str, int | None, int | None]]
    """Timeline name → (kind, first, last time)."""
    opens_on: str | None
    views: list[tuple[str, str]] = field(default_factory=list)
    """(name, class) of every view."""
    reports: list[str] = field(default_factory=list)
    """What views said failed to visualize."""
    screenshots: list[str] = field(default_factory=list)


class HeadlessViewer:
    """A headless viewer holding ``files``; a context manager. ``show(k, at=...)`` makes the
    k-th file's recording active, pauses at fractions of its timeline and saves screenshots."""

    def __init__(self, files: list[str | Path], *, window: str = "1600x1000",
                 load_timeout_s: float = 120.0) -> None:  # fmt: skip
        self.files = [str(f) for f in files]
        self.window, self.load_timeout_s = window, load_timeout_s
        self.port = free_port()
        self.proc: subprocess.Popen | None = None
        self.vc: Any = None
        self.load_s = 0.0

    def __enter__(self) -> HeadlessViewer:
        from rerun.experimental import ViewerClient

        env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
        env.setdefault("WGPU_BACKEND", "vulkan")
        self.proc = subprocess.Popen(
            [str(viewer_binary()), "--headless", "--port", str(self.port), "--window-size",
             self.window, "-j", "1", *self.files],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        )  # fmt: skip
        t0 = time.monotonic()
        while True:
            try:
                vc = ViewerClient.connect(f"rerun+http://127.0.0.1:{self.port}/proxy")
                vc.get_state()
                self.vc = vc
                break
            except Exception:
                if self.proc.poll() is not None or time.monotonic() - t0 > 60:
                    self.__exit__(None, None, None)
                    raise RuntimeError("the headless viewer did not start") from None
                time.sleep(0.5)
        while True:
            st = self.vc.get_state()
            done = [r for r in st.recordings if r.timelines]
            if not st.loading and len(done) >= len(self.files):
                break
            if time.monotonic() - t0 > self.load_timeout_s:
                self.__exit__(None, None, None)
                raise TimeoutError(f"still loading after {self.load_timeout_s} s: {st.loading}")
            time.sleep(0.5)
        self.load_s = time.monotonic() - t0
        return self

    def __exit__(self, *_: Any) -> None:
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)
        self.proc = None

    def recordings(self) -> list[Any]:
        """The viewer's recordings, in the order of ``files`` (by recording name's source)."""
        return list(self.vc.get_state().recordings)

    def logs(self) -> list[dict[str, Any]]:
        return [asdict(e) for e in self.vc.get_logs()]

    def show(self, rec: Any, prefix: str, *, at: tuple[float, ...] = (0.5,),
             settle_s: float = 3.0, views: tuple[str, ...] | None = None) -> Shown:  # fmt: skip
        """Make recording ``rec`` (one of ``recordings()``) active; at each fraction of its
        opening timeline save the whole viewer as ``PREFIX_tXX.png`` and each 3D view on
        screen (or only those named in ``views``) as ``PREFIX_tXX_<view>.png``."""
        vc = self.vc
        vc.set_location(rec.location)
        time.sleep(settle_s)
        rec = next(r for r in vc.get_state().recordings if r.store_id == rec.store_id)
        shown = Shown(
            name=str(rec.store_id), opens_on=rec.current_timeline,
            timelines={t.name: (t.time_type, t.start, t.end) for t in rec.timelines},
        )  # fmt: skip
        tl = next(
            t for t in rec.timelines if t.name == (rec.current_timeline or rec.timelines[0].name)
        )
        for frac in at:
            t = int(tl.start + frac * (tl.end - tl.start))
            if tl.time_type == "sequence":
                vc.set_time(tl.name, sequence=t, play_state="paused")
            elif tl.time_type == "duration":
                vc.set_time(tl.name, duration=t / 1e9, play_state="paused")
            else:
                vc.set_time(tl.name, timestamp=t / 1e9, play_state="paused")
            time.sleep(settle_s)
            out = f"{prefix}_t{int(frac * 100):02d}.png"
            vc.save_screenshot(out)
            shown.screenshots.append(out)
            for v in vc.get_state().views:
                if v.view_class == "3D" and v.visible and (views is None or v.name in views):
                    view = v.name.replace("/", "_").replace(" ", "_")
                    vout = f"{prefix}_t{int(frac * 100):02d}_{view}.png"
                    try:
                        vc.save_screenshot(vout, view_id=v.view_id)
                    except ConnectionError:  # in a tab not on screen: nothing drawn
                        continue
                    shown.screenshots.append(vout)
        state = vc.get_state()
        shown.views = [(v.name, v.view_class) for v in state.views]
        shown.reports = [
            f"{v.name}: {r.severity}: {r.summary}" for v in state.views for r in v.reports
        ]
        return shown


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd", nargs="+")
    ap.add_argument("--out", required=True, help="prefix of the screenshots")
    ap.add_argument("--at", type=float, nargs="*", default=[0.5])
    ap.add_argument("--window", default="1600x1000")
    args = ap.parse_args()
    if (why := vulkan_missing()) is not None:
        print("cannot run the viewer:", why)
        return 2
    with HeadlessViewer(args.rrd, window=args.window) as viewer:
        print(f"loaded {len(args.rrd)} file(s) in {viewer.load_s:.1f} s")
        for k, rec in enumerate(viewer.recordings()):
            shown = viewer.show(rec, f"{args.out}_{k}", at=tuple(args.at))
            print(json.dumps(asdict(shown), default=str, indent=1))
        problems = data_problems(viewer.logs())
    for e in problems:
        print("viewer:", e)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
