"""``REPORT.md`` of a reproduction: every figure and number the stages left in the run folder.

Read-only over the run folder (``write_report`` reads the stages' files and writes one
Markdown file), so it can be rewritten at any time, also after a failed stage.
"""

from __future__ import annotations

import datetime as dt
import json
import platform
from pathlib import Path
from typing import Any

import numpy as np

from calibration.report import TOLERANCE, within_tolerance
from evolve.settings import WorldSettings
from evolve.table import PAPER_TABLE, load_table
from infra.io import atomic_write_text
from servo_mj.robot.model import model_label
from servobot.reproduce.settings import ReproduceSettings
from servobot.robustness.matrix_choice import choice_line as matrix_choice_line
from servobot.robustness.report import MEAN_AND_DROP, matrix_table
from servobot.validation.colony_choice import choice_line
from servobot.validation.colony_team import team_line


def _load_json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _img(out: Path, path: Path, alt: str) -> list[str]:
    if not path.exists():
        return [f"*({alt}: {path.relative_to(out)} not written)*", ""]
    return [f"![{alt}]({path.relative_to(out).as_posix()})", ""]


def format_seconds(seconds: float) -> str:
    """``12.3 s`` below two minutes, else ``4.5 min``."""
    return f"{seconds:.1f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def _calibration_section(out: Path) -> list[str]:
    lines = ["## 1. Calibration (Figure 4 rebuilt in MuJoCo)", ""]
    lines += _img(out, out / "calibration" / "figure4.png", "Figure 4: measured vs paper")
    try:
        table = load_table(str(out / "calibration" / "gait_table.json"))
    except Exception as exc:  # noqa: BLE001 - the report names what is missing
        return [*lines, f"*(gait table unreadable: {exc})*", ""]
    v, std = table.values, table.std
    err = v - PAPER_TABLE
    lines += [
        "| gait | F | T | dH | paper F | paper T | paper dH | err F | err T | err dH |"
        + (" std F | std T | std dH |" if std is not None else ""),
        "|" + "---|" * (13 if std is not None else 10),
    ]
    for g in range(16):
        row = (
            f"| {g} | {v[g, 0]:.2f} | {v[g, 1]:.2f} | {v[g, 2]:.2f} | {PAPER_TABLE[g, 0]:g} | "
            f"{PAPER_TABLE[g, 1]:g} | {PAPER_TABLE[g, 2]:g} | {err[g, 0]:+.2f} | "
            f"{err[g, 1]:+.2f} | {err[g, 2]:+.2f} |"
        )
        if std is not None:
            row += f" {std[g, 0]:.2f} | {std[g, 1]:.2f} | {std[g, 2]:.2f} |"
        lines.append(row)
    mx = np.abs(err).max(axis=0)
    ok = within_tolerance(v)
    lines += [
        "",
        f"Largest error: F {mx[0]:.2f} cm, T {mx[1]:.2f} cm, dH {mx[2]:.2f}°. Entries within "
        f"{TOLERANCE[0]:g} cm (F, T) / {TOLERANCE[2]:g}° (dH) of the paper: {int(ok.sum())} of "
        f"48; gaits with all three "
        f"within: {int(ok.all(axis=1).sum())} of 16. Std = per-cycle standard deviation.",
        "",
    ]
    if table.dv is not None:
        dv = ", ".join(f"{g}: {v:.4f}" for g, v in enumerate(table.dv))
        lines += [f"Voltage drop per cycle from the servo model (V; paper 0.0209): {dv}.", ""]
    return lines


def _navigation_section(out: Path) -> list[str]:
    summ = _load_json(out / "navigation" / "summary.json")
    lines = ["## 2. Navigation (evolved on the calibrated table)", ""]
    if summ is None:
        return [*lines, "*(navigation/summary.json not written)*", ""]
    steps = summ.get("mean_steps_to_dock")
    sel = summ.get("selection", {})
    lines += [
        f"Chosen section (`navigation/best.txt`): generation {summ.get('chosen_generation')} of "
        f"population {summ['chosen_population']}, the best of {len(summ.get('candidates', []))} "
        f"candidates by {sel.get('criterion', 'fitness')} on {sel.get('selection_starts', '—')} "
        f"selection starts; docking success on {summ['test_starts']} fresh test starts: "
        f"**{100 * summ['dock_success']:.0f}%**"
        + (f", mean {steps:.1f} steps to dock." if steps is not None else "."),
        "",
    ]
    env = "envelope_dock_success" in summ
    if env:
        e_steps = summ.get("envelope_mean_steps_to_dock")
        lines += [
            "In its envelope, on the same test starts: "
            f"**{100 * summ['envelope_dock_success']:.0f}%**"
            + (f", mean {e_steps:.1f} steps to dock." if e_steps is not None else ".")
            + " The figure above is the exact world's (SPEC §3).",
            "",
        ]
    lines += [
        *_docking_rows(out, summ),
        "",
        "Each population's final best on the test starts:",
        "",
        "| population | test fitness | dock rate | final training fitness |"
        + (" test fitness (envelope) | dock rate (envelope) |" if env else ""),
        "|---|---|---|---|" + ("---|---|" if env else ""),
    ]
    for p in summ.get("populations", []):
        row = (
            f"| {p['population']} | {p['test_fitness']:.3f} | {100 * p['dock_rate']:.0f}% | "
            f"{p['final_training_fitness']:.3f} |"
        )
        if env and "envelope_dock_rate" in p:
            row += f" {p['envelope_test_fitness']:.3f} | {100 * p['envelope_dock_rate']:.0f}% |"
        lines.append(row)
    return [*lines, ""]


def _docking_rows(out: Path, nav: dict[str, Any]) -> list[str]:
    """Where the chosen section docks from, in the table world and in physics."""
    rows = [
        "| the navigation section, from | runs | docked (table world) | docked (physics) |",
        "|---|---|---|---|",
        f"| fresh navigation starts (the stage's test starts) | {nav['test_starts']} | "
        f"{100 * nav['dock_success']:.0f}% | |",
    ]
    if "envelope_dock_success" in nav:
        rows.append(
            f"| the same test starts, in the envelope | {nav['test_starts']} | "
            f"{100 * nav['envelope_dock_success']:.0f}% (envelope) | |"
        )
    cov = _load_json(out / "coverage" / "summary.json") or {}
    ho = cov.get("handoffs", {}).get("all")
    if ho and ho.get("dock_rate") is not None:
        rows.append(
            f"| the finalists' hand-offs on the Figure 9 test starts (in the coverage runs) | "
            f"{ho['docked'] + ho['failed']} (+{ho['cut']} cut by the step limit) | "
            f"{100 * ho['dock_rate']:.0f}% | |"
        )
    for name, what in (
        ("navigation_fresh", "fresh navigation starts (validation)"),
        ("navigation_handoffs", "hand-off poses and powers (validation)"),
    ):
        rep = _load_json(out / "validation" / name / "report.json")
        if rep is None:
            continue
        sm = rep["summary"]
        t, ph = sm.get("table_paired", {}), sm.get("physics", {})
        if t.get("runs"):
            rows.append(
                f"| {what} | {sm['physics_ok']}/{sm['starts']} | {100 * t['dock_success']:.0f}% | "
                f"{100 * ph['dock_success']:.0f}% |"
            )
    return rows


def _coverage_section(out: Path) -> list[str]:
    summ = _load_json(out / "coverage" / "summary.json")
    lines = ["## 3. Area coverage (Figures 8, 9, 10)", ""]
    lines += _img(out, out / "figure8.png", "Figure 8: arena, lit cones and dark area")
    lines += _img(out, out / "coverage" / "figure9.png", "Figure 9: inner coverage by generation")
    if summ is None:
        return [*lines, "*(coverage/summary.json not written)*", ""]
    lines += _figure9_lines(summ, "best individual")
    lines += ["Figure 10: each population's final best from (415, 252, 98°).", ""]
    for f in summ.get("figure10", []):
        k = f["population"]
        desc = ", ".join(f"{a} {f[a]}" for a in ("squares", "docks", "end") if a in f)
        lines += [f"Population {k}: {desc}", ""]
        lines += _img(out, out / "coverage" / f"figure10_pop{k}.png", f"Figure 10 pop {k}")
    return lines


def _figure9_lines(summ: dict[str, Any], who: str) -> list[str]:
    """A stage's Figure 9 (``summary.json``): the last generation's mean and per population,
    in the envelope too when it evolved in one, and the table by generation; ``who``: whose
    inner coverage it is."""
    gens = summ["generations"]
    inner = np.asarray(summ["figure9_inner_percent"])
    lines = [
        f"Figure 9 at generation {gens[-1]} ({who} on {summ['test_starts']} fresh "
        f"starts, % of the 64 inner squares): mean **{summ['final_mean_inner_percent']:.1f}%**"
        "; per population " + ", ".join(f"{k}: {v:.1f}%" for k, v in enumerate(inner[:, -1])) + ".",
        "",
    ]
    env = "envelope_final_mean_inner_percent" in summ
    e_mean = np.asarray(summ.get("envelope_figure9_mean_inner_percent", []))
    if env:
        e_final = summ["envelope_final_inner_percent"]
        lines += [
            f"In the envelope, on the same test starts: mean "
            f"**{summ['envelope_final_mean_inner_percent']:.1f}%**; per population "
            + ", ".join(f"{k}: {v:.1f}%" for k, v in enumerate(e_final))
            + ". The figure and the table's population columns are the exact world's (SPEC §3).",
            "",
        ]
    lines += [
        "| generation | "
        + " | ".join(f"pop {k}" for k in range(len(inner)))
        + " | mean |"
        + (" mean (envelope) |" if env else ""),
        "|---|" + "---|" * (len(inner) + 1 + int(env)),
    ]
    for j, g in enumerate(gens):
        lines.append(
            f"| {g} | "
            + " | ".join(f"{inner[k, j]:.1f}" for k in range(len(inner)))
            + f" | {inner[:, j].mean():.1f} |"
            + (f" {e_mean[j]:.1f} |" if env and j < len(e_mean) else "")
        )
    return [*lines, ""]


def _validation_section(out: Path, s: ReproduceSettings) -> tuple[list[str], list[Path]]:
    lines = [
        "## 4. Reality gap: table simulation vs MuJoCo physics",
        "",
        f"Each finalist (`coverage/best_pop{{k}}.txt`) from the same {s.validate_starts} "
        f"seeded coverage starts, {s.validate_max_steps} steps, in the table world and in "
        "physics. Inner % = mean inner squares / 64; dock = share of runs with ≥ 1 dock; gap = "
        "table − physics over the runs whose physics finished.",
        "",
        "| finalist | runs ok | table inner % | physics inner % | gap (pp) | table dock | "
        "physics dock | dock gap (pp) | physics errors | wall |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    rrds: list[Path] = []
    gaps, t_in, p_in, t_dk, p_dk = [], [], [], [], []
    for k in range(s.coverage_populations):
        sub = out / "validation" / f"pop{k}"
        rep = _load_json(sub / "report.json")
        rrds += sorted(sub.glob("run*.rrd"), key=lambda p: int(p.stem[3:] or 0))
        if rep is None:
            lines.append(f"| {k} | — | — | — | — | — | — | — | not run | — |")
            continue
        sm = rep["summary"]
        tp, ph, gap = sm.get("table_paired", {}), sm.get("physics", {}), sm.get("gap", {})
        if gap.get("runs", 0):
            gaps.append(gap["inner_pct_pp"])
            t_in.append(tp["inner_pct"])
            p_in.append(ph["inner_pct"])
            t_dk.append(tp["dock_success"])
            p_dk.append(ph["dock_success"])
            lines.append(
                f"| {k} | {gap['runs']}/{sm['starts']} | {tp['inner_pct']:.1f} | "
                f"{ph['inner_pct']:.1f} | {gap['inner_pct_pp']:+.1f} | "
                f"{100 * tp['dock_success']:.0f}% | {100 * ph['dock_success']:.0f}% | "
                f"{gap['dock_success_pp']:+.0f} | {sm['physics_errors']} | "
                f"{format_seconds(sm['wall_s'])} |"
            )
        else:
            lines.append(
                f"| {k} | 0/{sm['starts']} | — | — | — | — | — | — | {sm['physics_errors']} | "
                f"{format_seconds(sm['wall_s'])} |"
            )
    if gaps:
        lines.append(
            f"| **all** | | **{np.mean(t_in):.1f}** | **{np.mean(p_in):.1f}** | "
            f"**{np.mean(gaps):+.1f}** | {100 * np.mean(t_dk):.0f}% | {100 * np.mean(p_dk):.0f}% "
            f"| {100 * (np.mean(t_dk) - np.mean(p_dk)):+.0f} | | |"
        )
    lines += ["", "Per-run details: `validation/pop{k}/report.md`.", ""]
    return lines, rrds


def _robustness_section(out: Path, s: ReproduceSettings) -> list[str]:
    folder = out / "robustness"
    lines = ["## 5. Robustness: the finalists in physics worlds (SPEC §9)", ""]
    if s.model is not None:
        return [*lines, "*(not run: the test matrix's worlds are variants of the shipped "
                "robot, and this run's robot is another)*", ""]  # fmt: skip
    doc = _load_json(folder / "robustness.json")
    if doc is None:
        return [*lines, "*(robustness/robustness.json not written)*", ""]
    lines += [
        f"The {finalists_phrase(s)} (`coverage/best_pop{{k}}.txt`), unchanged, from the same "
        f"{doc['starts']} "
        f"seeded coverage starts (seed {doc['seed']}), {doc['steps']} steps, in the table world "
        "(the calibrated table) and in every built-in physics world "
        "(`servobot.robustness.worlds`); % of the 64 inner squares reached, mean over the runs "
        "whose physics finished. `long-legs` is held out: no choice may look at it.",
        "",
        *_img(out, folder / "robustness.png", "Robustness: finalists × physics worlds"),
        *matrix_table(doc),
        "",
        MEAN_AND_DROP,
        "",
        "| world | what it changes | physics errors |",
        "|---|---|---|",
        *(f"| {w['name']} | {w['description']} | {w['physics_errors']} |" for w in doc["worlds"]),
        "",
        "How runs end, model hashes: `robustness/robustness.md`; each cell's validation: "
        "`robustness/runs/{world}/best_pop{k}/report.md`.",
        "",
        matrix_choice_line(doc),
        "",
    ]
    return lines


COLONY_RECORDINGS = (
    "A colony's (`colony_validation/`) holds every robot in its colour and a `colony` tab with "
    'the station\'s and each robot\'s states (docs/colony.md, "Recordings").'
)
"""The Recordings section's line on the colony validation's recordings."""


def _number(value: float | None, fmt: str) -> str:
    """``value`` formatted, ``—`` for None."""
    return "—" if value is None else f"{value:{fmt}}"


def _robots_cell(values: list[float], fmt: str = ".2f") -> str:
    """Each robot's number, robot 0 first (``—`` when none)."""
    return " / ".join(f"{v:{fmt}}" for v in values) or "—"


def _start_powers(spread: float) -> str:
    """The colony's start powers in words: equal, or staggered by ``spread`` volts."""
    return f"staggered by {spread:g} V" if spread else "equal"


def _contact_yaw(deg: float) -> str:
    """The contact yaw in words (nothing when 0)."""
    return f", a blocked move turning {deg:g}° away from a robot abeam" if deg else ""


def _live_cells(finalist: dict[str, Any]) -> str:
    """A finalist's robots live at the end per run, table and physics cells ("—" for a
    validation recorded before the count was kept, or with no run)."""
    live = finalist.get("live_at_end", {})
    return " | ".join(_number(live.get(w), ".2f") for w in ("table", "physics"))


def _colony_section(out: Path, s: ReproduceSettings) -> tuple[list[str], list[Path]]:
    """The colony stages: the colony's Figure 9 and table-world test, its finalists in physics
    (gap, each robot's docks and station waits, tracks), and their recordings."""
    r = s.robots
    lines = [
        f"## 6. A colony of {r} robots sharing the station (SPEC §7)",
        "",
        f"Coverage learned by a colony of {r} (`servobot evolve colony`; table-world blocking "
        f"`{s.colony_blocking}`, fitness `{s.colony_fitness}`, start powers "
        f"{_start_powers(s.colony_start_power_spread)}, the other robots "
        f"{'seen' if s.colony_robots_seen else 'unseen'} by the object sensors"
        f"{_contact_yaw(s.colony_contact_yaw_deg)}), with the "
        "coverage stage's budget and test starts, the "
        "navigation section `navigation/best.txt` fixed, on the calibrated table. Colony inner "
        "% = squares reached by any robot / 64.",
        "",
        *_img(out, out / "colony" / "figure9.png", "Figure 9 of the colony"),
    ]
    rrds: list[Path] = []
    summ = _load_json(out / "colony" / "summary.json")
    if summ is None:
        return [*lines, "*(colony/summary.json not written)*", ""], rrds
    lines += _figure9_lines(summ, f"best individual as a colony of {r}")
    lines += [
        f"Each population's final best on the {summ['test_starts']} colony test starts "
        "(table world), and the same best alone from robot 0's poses:",
        "",
        "| population | colony inner % | per robot inner % | docks per robot | station waits "
        "per run | blocked moves per run | alone inner % |",
        "|---|---|---|---|---|---|---|",
        *(f"| {t['population']} | {t['colony_inner_percent']:.1f} | "
          f"{t['robot_inner_percent']:.1f} | {t['docks_per_robot']:.2f} | "
          f"{t['station_waits_per_run']:.2f} | {t['collisions_per_run']:.2f} | "
          f"{t['one_robot_inner_percent']:.1f} |" for t in summ["final_test"]),
        "",
        "Tracks of every robot from one colony start: `colony/figure10_pop{k}.png`.",
        "",
    ]  # fmt: skip
    folder = out / "colony_validation"
    done = _load_json(folder / "done.json")
    info = (done or {}).get("info", {})
    lines += [
        f"### The colony in physics ({r} ServoBots in one MuJoCo arena)",
        "",
        f"Each colony finalist (`colony/best_pop{{k}}.txt`) from the same "
        f"{s.colony_validate_starts} seeded colony starts (`colony_validation/starts.json`), "
        f"up to {s.validate_max_steps} steps per robot, in the table world and in physics "
        "(`servobot validate --robots`). Gap = table − physics over the runs whose physics "
        "finished; docks and station waits: each robot's mean per run, robot 0 first.",
        "",
    ]
    if "colony_finalists" not in info:
        return [*lines, "*(colony_validation not finished)*", ""], rrds
    lines += [
        f"| finalist | runs ok | table inner % | physics inner % | gap (pp) | live at the end "
        f"(of {r}), table | physics | docks per robot, table | physics | station waits per "
        "robot, table | physics | physics errors |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for k, f in info["colony_finalists"].items():
        t_in, p_in, gap = f["table_inner_percent"], f["physics_inner_percent"], f["gap_inner_pp"]
        lines.append(
            f"| {k} | {f['runs_ok']}/{f['starts']} | {_number(t_in, '.1f')} | "
            f"{_number(p_in, '.1f')} | {_number(gap, '+.1f')} | "
            f"{_live_cells(f)} | {_robots_cell(f['docks']['table'])} | "
            f"{_robots_cell(f['docks']['physics'])} | "
            f"{_robots_cell(f['station_waits']['table'])} | "
            f"{_robots_cell(f['station_waits']['physics'])} | {f['physics_errors']} |"
        )
    if info.get("gap_inner_pp") is not None:
        lines.append(f"| **all** | | | | **{info['gap_inner_pp']:+.1f}** | | | | | | | |")
    lines += ["", choice_line(folder, r), "", team_line(folder, r)]
    lines += ["", "Tracks from the first colony start (table world left, physics right):", ""]
    for k in info["colony_finalists"]:
        sub = folder / f"pop{k}"
        lines += _img(out, sub / "tracks0.png", f"colony finalist {k}: tracks")
        rrds += sorted(sub.glob("run*.rrd"), key=lambda p: int(p.stem[3:] or 0))
    lines += ["Per-run and per-robot details: `colony_validation/pop{k}/report.md`.", ""]
    return lines, rrds


def finalists_phrase(s: ReproduceSettings) -> str:
    """Which finalists the matrix ran: all of them, or the best n by Figure 9."""
    n = s.matrix_finalists()
    if n == s.coverage_populations:
        return f"{n} finalists" if n > 1 else "finalist"
    return f"{n} best finalists by Figure 9" if n > 1 else "best finalist by Figure 9"


def _field(v: bool | float | str) -> str:
    """An envelope field's value as the report prints it: true / false, a number, a name."""
    if isinstance(v, bool):
        return str(v).lower()
    return f"{v:g}" if isinstance(v, int | float) else str(v)


def _envelope_line(s: ReproduceSettings) -> str:
    """Which table world navigation and coverage evolved in."""
    try:
        env = s.envelope_value()
    except Exception as exc:  # noqa: BLE001 - the report names what is missing
        return f"Envelope: `{s.envelope}` *(unreadable now: {exc})*."
    if not env.varies:
        return "Envelope: `none` (navigation and coverage evolved in the exact world, SPEC §3)."
    fields = ", ".join(f"{k} {_field(v)}" for k, v in env.to_dict().items())
    return (
        f"Envelope: `{s.envelope}` ({fields}; SPEC §9): navigation and coverage evolved in it; "
        "their test figures are given in the envelope and in the exact world (SPEC §3), on the "
        "same test starts. Validation and the robustness matrix run the exact table world."
    )


def write_report(
    out: Path,
    s: ReproduceSettings,
    world: WorldSettings,
    stages: dict[str, dict[str, Any]],
    *,
    total_wall_s: float,
    ncpu: int,
) -> Path:
    """Write ``out/REPORT.md`` from the files the stages left in ``out``."""
    now = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    lines = [
        "# ServoBot colony reproduction — report",
        "",
        f"Written {now} on {platform.node() or 'this machine'} ({ncpu} CPU cores, "
        f"Python {platform.python_version()}). Settings: `settings.json`; seed {s.seed}. "
        f"Robot: {model_label(s.model)}.",
        "",
        _envelope_line(s),
        "",
        "| stage | wall time | this invocation |",
        "|---|---|---|",
    ]
    for name in s.stages():
        st = stages.get(name)
        if st is None:
            lines.append(f"| {name} | — | not reached |")
        else:
            how = st.get("failed") or ("skipped (done earlier)" if st.get("skipped") else "ran")
            lines.append(f"| {name} | {format_seconds(float(st['wall_s']))} | {how} |")
    ran = sum(float(st["wall_s"]) for st in stages.values())
    lines += [
        f"| **all stages** | **{format_seconds(ran)}** | this invocation took "
        f"{format_seconds(total_wall_s)} |",
        "",
    ]
    lines += _calibration_section(out)
    lines += _navigation_section(out)
    lines += _coverage_section(out)
    vlines, rrds = _validation_section(out, s)
    lines += vlines
    lines += _robustness_section(out, s)
    section = 6
    if s.colony() is not None:
        clines, crrds = _colony_section(out, s)
        lines += clines
        rrds += crrds
        section += 1
    if (out / "calibration" / "calibration.rrd").exists():
        rrds.insert(0, out / "calibration" / "calibration.rrd")
    lines += [f"## {section}. Recordings", "", "Open any run in the rerun viewer:", ""]
    by_folder: dict[str, list[str]] = {}
    for p in rrds:
        by_folder.setdefault(p.parent.relative_to(out).as_posix(), []).append(p.name)
    for folder, names in by_folder.items():
        more = f" ({len(names)} recordings in `{folder}/`)" if len(names) > 1 else ""
        lines.append(f"- `rerun {folder}/{names[0]}`{more}")
    if not by_folder:
        lines.append("*(none)*")
    lines += [
        "",
        "Each holds the arena, the robot's bodies, the physics (orange) and table (blue) tracks,",
        "squares as reached, power, sensors, mode and squares over time, and the instructions.",
        *([COLONY_RECORDINGS] if s.colony() is not None else []),
        "",
        f"## {section + 1}. Settings",
        "",
        "```json",
        json.dumps({"ReproduceSettings": s.to_dict()}, indent=2),
        "```",
        "",
        "World, GA and physics settings of each stage: `*/settings.json` and",
        "`validation/pop*/report.json`; calibration provenance: `calibration/gait_table.json`;",
        "the test matrix's: `robustness/settings.json`.",
        "",
    ]
    return atomic_write_text(out / "REPORT.md", "\n".join(lines))


__all__ = ["format_seconds", "write_report"]
