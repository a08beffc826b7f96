"""The summary of a results store: per robot, scene and kind, how many rose and with what margins."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["summarize", "summary_table"]


def _stat(values: list[float], fn) -> float | None:
    vals = [v for v in values if v is not None and not math.isnan(v)]
    return float(fn(vals)) if vals else None


def _group(rows: Sequence[dict[str, Any]], robot: str, scene: str, kind: str) -> dict[str, Any]:
    ok = [r for r in rows if r["proven"]]
    durations = [r["duration_s"] for r in ok]
    return {
        "robot": robot,
        "scene": scene,
        "kind": kind,
        "tasks": len(rows),
        "proven": len(ok),
        "failed": sum(r["status"] == "failed" for r in rows),
        "success": len(ok) / len(rows) if rows else 0.0,
        "duration_median_s": _stat(durations, np.median),
        "duration_p90_s": _stat(durations, lambda v: np.percentile(v, 90)),
        "worst_tilt_deg": _stat([r["worst_tilt_deg"] for r in ok], max),
        "worst_height_fraction": _stat([r["worst_height_fraction"] for r in ok], min),
        "worst_torque_ratio": _stat([r["worst_torque_ratio"] for r in ok], max),
        "worst_zmp_margin_m": _stat([r["worst_zmp_margin_m"] for r in ok], min),
        "wall_median_s": _stat([r["wall_s"] for r in rows], np.median),
    }


def summarize(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One entry per (robot, scene, kind) in the rows' order, then "all" (every row).

    Durations are of proven rows; worst margins are the worst over the proven rows of each row's
    ensemble worst (None when no proven row has one).
    """
    keys: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        keys.setdefault((r["robot"], r["scene"], r["kind"]), []).append(r)
    out = [_group(rs, *key) for key, rs in keys.items()]
    if len(out) != 1:
        out.append(_group(list(rows), "all", "all", "all"))
    return out


def _fmt(v: Any, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def summary_table(groups: Sequence[dict[str, Any]]) -> str:
    """The summary as an aligned text table (one line per group)."""
    head = ["robot", "scene", "kind", "tasks", "proven", "failed", "success", "dur med [s]", "dur p90 [s]", "tilt max [deg]", "height min", "torque max", "zmp min [m]"]
    lines = [head]
    for g in groups:
        lines.append([
            g["robot"], g["scene"], g["kind"], str(g["tasks"]), str(g["proven"]), str(g["failed"]), f"{100 * g['success']:.0f}%",
            _fmt(g["duration_median_s"], ".2f"), _fmt(g["duration_p90_s"], ".2f"), _fmt(g["worst_tilt_deg"], ".1f"),
            _fmt(g["worst_height_fraction"], ".2f"), _fmt(g["worst_torque_ratio"], ".2f"), _fmt(g["worst_zmp_margin_m"], ".3f"),
        ])
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    return "\n".join("  ".join(c.ljust(w) if i < 3 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))).rstrip() for row in lines)
