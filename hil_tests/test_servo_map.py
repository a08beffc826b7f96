"""Servo map reading, tick conversion and control tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

import drivers
from drivers.control_table import SUPPORTED_MODELS, control_table, model_for_number
from drivers.errors import ControlTableError, ServoMapError
from drivers.servo_map import ServoMap, ServoSpec, parse_servo_map
from drivers.session import mock_bus_for


def _doc(**servo: object) -> dict:
    row = {"id": 1, "joint": "a", "model": "XM430-W350"}
    row.update(servo)
    return {"format": "robot-rise/servos@1", "robot": "t", "bus": {"baud_rate": 1000000}, "servo": [row]}


def test_that_the_op3_map_has_20_xm430_servos_with_unique_ids(servo_map: ServoMap) -> None:
    assert servo_map.ids == tuple(range(1, 21))
    assert servo_map.bus.baud_rate == 2_000_000 and servo_map.bus.return_delay_units == 1


def test_that_ticks_follow_the_documented_formula() -> None:
    s = ServoSpec(1, "a", "XM430-W350", direction=-1, zero_offset=0.1, min=-2.0, max=2.0)
    assert s.to_ticks(0.0) == round(2048 - 0.1 * 4096 / (2 * math.pi))
    assert s.to_radians(s.to_ticks(0.5)) == pytest.approx(0.5, abs=2 * math.pi / 4096)


def test_that_vector_conversion_round_trips_within_one_tick(servo_map: ServoMap) -> None:
    q = np.random.default_rng(0).uniform(servo_map.lower_rad, servo_map.upper_rad)
    assert np.allclose(servo_map.to_radians(servo_map.to_ticks(q)), q, atol=math.pi / 4096)


def test_that_a_wrong_format_is_named() -> None:
    with pytest.raises(ServoMapError, match="robot-rise/servos@1"):
        parse_servo_map({"format": "x"})


def test_that_unknown_models_list_the_supported_ones() -> None:
    with pytest.raises(ServoMapError) as e:
        parse_servo_map(_doc(model="AX-12"))
    assert "XM430-W350" in e.value.hint


def test_that_duplicate_ids_are_refused() -> None:
    doc = _doc()
    doc["servo"].append({"id": 1, "joint": "b", "model": "XM430-W350"})
    with pytest.raises(ServoMapError, match="duplicate"):
        parse_servo_map(doc)


def test_that_index_of_maps_trajectory_columns_and_names_missing_joints(servo_map: ServoMap) -> None:
    names = list(reversed(servo_map.joint_names))
    idx = servo_map.index_of(names)
    assert [names[i] for i in idx] == list(servo_map.joint_names)
    with pytest.raises(ServoMapError, match="head_tilt"):
        servo_map.index_of(names[1:])


def test_that_each_model_has_its_control_table_and_model_number() -> None:
    assert set(SUPPORTED_MODELS) == {"XM430-W350", "XL430-W250", "XM540-W270", "MX-28(2.0)", "XH430-W350", "XH540-W270", "MX-64(2.0)", "MX-106(2.0)"}
    assert {t.model_number for t in map(control_table, SUPPORTED_MODELS)} == {1020, 1060, 1120, 30, 1000, 1100, 311, 321}
    assert control_table("MX-106") is control_table("MX-106(2.0)")  # the servo catalog's name for it
    for model in SUPPORTED_MODELS:
        t = control_table(model)
        assert t["goal_position"].address == 116 and t["present_position"].address == 132
        assert model_for_number(t.model_number) is t
    assert control_table("XL430-W250").has("present_load") and not control_table("XL430-W250").has("goal_current")


def test_that_unknown_register_names_list_valid_ones() -> None:
    with pytest.raises(ControlTableError) as e:
        control_table("XM430-W350")["goal_postion"]
    assert "goal_position" in e.value.hint


def test_that_every_name_in_all_resolves() -> None:
    import importlib

    for mod in ("drivers", "drivers.mockbus", "drivers.protocol", "drivers.safety", "drivers.executor",
                "drivers.bus", "drivers.group", "drivers.startup", "drivers.servo_map", "drivers.control_table"):
        m = importlib.import_module(mod)
        for name in m.__all__:
            assert hasattr(m, name), f"{mod}.{name}"
    assert drivers.__all__


def test_that_the_servo_maps_supply_reaches_the_mock_bus_and_scales_the_executors_voltage_window() -> None:
    doc = _doc()
    doc["bus"]["supply_voltage_v"] = 14.8  # a 4S LiPo
    smap = parse_servo_map(doc)
    assert smap.bus.supply_voltage_v == 14.8
    assert mock_bus_for(smap).faults.voltage_of(1) == 14.8
    window = drivers.voltage_limits_for_supply(14.8)
    assert window["min_voltage_v"] <= 14.8 * 0.925 and 16.8 <= window["max_voltage_v"]  # the proof's low supply; a charged 4S
    limits = drivers.SafetyLimits(smap.lower_rad, smap.upper_rad, **window)
    assert limits.min_voltage_v > 12.0  # what a 3S robot runs on is a flat 4S battery
    default = drivers.SafetyLimits(smap.lower_rad, smap.upper_rad)
    assert drivers.voltage_limits_for_supply(12.0) == {"min_voltage_v": default.min_voltage_v, "max_voltage_v": default.max_voltage_v}


@pytest.mark.parametrize("value", [48.0, "twelve"])
def test_that_a_supply_no_servo_runs_on_is_a_servo_map_error(value: object) -> None:
    doc = _doc()
    doc["bus"]["supply_voltage_v"] = value
    with pytest.raises(ServoMapError, match="supply_voltage_v|not a number"):
        parse_servo_map(doc)
