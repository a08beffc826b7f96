"""Real-time scheduling for the control loop: applied, restored, or refused with a note."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from drivers.clock import cpu_wakeup_latency, realtime_scheduling


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


def _open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def test_that_the_wake_up_latency_request_is_written_held_and_released(tmp_path: Path) -> None:
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"\xff\xff\xff\xff")
    before = _open_fds()
    with cpu_wakeup_latency(0, device=str(device)) as note:
        assert note == "CPU wake-up latency held at 0 us"
        assert _open_fds() == before + 1  # the request lasts as long as the file is open
    assert device.read_bytes() == b"\x00\x00\x00\x00"  # a 32-bit value, as the kernel reads it
    assert _open_fds() == before


def test_that_a_missing_latency_device_runs_unchanged_and_says_why(tmp_path: Path) -> None:
    with cpu_wakeup_latency(0, device=str(tmp_path / "absent")) as note:
        assert note.startswith("CPU idle states unrestricted") and "No such file" in note


def test_that_no_latency_request_touches_nothing(tmp_path: Path) -> None:
    device = tmp_path / "cpu_dma_latency"
    with cpu_wakeup_latency(None, device=str(device)) as note:
        assert note == "CPU idle states unrestricted"
    assert not device.exists()


def test_that_an_error_in_the_block_does_not_carry_the_refused_request(tmp_path: Path) -> None:
    with pytest.raises(ValueError) as raised:
        with cpu_wakeup_latency(0, device=str(tmp_path / "absent")):
            raise ValueError("the loop's own error")
    assert raised.value.__context__ is None
