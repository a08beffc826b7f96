"""The bus benchmark end to end (few cycles): figures present and physically possible."""

from __future__ import annotations

import pytest

from robot_rise.bench.bus import bench_bus, format_result


@pytest.mark.parametrize("transport", ["pty", "inprocess"])
def test_that_no_cycle_beats_the_wire_and_every_figure_is_reported(transport: str) -> None:
    r = bench_bus(4_000_000, cycles=40, jitter_s=0.2, transport=transport, cpu_latency_us=None)
    # 20 servos: goal sync write 114 B + Fast Sync Read 34 B + 368 B reply at 4 Mbps
    assert r.wire_limit_hz == pytest.approx(4_000_000 / (516 * 10))
    # the emulator releases each reply only after its bytes would have crossed the wire
    assert 0 < r.cycle_rate_hz <= 1.02 * r.wire_limit_hz
    assert r.pipelined_rate_hz is not None and 0 < r.pipelined_rate_hz <= 1.02 * r.wire_limit_hz
    assert r.host_cpu_per_cycle_s > 0 and r.jitter_p99_at_100hz_s is not None and r.jitter_run_completed
    assert r.fast_read_failures == 0 and r.timeouts == 0
    line = format_result(r)
    assert "wire limit 775 Hz" in line and "CPU idle states unrestricted" in line
