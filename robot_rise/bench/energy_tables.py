"""Tables of the energy-planner benchmark (issue 7): the BENCHMARKS.md Markdown, made from its rows.

:func:`energy_report` is what ``robot-rise bench energy`` prints: the summary per problem set and
planner, the paired counts of the lowest jerk (three measures) among the three planners and, for
each ablation that ran, in place of the planner it ablates, then one line per failed run.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from robot_rise.bench.energy import ABLATIONS, PLANNER_NAMES, THREE, BenchRow
from robot_rise.bench.energy_metrics import common_duration_jerk

__all__ = ["with_common_duration_jerk", "summary_table", "paired_jerk_table", "energy_report"]

JERK_MEASURES = ("jerk", "jerk_common_duration", "dimensionless_jerk")  # the paired counts, one table each


def with_common_duration_jerk(rows: list[BenchRow], reference: tuple[str, ...] = THREE) -> list[BenchRow]:
    """Rows with ``jerk_common_duration``: each problem's jerks at the longest duration of the ``reference`` planners on it.

    The reference duration of a problem is the longest timed duration among the rows of the
    ``reference`` planners that solved it (all rows when none of them is present); unsolved rows
    keep NaN.
    """
    ref: dict[tuple[str, str, int], float] = {}
    have_ref = any(r.planner in reference for r in rows)
    for r in rows:
        if r.solved and (r.planner in reference or not have_ref):
            k = (r.pset, r.kind, r.variant)
            ref[k] = max(ref.get(k, 0.0), r.duration_s)
    out = []
    for r in rows:
        k = (r.pset, r.kind, r.variant)
        val = common_duration_jerk(r.jerk, r.duration_s, ref[k]) if r.solved and k in ref else math.nan
        out.append(dataclasses.replace(r, jerk_common_duration=val))
    return out


def _groups(rows: list[BenchRow]) -> list[tuple[str, str, list[BenchRow]]]:
    """(planner, problem label, rows): crossed kinds one by one, lying60 as one set."""
    keys: list[tuple[str, str]] = []
    for r in rows:
        k = (r.planner, r.kind if r.pset == "crossed" else r.pset)
        if k not in keys:
            keys.append(k)
    return [(p, lab, [r for r in rows if r.planner == p and (r.kind if r.pset == "crossed" else r.pset) == lab]) for p, lab in keys]


def summary_table(rows: list[BenchRow]) -> str:
    """Markdown table per problem set and planner: success, times, length, clearance, jerks, duration, root motion."""
    rows = with_common_duration_jerk(rows)
    lines = [
        "| problem | planner | success | plan time median / p95 [s] | total time median / p95 [s] | path length median | "
        "min self / ground clearance [mm] | integrated sq. jerk median [rad²/s⁵] | jerk at common duration median [rad²/s⁵] | "
        "dimensionless jerk median | duration median [s] | root travel / rotation median [m / rad] |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    groups = _groups(rows)
    order = {lab: k for k, lab in enumerate(dict.fromkeys(lab for _, lab, _ in groups))}
    pl = {p: k for k, p in enumerate(PLANNER_NAMES)}
    for planner, label, rs in sorted(groups, key=lambda g: (order[g[1]], pl.get(g[0], 99))):
        ok = [r for r in rs if r.solved]

        def med(vals: list[float]) -> str:
            return f"{np.median(vals):.3g}" if vals else "-"

        def mp(vals: list[float]) -> str:
            return f"{np.median(vals):.2f} / {np.percentile(vals, 95):.2f}" if vals else "-"

        clear = f"{1000 * min(r.min_self_clearance_m for r in ok):.1f} / {1000 * min(r.min_ground_clearance_m for r in ok):.1f}" if ok else "-"
        lines.append(
            f"| {label} | {planner} | {len(ok)}/{len(rs)} ({100 * len(ok) / max(1, len(rs)):.0f} %) | {mp([r.plan_s for r in ok])} | "
            f"{mp([r.total_s for r in ok])} | {med([r.path_length for r in ok])} | {clear} | {med([r.jerk for r in ok])} | "
            f"{med([r.jerk_common_duration for r in ok if not math.isnan(r.jerk_common_duration)])} | "
            f"{med([r.dimensionless_jerk for r in ok if not math.isnan(r.dimensionless_jerk)])} | {med([r.duration_s for r in ok])} | "
            f"{med([r.root_travel_m for r in ok if not math.isnan(r.root_travel_m)])} / "
            f"{med([r.root_rotation_rad for r in ok if not math.isnan(r.root_rotation_rad)])} |"
        )
    return "\n".join(lines)


def paired_jerk_table(rows: list[BenchRow], measure: str = "jerk") -> str:
    """Per problem label: on how many problems solved by all planners each planner had the lowest ``measure``.

    A planner counts a problem only when it is strictly lowest there; equal lowest values (e.g. two
    planners returning the same straight motion) are counted in the ``tied`` column, not given to
    the first planner. ``jerk_common_duration`` must already be filled (``with_common_duration_jerk``)
    to rank by it.
    """
    names = list(dict.fromkeys(r.planner for r in rows))
    lines = ["| problem | solved by all | " + " | ".join(f"{n} lowest {measure.replace('_', ' ')}" for n in names) + " | tied |",
             "| --- | --- |" + " --- |" * (len(names) + 1)]
    labels = list(dict.fromkeys(r.kind if r.pset == "crossed" else r.pset for r in rows))
    for lab in labels:
        by: dict[tuple[str, int], dict[str, BenchRow]] = {}
        for r in rows:
            if (r.kind if r.pset == "crossed" else r.pset) == lab:
                by.setdefault((r.kind, r.variant), {})[r.planner] = r
        common = [v for v in by.values() if len(v) == len(names) and all(x.solved for x in v.values())]
        wins = dict.fromkeys(names, 0)
        tied = 0
        for v in common:
            low = min(getattr(x, measure) for x in v.values())
            best = [n for n, x in v.items() if getattr(x, measure) <= low]
            if len(best) == 1:
                wins[best[0]] += 1
            else:
                tied += 1
        lines.append(f"| {lab} | {len(common)} | " + " | ".join(str(wins[n]) for n in names) + f" | {tied} |")
    return "\n".join(lines)


def energy_report(rows: list[BenchRow]) -> str:
    """The benchmark's Markdown: summary table, paired jerk counts (the three planners, then each ablation's trio), failures."""
    out = [summary_table(rows), ""]
    three = with_common_duration_jerk([r for r in rows if r.planner in THREE])  # the paired counts compare the three planners
    out += _paired_tables(three)
    for abl in ABLATIONS:  # each ablation in place of the energy planner (RRT-blossom's in its place)
        if any(r.planner == abl for r in rows):
            trio = (("energy_oldsmooth" if abl.endswith("oldsmooth") else "energy_abc"), abl, "ompl_rrtconnect") if abl.startswith("rrt_blossom") else (abl, "rrt_blossom", "ompl_rrtconnect")
            if not all(any(r.planner == n for r in rows) for n in trio):
                continue
            alt = with_common_duration_jerk([r for r in rows if r.planner in trio], reference=trio)
            out += _paired_tables(alt)
    out += [f"- {r.planner} {r.pset} {r.kind}/{r.variant}: {r.reason[:300]}" for r in rows if not r.solved]
    return "\n".join(out)


def _paired_tables(rows: list[BenchRow]) -> list[str]:
    """The paired counts of ``rows`` by each of JERK_MEASURES, each table followed by a blank line."""
    out: list[str] = []
    for measure in JERK_MEASURES:
        out += [paired_jerk_table(rows, measure), ""]
    return out
