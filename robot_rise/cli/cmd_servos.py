"""robot-rise servos: scan, status, torque on|off, reboot ID, read-posture (operator tools)."""

from __future__ import annotations

import argparse
import math
import sys


from robot_rise.cli._common import Formatter, print_json

EPILOG = """examples:
  robot-rise servos scan --port /dev/ttyUSB0
  robot-rise servos status --port /dev/ttyUSB0 --baud 2000000
  robot-rise servos torque off --port /dev/ttyUSB0
  robot-rise servos reboot 7 --port /dev/ttyUSB0
  robot-rise servos read-posture --port /dev/ttyUSB0 --out postures/crouch.json
  robot-rise servos scan --mock          # against the emulated bus
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("servos", help="scan, inspect and pose the servos on a bus",
                       formatter_class=Formatter, epilog=EPILOG)
    ssub = p.add_subparsers(dest="servos_cmd", metavar="ACTION", required=True)

    def common(q: argparse.ArgumentParser) -> None:
        g = q.add_mutually_exclusive_group(required=True)
        g.add_argument("--port", help="serial device or pyserial URL (e.g. /dev/ttyUSB0, dxlsim://NAME)")
        g.add_argument("--mock", action="store_true", help="use an emulated bus built from the servo map")
        q.add_argument("--baud", type=int, help="baud rate [bit/s] (default: from servos.toml)")
        q.add_argument("--robot", metavar="DIR", help="robot directory (default: the embedded OP3)")
        q.add_argument("--json", action="store_true", help="print one JSON object instead of the text")

    q = ssub.add_parser("scan", help="ping every ID of the servo map; show model and firmware",
                        formatter_class=Formatter, epilog="example:\n  robot-rise servos scan --port /dev/ttyUSB0")
    common(q)
    q.add_argument("--all", action="store_true", help="ping IDs 0..252, not only the mapped ones")
    q.set_defaults(func=run_scan)
    q = ssub.add_parser("status", help="positions, temperatures, voltages and errors of every servo",
                        formatter_class=Formatter, epilog="example:\n  robot-rise servos status --port /dev/ttyUSB0")
    common(q)
    q.set_defaults(func=run_status)
    q = ssub.add_parser("torque", help="torque on (goal = present first) or off",
                        formatter_class=Formatter, epilog="example:\n  robot-rise servos torque off --port /dev/ttyUSB0")
    q.add_argument("state", choices=["on", "off"])
    common(q)
    q.set_defaults(func=run_torque)
    q = ssub.add_parser("reboot", help="reboot one servo (clears a shutdown)",
                        formatter_class=Formatter, epilog="example:\n  robot-rise servos reboot 7 --port /dev/ttyUSB0")
    q.add_argument("id", type=int)
    common(q)
    q.set_defaults(func=run_reboot)
    q = ssub.add_parser("read-posture", help="torque off, then save the present joint angles as a posture file",
                        formatter_class=Formatter,
                        epilog="example:\n  robot-rise servos read-posture --port /dev/ttyUSB0 --out crouch.json")
    common(q)
    q.add_argument("--out", required=True, help="posture JSON to write")
    q.add_argument("--keep-torque", action="store_true", help="do not turn torque off first")
    q.add_argument("--root-from", metavar="POSTURE",
                   help="take the root pose (position, orientation) from this posture file; the servos cannot "
                        "know it (default: the robot's 'stand' keyframe)")
    q.set_defaults(func=run_read_posture)


def _connect(args: argparse.Namespace):
    from drivers.servo_map import load_servo_map
    from drivers.session import connect, mock_url_for
    from robot_rise.model import load_robot
    from robot_rise.posture import stand_posture

    robot = load_robot(args.robot)
    smap = load_servo_map(robot.directory / "servos.toml")
    port = args.port
    if args.mock:
        stand = dict(stand_posture(robot).joints)
        port = mock_url_for(smap, initial_rad=stand, wire_timing=False)
    return robot, smap, connect(smap, port, baud_rate=args.baud)


def run_scan(args: argparse.Namespace) -> int:
    from drivers.control_table import model_for_number

    _, smap, conn = _connect(args)
    with conn:
        ids = range(0, 253) if args.all else smap.ids
        found = conn.bus.scan(ids)
        lines = [f"port {conn.url} at {conn.bus.baud_rate} bit/s, Protocol {smap.protocol:.1f}: {conn.latency.note}"]
        rows = []
        for sid in sorted(set(ids) | set(found)):
            if sid not in found and sid not in smap.ids:
                continue
            expected = smap.by_id(sid) if sid in smap.ids else None
            r = found.get(sid)
            if r is None:
                lines.append(f"  id {sid:3d}  MISSING  (expected {expected.model} for {expected.joint})")  # type: ignore[union-attr]
                rows.append({"id": sid, "answered": False, "joint": expected.joint, "expected_model": expected.model})  # type: ignore[union-attr]
                continue
            t = model_for_number(r.model_number, smap.protocol)
            name = t.model if t else f"model {r.model_number}"
            wrong = expected is not None and expected.table.model != name
            flag = f"  WRONG MODEL (map: {expected.model})" if wrong else ""  # type: ignore[union-attr]
            joint = expected.joint if expected else "(not in map)"
            # 2.0: the status alert bit; 1.0: the status packet's alarm bits themselves
            alert = bool(r.error & (0x80 if smap.protocol == 2.0 else 0x7F))
            lines.append(f"  id {sid:3d}  {name:12s} fw {r.firmware_version:3d}  {joint}{flag}{'  ALERT' if alert else ''}")
            rows.append({"id": sid, "answered": True, "joint": expected.joint if expected else None, "model": name,
                         "model_number": r.model_number, "firmware_version": r.firmware_version,
                         "expected_model": expected.model if expected else None, "wrong_model": wrong, "alert": alert})
        missing = [i for i in smap.ids if i not in found]
        lines.append(f"{len(found)} servo(s) answered; {len(missing)} of the map missing")
        if args.json:
            print_json({"port": conn.url, "baud_rate": conn.bus.baud_rate, "protocol": smap.protocol,
                        "latency": conn.latency.note, "servos": rows, "answered": len(found), "missing": missing})
        else:
            print("\n".join(lines))
        if not found:
            _nothing_answered(conn.bus.baud_rate, smap.bus.baud_rate)
        return 0 if not missing else 1


def _nothing_answered(baud: int, map_baud: int) -> None:
    other = "" if baud == map_baud else f" (servos.toml says {map_baud})"
    print(f"hint: no servo answered at {baud} bit/s{other}: check power, cabling and --baud "
          "(robot-rise servos scan --all pings every ID)", file=sys.stderr)


def run_status(args: argparse.Namespace) -> int:
    from drivers.control_table import HardwareErrorBits
    from drivers.startup import preflight

    _, smap, conn = _connect(args)
    with conn:
        preflight(conn.group, configure=False, require_all=False)
        conn.group.use_indirect = False  # do not touch the servos' indirect map for a status read
        fb = conn.group.read_feedback()
        lines = [f"{'id':>3} {'joint':14s} {'angle[rad]':>10} {'temp[C]':>7} {'volt[V]':>7}  errors"]
        rows: list[dict] = []
        for k, s in enumerate(smap.servos):
            if not fb.valid[k]:
                lines.append(f"{s.id:3d} {s.joint:14s} {'--':>10}  no answer")
                rows.append({"id": s.id, "joint": s.joint, "answered": False})
                continue
            err = HardwareErrorBits.describe(int(fb.hardware_error[k]))
            lines.append(f"{s.id:3d} {s.joint:14s} {fb.position_rad[k]:10.3f} {fb.temperature_c[k]:7.0f} "
                         f"{fb.voltage_v[k]:7.1f}  {err}")
            rows.append({"id": s.id, "joint": s.joint, "answered": True, "angle_rad": float(fb.position_rad[k]),
                         "temperature_c": float(fb.temperature_c[k]), "voltage_v": float(fb.voltage_v[k]),
                         "hardware_error": int(fb.hardware_error[k]), "errors": err})
        if args.json:
            print_json({"servos": rows})
        else:
            print("\n".join(lines))
        if not fb.valid.any():
            _nothing_answered(conn.bus.baud_rate, smap.bus.baud_rate)
        return 0 if fb.valid.all() and not fb.hardware_error.any() else 1


def run_torque(args: argparse.Namespace) -> int:
    from drivers.startup import engage, preflight

    _, smap, conn = _connect(args)
    with conn:
        if args.state == "off":
            conn.group.torque(False)
            _say(args, f"torque off on {len(smap)} servo(s)", torque="off", servos=len(smap))
            return 0
        preflight(conn.group)
        engage(conn.group, watchdog_s=None)  # goal = present, then torque on; no watchdog (we exit)
        _say(args, f"torque on (holding present position) on {len(smap)} servo(s)", torque="on", servos=len(smap))
        return 0


def run_reboot(args: argparse.Namespace) -> int:
    from drivers.startup import recover

    _, smap, conn = _connect(args)
    with conn:
        smap.by_id(args.id)  # names valid IDs if unknown
        report = recover(conn.group, [args.id], attempts=1, torque_on=False)
        if args.json:
            print_json({"id": args.id, "ok": report.ok, "messages": list(report.messages)})
        for line in () if args.json else report.messages:
            print(line)
        return 0 if report.ok else 1


def run_read_posture(args: argparse.Namespace) -> int:
    from robot_rise.posture import Posture, read_posture, stand_posture, write_posture

    # Read the root source before the bus is touched: a bad file must not leave torque off for nothing.
    root_source = read_posture(args.root_from, None) if args.root_from else None
    robot, smap, conn = _connect(args)
    if root_source is not None and root_source.robot != robot.name:
        from robot_rise.errors import PostureError

        raise PostureError(f"{args.root_from}: posture of robot {root_source.robot!r}, the bus is {robot.name!r}")
    with conn:
        if not args.keep_torque:
            conn.group.torque(False)
        conn.group.use_indirect = False
        fb = conn.group.read_feedback()
        if not fb.valid.all():
            from drivers.errors import CommunicationError

            missing = [s.id for s, ok in zip(smap.servos, fb.valid) if not ok]
            raise CommunicationError(f"no present position from servo(s) {missing}; no posture written",
                                     hint="check power and cabling (robot-rise servos status --port PORT)")
    stand = stand_posture(robot)
    joints = dict(stand.joints)
    for s, q in zip(smap.servos, fb.position_rad):
        joints[s.joint] = float(q)
    if root_source is not None:
        root_pos, root_quat, root_note = root_source.root_pos, root_source.root_quat_wxyz, f"from {args.root_from}"
    else:
        root_pos, root_quat = stand.root_pos, stand.root_quat_wxyz
        root_note = "from the 'stand' keyframe"
    posture = Posture(robot.name, root_pos, root_quat, joints)
    write_posture(args.out, posture)
    worst = max(abs(joints[s.joint] - min(max(joints[s.joint], s.min), s.max)) for s in smap.servos)
    note = "" if worst < 1e-9 else f" (some joints outside the servo map limits by up to {math.degrees(worst):.1f} deg)"
    _say(args, f"wrote {args.out}: {len(smap)} joint angles read, root pose {root_note}{note}", file=str(args.out),
         joints=dict(joints), root=root_note, outside_limits_rad=worst)
    return 0


def _say(args: argparse.Namespace, text: str, **facts: object) -> None:
    """Print ``text``, or with --json the same facts as one JSON object."""
    if args.json:
        print_json(facts)
    else:
        print(text)
