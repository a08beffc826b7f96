"""One self-contained HTML page about a trajectory: the video, plots, the judge's verdict, its numbers.

The trajectory is replayed from its start posture through the servo model and judged with
:func:`robot_rise.filter.prove` (the same check as ``robot-rise check``); this package only draws
what that recording and verdict say. The page embeds everything (images and video as ``data:``
URIs, inline CSS, no script), so it can be mailed or archived as one file.

Sections: verdict and problems; video (MP4, or an animated GIF where imageio-ffmpeg is missing) and
key frames; joint targets vs simulated positions; servo torque against the torque-speed envelope
per joint, the limit and the (1 - margin) line drawn; envelope use over time; ZMP and support
polygon while on feet; torso tilt and height against the judge's bounds; ground contacts over time;
the check's numbers and every entry of the trajectory's own report.

- :mod:`~robot_rise.report.figures`: matplotlib figures on the Agg canvas, their PNG bytes.
- :mod:`~robot_rise.report.plots`: the recording's plots (joints, envelope, envelope use, judge, contacts).
- :mod:`~robot_rise.report.support`: the balance plot, ZMP against the support polygon drawn from the soles.
- :mod:`~robot_rise.report.page`: the HTML (CSS, ``data:`` URIs, value tables, the verdict banner, the page).
- :mod:`~robot_rise.report.media`: the replay section (video or GIF, key frames), drawn through :mod:`robot_rise.render`.
- :mod:`~robot_rise.report.write`: ``write_report`` and its ``ReportResult``.
"""

from robot_rise.report.support import SOLE_CONTACT_TOLERANCE_M
from robot_rise.report.write import REPORT_FILE, ReportResult, write_report

__all__ = ["ReportResult", "write_report", "REPORT_FILE", "SOLE_CONTACT_TOLERANCE_M"]
