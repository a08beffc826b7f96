"""``python -m drivers.mockbus``: serve an emulated bus on a pseudo-terminal (:mod:`drivers.mockbus.pty_server`).

The program :func:`~drivers.mockbus.pty_server.spawn_pty_server` runs in a child process: its
first stdout line, ``DEVICE /dev/pts/N``, tells the parent where the bus is. It is the one
program of ``drivers``, and so the one place in ``drivers`` that configures logging and writes
to stdout (``drivers`` never imports ``robot_rise``, whose ``cli`` is the other such place).
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from collections.abc import Sequence

from drivers.clock import MonotonicClock, realtime_scheduling
from drivers.mockbus.emulator import MockBus
from drivers.mockbus.protocol_dxlsim import parse_ids
from drivers.mockbus.pty_server import DEVICE_LINE_PREFIX, PtyServer

_log = logging.getLogger("drivers.mockbus.pty_server")  # the server's own logger, as before


def main(argv: Sequence[str] | None = None) -> int:  # pragma: no cover - exercised via subprocess
    """Serve until SIGTERM or Ctrl-C; the first stdout line names the device (``DEVICE_LINE_PREFIX``)."""
    p = argparse.ArgumentParser(prog="python -m drivers.mockbus",
                                description="Serve an emulated Dynamixel bus on a pseudo-terminal.")
    p.add_argument("--ids", default="1-20", help="servo IDs, e.g. 1-20 or 1,3,5 (default 1-20)")
    p.add_argument("--model", default=None, help="servo model (default XM430-W350, or MX-28 with --protocol 1.0)")
    p.add_argument("--protocol", type=float, default=2.0, choices=[1.0, 2.0], help="Dynamixel protocol (default 2.0)")
    p.add_argument("--baud", type=int, default=1_000_000, help="bus baud rate [bit/s]")
    p.add_argument("--wire-timing", action="store_true", help="replies take their wire time")
    p.add_argument("--delay", type=int, default=0, help="Return Delay Time (2 us units)")
    p.add_argument("--link", help="symlink to the device")
    p.add_argument("--rt-priority", type=int, metavar="P",
                   help="serve under SCHED_FIFO priority P (needs root or CAP_SYS_NICE): replies on time on a busy host")
    p.add_argument("-v", "--verbose", action="store_true", help="info logs (served and late replies at exit)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if args.protocol == 1.0:
        from drivers.mockbus.emulator1 import MockBus1

        bus: MockBus = MockBus1.from_ids(parse_ids(args.ids), args.model or "MX-28", baud_rate=args.baud,
                                         clock=MonotonicClock(), wire_timing=args.wire_timing,
                                         return_delay_units=args.delay)
    else:
        bus = MockBus.from_ids(parse_ids(args.ids), args.model or "XM430-W350", baud_rate=args.baud,
                               clock=MonotonicClock(), wire_timing=args.wire_timing, return_delay_units=args.delay)
    server = PtyServer(bus, link=args.link)
    device = server.open()
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    with realtime_scheduling(args.rt_priority) as note:
        _log.info("emulator: %s", note)
        print(f"{DEVICE_LINE_PREFIX}{device}", flush=True)
        try:
            server.serve()
        except KeyboardInterrupt:
            pass
        finally:
            server.close()
    st = server.stats
    _log.info("served %d replies; %d late by > 0.5 ms (max %.2f ms); %d bytes at a wrong baud rate ignored",
              st.replies, st.late_replies, st.max_lateness_s * 1e3, st.dropped_wrong_baud)
    return 0


if __name__ == "__main__":
    sys.exit(main())
