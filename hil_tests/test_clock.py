"""Real-time scheduling for the control loop: applied, restored, or refused with a note."""

from __future__ import annotations

import os

import pytest

from drivers.clock import realtime_scheduling


def test_that_no_priority_leaves_scheduling_alone() -> None:
    before = os.sched_getscheduler(0)
    with realtime_scheduling(None) as note:
        assert note == "normal scheduling"
        assert os.sched_getscheduler(0) == before


def test_that_a_refused_priority_runs_normally_and_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(pid: int, policy: int, param: os.sched_param) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    with realtime_scheduling(10) as note:
        assert note.startswith("SCHED_FIFO 10 refused") and "normal scheduling" in note


def test_that_the_previous_policy_is_restored_after_the_block(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[int, int]] = []
    monkeypatch.setattr(os, "sched_setscheduler",
                        lambda pid, policy, param: calls.append((policy, param.sched_priority)))
    before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    with realtime_scheduling(20) as note:
        assert note == "SCHED_FIFO priority 20"
    assert calls == [(os.SCHED_FIFO, 20), before]
