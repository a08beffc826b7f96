"""The pipelined bus cycle: goal writes and feedback reads overlapped with the host's work."""

from __future__ import annotations

import numpy as np

from drivers.group import ServoGroup

__all__ = ["pipelined_cycles"]


def pipelined_cycles(group: ServoGroup, q: np.ndarray, cycles: int) -> int:
    """``cycles`` goal-write + feedback-read cycles, pipelined; returns the cycles whose
    feedback was complete.

    Order on the wire is unchanged (request k, reply k, request k+1, ...): only the host's work
    moves. Goals for cycle k+1 are encoded while reply k is on the wire, request k+1 leaves
    as soon as reply k is in, and reply k is decoded while request k+1 is on the wire. A failed
    fast read falls back to :meth:`ServoGroup.read_feedback` (which also re-sends the goals).
    """
    complete = 0
    if not group.pipelinable:
        for _ in range(cycles):
            group.write_goals(q, defer=True)
            complete += int(group.read_feedback().valid.all())
        return complete
    group.write_goals(q, defer=True)
    group.request_fast_feedback()
    for k in range(cycles):
        last = k + 1 == cycles
        if not last:
            group.write_goals(q, defer=True)  # queued: leaves with the next request
        raw = group.collect_fast_feedback_raw()
        sent_next = raw is not None and not last
        if sent_next:
            group.request_fast_feedback()
        fb = group.decode_fast_feedback(raw)
        if fb is None:  # fall back for this cycle, then restart the pipeline
            if sent_next:  # half duplex: take the reply already coming before asking again
                group.collect_fast_feedback_raw()
            fb = group.read_feedback()
            if not last and group.pipelinable:
                group.write_goals(q, defer=True)
                group.request_fast_feedback()
            elif not last:
                return complete + int(fb.valid.all()) + pipelined_cycles(group, q, cycles - k - 1)
        complete += int(fb.valid.all())
    return complete
