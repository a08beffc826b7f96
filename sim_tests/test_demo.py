"""robot-rise demo: the main job end to end (sample, rise, check, execute on the twin, report)."""

from __future__ import annotations

from robot_rise.cli import main
from robot_rise.trajectory import read_trajectory


def test_that_the_demo_rises_executes_on_the_twin_and_writes_the_report(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--kind", "prone", "--seed", "0"]) == 0
    printed = capsys.readouterr().out
    for stage in ("1. sampled", "2. rise: PROVEN", "3. check (independent replay): PROVEN", "4. execute", "5. report"):
        assert stage in printed, stage
    assert "upright" in printed and "NOT upright" not in printed and "completed" in printed
    assert read_trajectory(out / "rise.json").report["proven"] is True
    assert (out / "execute_log.csv").stat().st_size > 0
    assert (out / "report" / "report.html").exists()
