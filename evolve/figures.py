"""Figures 8, 9 and 10 of the paper as PNG files (matplotlib, Agg backend; no display needed).

Figure 8: the arena alone — the 10 × 10 squares with their central contact zones (inner
squares shaded), the kill zone, the power station and docking box, the two lights, the edges
of their lit cones and the dark area. Figure 9: test fitness (% of the 64 inner squares) of each
population's best individual per saved generation, 5 thin lines and their bold mean.
``figure_anytime``: anytime learning's best by generation in physics and in the table world.
``docking_map``: where a navigation section docks from, each start coloured by its end.
``figure_colony_docks``: a colony's cumulative docks per robot and live robots by colony step.
Figure 10: a chromosome's track from a start pose (the table interpreter) over the arena; for
a colony (SPEC §7), every robot's track in its own colour from one colony start.
Arena units (cm), x east, y north; headings 0 = north, clockwise.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import patches  # noqa: E402

from evolve import geometry  # noqa: E402
from evolve.interpreter import END_NAMES, END_STEP_LIMIT  # noqa: E402
from evolve.settings import ColonySettings, WorldSettings  # noqa: E402
from evolve.table import GaitTable  # noqa: E402
from infra.io import atomic_write  # noqa: E402

LIT_GRID_STEP = 2.5
"""Resolution of the lit/dark shading, arena units."""
DPI = 130
"""Resolution of the PNG files."""
CONE_EDGE_LENGTH_FACTOR = 1.5
"""Lit-cone edges are drawn this many arena sides long (the axes clip them at the walls)."""
ROBOT_COLOURS = ("tab:blue", "tab:purple", "tab:brown", "tab:pink", "tab:cyan", "tab:olive",
                 "tab:gray", "black")  # fmt: skip
"""Track colour of colony robot i (cycled): none of the arena's green, red and orange."""
ANYTIME_COLOURS = {"none": "tab:gray", "bias": "tab:blue", "model": "tab:orange",
                   "transfer": "tab:green"}  # fmt: skip
"""Colour of each anytime method's curves (the control grey)."""
HEADING_ARROW = 18.0
"""Length of the start-heading arrow, arena units."""


def lit_mask(world: WorldSettings, step: float = LIT_GRID_STEP) -> np.ndarray:
    """Boolean (ny, nx) grid of cell centres lit by at least one source (row 0 = south)."""
    centres = np.arange(step / 2, world.arena_size, step)
    mask = np.zeros((centres.size, centres.size), dtype=bool)
    for j, y in enumerate(centres):
        for i, x in enumerate(centres):
            mask[j, i] = any(geometry.lit(x, y, world))
    return mask


def draw_arena(ax: Any, world: WorldSettings, *, reached: frozenset[int] = frozenset()) -> None:
    """Draw the arena of SPEC §3 on ``ax``; squares in ``reached`` are filled green."""
    size = world.arena_size
    _draw_dark_area(ax, world)
    _draw_squares(ax, world, reached)
    _draw_kill_zone(ax, world)
    _draw_station(ax, world)
    _draw_lights(ax, world)
    ax.set_xlim(0, size)
    ax.set_ylim(0, size)
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm, east)")
    ax.set_ylabel("y (cm, north)")


def _draw_dark_area(ax: Any, world: WorldSettings) -> None:
    """Grey where no source lights the floor, plus its legend entry."""
    size = world.arena_size
    dark = np.where(~lit_mask(world), 1.0, np.nan)
    ax.imshow(dark, extent=(0, size, 0, size), origin="lower", cmap="Greys", vmin=0,
              vmax=2.5, alpha=0.55, zorder=0)  # fmt: skip
    # legend entry only (zero size): the dark area itself is the grey image
    ax.add_patch(patches.Rectangle((0, 0), 0, 0, fc="0.55", alpha=0.55, label="dark area"))


def _draw_squares(ax: Any, world: WorldSettings, reached: frozenset[int]) -> None:
    """The grid and each square's central contact zone (inner squares tinted)."""
    sq, n, half = world.square_size, world.grid_n, world.contact_half_width
    for j in range(n):
        for i in range(n):
            idx = i + n * j
            inner = geometry.is_inner(idx, world)
            ax.add_patch(
                patches.Rectangle((i * sq, j * sq), sq, sq, fill=False, lw=0.4, ec="0.6", zorder=1)
            )
            fc = "tab:green" if idx in reached else ("#dbe8f5" if inner else "#f2f2f2")
            corner = (i * sq + sq / 2 - half, j * sq + sq / 2 - half)
            ax.add_patch(
                patches.Rectangle(corner, 2 * half, 2 * half, fc=fc, ec="0.75", lw=0.3,
                                  alpha=0.8 if idx in reached else 0.7, zorder=1)
            )  # fmt: skip


def _draw_kill_zone(ax: Any, world: WorldSettings) -> None:
    """The band within ``kill_margin`` of the walls."""
    size, m = world.arena_size, world.kill_margin
    ring = [(0, 0), (size, 0), (size, size), (0, size), (0, 0),
            (m, m), (m, size - m), (size - m, size - m), (size - m, m), (m, m)]  # fmt: skip
    ax.add_patch(patches.Polygon(ring, closed=True, fc="tab:red", alpha=0.18, ec="none",
                                 zorder=2, label="kill zone"))  # fmt: skip


def _draw_station(ax: Any, world: WorldSettings) -> None:
    """The station plate on the east wall and the docking box in front of it."""
    size, w = world.arena_size, world.station_width
    ax.add_patch(
        patches.Rectangle((size - 6, world.station_y - w / 2), 6, w, fc="tab:orange", ec="k",
                          lw=0.6, zorder=4, label="power station")
    )  # fmt: skip
    ax.add_patch(
        patches.Rectangle(
            (world.dock_x_min, world.station_y - world.dock_y_half_width),
            size - world.dock_x_min, 2 * world.dock_y_half_width,
            fill=False, ec="tab:orange", ls="--", lw=0.8, zorder=4, label="docking box",
        )
    )  # fmt: skip


def _draw_lights(ax: Any, world: WorldSettings) -> None:
    """The light sources and the edges of their lit cones."""
    lx = [s[0] for s in world.lights]
    ly = [s[1] for s in world.lights]
    ax.scatter(lx, ly, marker="*", s=90, c="gold", ec="k", lw=0.5, zorder=5, label="lights")
    reach = CONE_EDGE_LENGTH_FACTOR * world.arena_size
    for k, (x0, y0) in enumerate(world.lights):
        for side in (-1.0, 1.0):
            a = np.deg2rad(world.light_axis_deg + side * world.light_half_angle_deg)
            ax.plot([x0, x0 + reach * np.sin(a)], [y0, y0 + reach * np.cos(a)],
                    color="goldenrod", ls=":", lw=0.9, zorder=3,
                    label="lit-cone edges" if k == 0 and side < 0 else None)  # fmt: skip


def _save(fig: Any, path: Path) -> Path:
    out = atomic_write(path, lambda p: fig.savefig(p, dpi=DPI, bbox_inches="tight"))
    plt.close(fig)
    return out


def _arena_plot(world: WorldSettings, reached: frozenset[int] = frozenset()) -> tuple[Any, Any]:
    """(figure, axes) of a square arena plot: the arena of ``world`` with ``reached`` squares."""
    fig, ax = plt.subplots(figsize=(6.2, 6.2))
    draw_arena(ax, world, reached=reached)
    return fig, ax


def _save_arena(
    fig: Any, ax: Any, path: str | Path, title: str, *, title_size: float = 9,
    legend_size: float = 7,
) -> Path:  # fmt: skip
    """Title an arena plot (font sizes in points), put its legend in the upper left (over the
    dark area) and save it at ``path``."""
    ax.set_title(title, fontsize=title_size)
    ax.legend(loc="upper left", fontsize=legend_size, framealpha=0.9)
    return _save(fig, Path(path))


def figure8(path: str | Path, world: WorldSettings = geometry.DEFAULT_WORLD) -> Path:
    """Figure 8: the arena alone, as a PNG at ``path``."""
    fig, ax = _arena_plot(world)
    title = (
        "Figure 8: colony arena — squares (contact zones), kill zone, station,\n"
        "lights and the dark area outside both lit cones"
    )
    return _save_arena(fig, ax, path, title)


def figure9(
    path: str | Path,
    generations: Any,
    inner_percent: np.ndarray,
    title: str = "Figure 9: area-coverage fitness of each population's best individual",
) -> Path:
    """Figure 9: one thin line per population (rows of ``inner_percent``, % of 64 inner
    squares) over ``generations``, and their mean in bold."""
    inner = np.asarray(inner_percent, dtype=float)
    gens = np.asarray(generations)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for k, row in enumerate(inner):
        ax.plot(gens, row, lw=0.9, marker=".", alpha=0.8, label=f"population {k}")
    mean = inner.mean(axis=0)
    ax.plot(gens, mean, lw=2.8, color="k", label="mean")
    ax.annotate(
        f"{mean[-1]:.1f}%",
        (gens[-1], mean[-1]),
        textcoords="offset points",
        xytext=(4, 4),
        fontsize=8,
    )
    ax.set_xlabel("generation")
    ax.set_ylabel("test fitness (% of 64 inner squares)")
    ax.set_ylim(0, 100)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, Path(path))


END_COLOURS = {"docked": "tab:green", "kill zone": "tab:red", "power empty": "tab:blue",
               "step limit": "black", "branch limit": "tab:purple"}  # fmt: skip
"""Colour of each run end in the docking map."""


def docking_map(
    path: str | Path, starts: np.ndarray, ends: np.ndarray, world: WorldSettings, title: str
) -> Path:
    """Where a navigation section docks from: each start pose (S, 3) a dot over the arena,
    coloured by how its run ended (``ends``: end codes, ``END_NAMES``)."""
    fig, ax = _arena_plot(world)
    ends = np.asarray(ends)
    for code, name in enumerate(END_NAMES):
        mine = ends == code
        if mine.any():
            ax.scatter(starts[mine, 0], starts[mine, 1], s=7, color=END_COLOURS[name],
                       label=f"{name}: {mine.mean():.1%}", zorder=5)  # fmt: skip
    return _save_arena(fig, ax, path, title)


def figure_anytime(
    path: str | Path, arms: list[tuple[str, dict[str, Any], str]], title: str
) -> Path:
    """Anytime learning: per arm (label, ``{"generations", "physics_fitness",
    "table_fitness"}``, colour), the fitness (squares of 100) of the best at each punctuation in
    physics (solid) and in the table world on the same starts (dotted)."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for label, curve, colour in arms:
        gens = np.asarray(curve["generations"])
        phys = np.array([np.nan if v is None else v for v in curve["physics_fitness"]], float)
        table = np.array([np.nan if v is None else v for v in curve["table_fitness"]], float)
        ax.plot(gens, phys, lw=2.0, marker="o", color=colour, label=f"{label}: physics")
        ax.plot(gens, table, lw=1.0, ls=":", marker=".", color=colour, label="  table, same starts")
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness of the best (squares of 100)")
    ax.set_ylim(bottom=0)
    ax.set_title(title, fontsize=8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, Path(path))


def figure_colony_docks(
    path: str | Path,
    curves: list[dict[str, Any]],
    title: str,
    *,
    dock_goal: float = 2.0,
    live_goal: float | None = None,
) -> Path:
    """The colony's docks over time (``evolve.colony_timeline``): two panels over the colony
    steps, one line per curve (``label``; ``docks_per_robot``, ``live``, optionally
    ``charging`` and ``robots``, each a mean over colony starts per colony step). Top: the
    cumulative docks per robot, dashed at ``dock_goal`` (issue 17: 2). Bottom: the robots
    live (solid) and charging (dotted) of R, dashed at ``live_goal`` (default ⅔ R: 2 of 3)."""
    robots = max(int(c.get("robots", 1)) for c in curves) if curves else 1
    goal = 2.0 * robots / 3.0 if live_goal is None else live_goal
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7.0, 5.6),
                                      gridspec_kw={"height_ratios": (3, 2)})  # fmt: skip
    for k, c in enumerate(curves):
        colour = f"C{k % 10}"
        steps = np.arange(len(c["docks_per_robot"]))
        docks = np.asarray(c["docks_per_robot"], dtype=float)
        top.plot(steps, docks, lw=1.3, color=colour, label=f"{c['label']}: {docks[-1]:.2f}")
        live = np.asarray(c["live"], dtype=float)
        bottom.plot(steps, live, lw=1.3, color=colour, label=f"{c['label']}: {live[-1]:.2f}")
        if "charging" in c:
            bottom.plot(steps, np.asarray(c["charging"], dtype=float), lw=0.7, ls=":",
                        color=colour, alpha=0.7)  # fmt: skip
    top.axhline(dock_goal, color="k", ls="--", lw=0.9, label=f"goal: {dock_goal:g} docks per robot")
    top.set_ylabel("cumulative docks per robot")
    top.set_ylim(0, max(dock_goal * 1.15, *(max(c["docks_per_robot"]) * 1.1 for c in curves)))
    top.set_title(title, fontsize=8)
    top.legend(fontsize=7, loc="upper left", title="at the end", title_fontsize=7)
    bottom.axhline(goal, color="k", ls="--", lw=0.9, label=f"goal: {goal:g} of {robots} live")
    bottom.plot([], [], color="0.4", lw=0.7, ls=":", label="dotted: robots charging")
    bottom.set_ylabel(f"robots live (of {robots})")
    bottom.set_xlabel("colony step")
    bottom.set_ylim(0, robots + 0.15)
    bottom.legend(fontsize=6.5, loc="upper right", ncol=2, title="live at the end",
                  title_fontsize=7)  # fmt: skip
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    bottom.set_xlim(left=0)
    fig.tight_layout()
    return _save(fig, Path(path))


def figure_colony_choice(
    path: str | Path,
    points: list[dict[str, Any]],
    title: str,
    *,
    robots: int = 3,
    min_live: float = 2.0,
    joined: tuple[str, ...] = ("chosen", "confirmation"),
) -> Path:
    """Finalists' colony validations in the plane physics chooses in: colony inner coverage
    (%, x) against robots live at the end per run (of ``robots``, y). Each point (``label``,
    ``inner_pct``, ``live_per_run``, optional ``kind``: ``finalist``, ``chosen``, ``team`` or
    ``confirmation``) is drawn by its kind; the points of the ``joined`` kinds (a chosen
    finalist and its confirmation) are joined in order. Dashed: ``min_live``, the rule's floor
    (none at 0)."""
    style = {"finalist": dict(marker="o", color="0.55", s=30),
             "chosen": dict(marker="o", color="C3", s=55),
             "team": dict(marker="D", color="C0", s=50),
             "confirmation": dict(marker="*", color="C3", s=140)}  # fmt: skip
    fig, ax = plt.subplots(figsize=(6.0, 4.4))
    for kind, kw in style.items():
        pts = [p for p in points if p.get("kind", "finalist") == kind]
        if pts:
            ax.scatter([p["inner_pct"] for p in pts], [p["live_per_run"] for p in pts],
                       zorder=3, label=kind, ec="k", lw=0.4, **kw)  # fmt: skip
        for p in pts:
            ax.annotate(p["label"], (p["inner_pct"], p["live_per_run"]), fontsize=6.5,
                        xytext=(4, 3), textcoords="offset points")  # fmt: skip
    chosen = [p for p in points if p.get("kind") in joined]
    for a, b in zip(chosen[:-1], chosen[1:], strict=True):
        ax.annotate("", (b["inner_pct"], b["live_per_run"]), (a["inner_pct"], a["live_per_run"]),
                    arrowprops=dict(arrowstyle="->", color="C3", lw=0.9))  # fmt: skip
    if min_live > 0:
        ax.axhline(min_live, color="k", ls="--", lw=0.9, label=f"{min_live:g} of {robots} live")
    ax.set_xlabel("colony inner coverage, physics (% of the inner squares)")
    ax.set_ylabel(f"robots live at the end per run (of {robots})")
    ax.set_ylim(-0.1, robots + 0.1)
    ax.set_title(title, fontsize=8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return _save(fig, Path(path))


def run_track(
    chromosome: np.ndarray,
    *,
    table: GaitTable | np.ndarray,
    world: WorldSettings,
    start: tuple[float, float, float],
    mode: str = "coverage",
    max_steps: int | None = None,
) -> Any:
    """Run ``chromosome`` from ``start`` with the reference interpreter on the table world."""
    from evolve.interpreter import run
    from evolve.world import TableWorld

    values = getattr(table, "values", table)
    tw = TableWorld(values, *start, world)
    steps = (
        max_steps
        if max_steps is not None
        else (world.coverage_steps if mode == "coverage" else world.navigation_steps)
    )
    return run(
        np.asarray(chromosome, np.uint8),
        tw,
        mode=mode,
        settings=world,
        start_power=world.start_power_v,
        max_steps=steps,
    )


def _draw_track(
    ax: Any, track: np.ndarray, colour: str, label: str, start_colour: str, end_colour: str,
    heading: float, end_marker: str = "s",
) -> None:  # fmt: skip
    """A track (rows x, y, …) as a line, its start (circle and heading arrow) and its end."""
    track = np.asarray(track, dtype=float)
    ax.plot(track[:, 0], track[:, 1], lw=0.9, color=colour, zorder=6, label=label)
    ax.plot(*track[0, :2], "o", color=start_colour, mec="k", mew=0.4, ms=6, zorder=7,
            label="start" if label == "track" else None)  # fmt: skip
    ax.plot(*track[-1, :2], end_marker, color=end_colour, ms=5, zorder=7,
            label="end" if label == "track" else None)  # fmt: skip
    h = np.deg2rad(heading)
    x, y = track[0, 0], track[0, 1]
    ax.arrow(x, y, HEADING_ARROW * np.sin(h), HEADING_ARROW * np.cos(h), width=1.5,
             color=start_colour, zorder=7)  # fmt: skip


def draw_colony_robot(
    ax: Any, i: int, track: np.ndarray, label: str, end: int, disc_radius: float
) -> None:
    """Colony robot ``i``'s track (rows x, y, heading) in its colour (``ROBOT_COLOURS``),
    its start and heading, its end (a square when it lived to its step limit, an × when it
    ended early) and its final disc."""
    c = ROBOT_COLOURS[i % len(ROBOT_COLOURS)]
    track = np.asarray(track, dtype=float)
    marker = "s" if end == END_STEP_LIMIT else "X"
    _draw_track(ax, track, c, label, c, c, float(track[0, 2]), marker)
    ax.add_patch(patches.Circle(tuple(track[-1, :2]), disc_radius, fill=False, ec=c, lw=1.0,
                                zorder=7))  # fmt: skip


def run_colony_track(
    chromosome: np.ndarray,
    *,
    table: GaitTable | np.ndarray,
    world: WorldSettings,
    colony: ColonySettings,
    starts: np.ndarray,
) -> Any:
    """Run ``chromosome`` on a colony from ``starts`` (R, 3) with the reference interpreter
    on the table world (coverage mode)."""
    from evolve.interpreter import run_colony
    from evolve.world import TableColony

    values = getattr(table, "values", table)
    tc = TableColony(values, starts, world, colony)
    return run_colony(
        np.asarray(chromosome, np.uint8), tc, settings=world, colony=colony,
        start_power=world.start_power_v,
    )  # fmt: skip


def colony_figure10(
    path: str | Path,
    chromosome: np.ndarray,
    *,
    table: GaitTable | np.ndarray,
    world: WorldSettings,
    colony: ColonySettings,
    starts: np.ndarray,
    title: str = "",
) -> dict[str, Any]:
    """Figure 10 for a colony: every robot's track from its pose in ``starts`` (R, 3), one
    colour per robot, over the arena with the colony's squares; each robot's final disc, an
    × on robots that ended early. Returns the colony's and each robot's numbers."""
    res = run_colony_track(chromosome, table=table, world=world, colony=colony, starts=starts)
    fig, ax = _arena_plot(world, frozenset(res.reached))
    robots = []
    for i, r in enumerate(res.robots):
        label = f"robot {i}: {r.squares} sq, {r.docks} docks, {_end_name(r.end)}"
        draw_colony_robot(ax, i, r.track, label, r.end, colony.disc_radius)
        robots.append({"robot": i, **_run_info(r), **_counts(r, "collisions", "station_waits")})
    info = _counts(res, "squares", "inner_squares", "colony_steps", "collisions", "station_waits")
    info["robots"] = robots
    text = (
        f"Figure 10 {title}: a colony of {len(robots)} — {info['squares']} squares "
        f"({info['inner_squares']} inner), {info['station_waits']} station waits, "
        f"{info['collisions']} blocked moves"
    )
    _save_arena(fig, ax, path, text, title_size=8, legend_size=6.5)
    return info


def _end_name(end: Any) -> str:
    return END_NAMES[int(end)] if isinstance(end, int | np.integer) else str(end)


def _counts(res: Any, *names: str) -> dict[str, Any]:
    """``{name: int(res.name)}`` for each of ``names``, in that order."""
    return {name: int(getattr(res, name)) for name in names}


def _run_info(res: Any) -> dict[str, Any]:
    """A run's ``{squares, inner_squares, docks, steps, end}`` (end by name)."""
    return _counts(res, "squares", "inner_squares", "docks", "steps") | {"end": _end_name(res.end)}


def figure10(
    path: str | Path,
    chromosome: np.ndarray,
    *,
    table: GaitTable | np.ndarray,
    world: WorldSettings = geometry.DEFAULT_WORLD,
    start: tuple[float, float, float] = (415.0, 252.0, 98.0),
    title: str = "",
) -> dict[str, Any]:
    """Figure 10: the track of a 16-gene ``chromosome`` from ``start`` over the arena, with
    the squares it reached. Returns ``{squares, inner_squares, docks, steps, end}``."""
    res = run_track(chromosome, table=table, world=world, start=start)
    fig, ax = _arena_plot(world, frozenset(res.reached))
    _draw_track(ax, res.track, "tab:blue", "track", "tab:green", "tab:red", start[2])
    info = _run_info(res)
    text = (
        f"Figure 10 {title}: from ({start[0]:g}, {start[1]:g}, {start[2]:g}°) — "
        f"{info['squares']} squares ({info['inner_squares']} inner), "
        f"{info['docks']} docks, {info['steps']} steps, end: {info['end']}"
    )
    _save_arena(fig, ax, path, text, title_size=8)
    return info


__all__ = [
    "colony_figure10",
    "draw_colony_robot",
    "draw_arena",
    "figure8",
    "figure9",
    "figure10",
    "figure_anytime",
    "figure_colony_choice",
    "figure_colony_docks",
    "lit_mask",
    "run_colony_track",
    "run_track",
]
