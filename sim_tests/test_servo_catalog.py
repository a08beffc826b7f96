"""The servo catalog as data: configs/servos/catalog.toml plus a robot's own servo_models.toml."""

from __future__ import annotations

import logging
import math
import os
import shutil
from pathlib import Path

import pytest

from robot_rise.errors import ConfigError
from robot_rise.paths import configs_dir
from robot_rise.servo import (
    ROBOT_SERVO_MODELS_FILE,
    SERVO_CATALOG_FORMAT,
    SERVO_DATASHEETS,
    ServoDatasheet,
    product_catalog_path,
    read_servo_catalog,
    servo_catalog,
    servo_datasheet,
)

MODELS = ("XM430-W350", "XM540-W270", "XH430-W350", "XH540-W270", "XL430-W250", "MX-28", "MX-64", "MX-106")
PROTOCOL_1_MODELS = ("AX-12A", "AX-18A", "RX-28", "RX-64", "MX-28(1.0)", "MX-64(1.0)", "MX-106(1.0)")  # issue 43
FIGURES = (
    "control_table_family",
    "resolution_ticks_per_rev",
    "gear_ratio",
    "nominal_voltage_v",
    "performance",
    "position_p_gain",
    "position_d_gain",
    "armature_kg_m2",
    "friction_loss_nm",
    "viscous_damping_nm_s",
)


def rpm(x: float) -> float:
    return x * 2 * math.pi / 60.0


# What robot_rise/servo.py held in code before the catalog: (nominal V, stall N m, no-load rad/s,
# gear ratio, P, D, armature, friction, viscous). The product's behaviour rests on these.
BEFORE = {
    "XM430-W350": (12.0, 4.1, rpm(46.0), 353.5, 800, 0, 0.012, 0.03, 0.05),
    "XL430-W250": (12.0, 1.5, rpm(61.0), 258.5, 640, 0, 0.005, 0.02, 0.03),
    "XM540-W270": (12.0, 10.6, rpm(30.0), 272.5, 900, 0, 0.03, 0.05, 0.08),
    "MX-28(2.0)": (12.0, 2.5, rpm(55.0), 193.0, 850, 0, 0.006, 0.02, 0.03),
}


def model_toml(name: str = "TEST-1", *, aliases: str = "[]", stall_12v: str = "2.0", drop: str = "", fmt: str = SERVO_CATALOG_FORMAT) -> str:
    """A complete, valid one-model catalog (optionally without one field)."""
    fields = {
        "aliases": aliases,
        "control_table_family": '"x"',
        "resolution_ticks_per_rev": "4096",
        "gear_ratio": "200.0",
        "nominal_voltage_v": "12.0",
        "performance": "[ { voltage_v = 11.1, stall_torque_nm = 1.8, no_load_speed_rpm = 50 },"
        f" {{ voltage_v = 12.0, stall_torque_nm = {stall_12v}, no_load_speed_rpm = 54 }} ]",
        "position_p_gain": "700",
        "position_d_gain": "0",
        "armature_kg_m2": "0.01",
        "friction_loss_nm": "0.02",
        "viscous_damping_nm_s": "0.03",
    }
    body = "\n".join(f"{k} = {v}" for k, v in fields.items() if k != drop)
    sources = "\n".join(f'{k} = "estimate: test figure"' for k in FIGURES)
    return f'format = "{fmt}"\n\n[models."{name}"]\n{body}\n\n[models."{name}".sources]\n{sources}\n'


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_the_product_catalog_has_the_eight_models_with_a_source_for_every_figure() -> None:
    catalog = servo_catalog()
    assert set(MODELS) <= set(catalog)
    assert product_catalog_path() == configs_dir() / "servos" / "catalog.toml"
    for name in MODELS:
        s = catalog[name]
        assert s.model == name
        assert s.control_table_family == "x" and s.resolution_ticks_per_rev == 4096
        assert len(s.performance) >= 3, name  # the e-manual's voltage rows
        for figure in FIGURES:
            src = s.source(figure)
            assert src.startswith(("https://emanual.robotis.com/", "estimate: ")), (name, figure, src)
        for figure in ("performance", "gear_ratio"):
            assert s.source(figure).startswith("https://emanual.robotis.com/"), (name, figure)


def test_protocol_2_names_are_aliases_of_the_mx_models() -> None:
    for alias, name in (("MX-28(2.0)", "MX-28"), ("MX-64(2.0)", "MX-64"), ("MX-106(2.0)", "MX-106")):
        assert servo_datasheet(alias) is servo_datasheet(name)
        assert alias in SERVO_DATASHEETS and alias in servo_catalog().names()
    assert "MX-28(2.0)" not in list(SERVO_DATASHEETS)  # iteration lists each model once


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_the_models_robot_rise_had_keep_their_numbers_exactly(name: str) -> None:
    s = servo_datasheet(name)
    got = (s.nominal_voltage_v, s.stall_torque_nm, s.no_load_speed_rad_s, s.gear_ratio, s.position_p_gain, s.position_d_gain,
           s.armature_kg_m2, s.friction_loss_nm, s.viscous_damping_nm_s)
    assert got == BEFORE[name]  # exact, not approximate
    stall, noload = BEFORE[name][1:3]
    assert s.stall_torque_at(12.0) == stall and s.no_load_speed_at(12.0) == noload
    assert s.back_emf_damping_nm_s == stall / noload
    p = BEFORE[name][4]
    assert s.position_gain_nm_per_rad(12.0) == p / 128.0 * (4096 / (2 * math.pi)) * stall / 885
    assert s.saturation_error_rad() == 885 / (p / 128.0) * 2 * math.pi / 4096


def test_voltage_rows_are_interpolated_and_the_nominal_row_scales_outside_them() -> None:
    s = servo_datasheet("XM430-W350")  # rows 11.1 / 12.0 / 14.8 V: 3.8 / 4.1 / 4.8 N m, 43 / 46 / 57 rpm
    assert s.stall_torque_at(11.1) == 3.8 and s.no_load_speed_at(14.8) == pytest.approx(rpm(57))
    assert s.stall_torque_at(11.55) == pytest.approx(3.95)
    assert s.no_load_speed_at(13.4) == pytest.approx(rpm(51.5))
    assert s.stall_torque_at(6.0) == pytest.approx(4.1 / 2)  # below the rows: proportional to voltage
    assert s.stall_torque_at(16.0) == pytest.approx(4.1 * 16 / 12)
    one_row = ServoDatasheet("ONE", 12.0, 2.0, 5.0, 100.0, 800, 0, 0.0, 0.0, 0.0)  # no rows: as before the catalog
    assert one_row.stall_torque_at(11.1) == pytest.approx(2.0 * 11.1 / 12) and one_row.no_load_speed_at(6.0) == pytest.approx(2.5)


def test_a_robot_catalog_adds_a_model_that_is_then_used(tmp_path: Path) -> None:
    extra = write(tmp_path / ROBOT_SERVO_MODELS_FILE, model_toml("TEST-1", aliases='["TEST-1(2.0)"]'))
    s = servo_datasheet("TEST-1", extra_catalog=extra)
    assert (s.stall_torque_nm, s.no_load_speed_rad_s, s.position_p_gain) == (2.0, rpm(54), 700)
    assert servo_datasheet("TEST-1(2.0)", extra_catalog=extra) is s
    catalog = servo_catalog(extra)
    assert set(MODELS) | set(PROTOCOL_1_MODELS) | {"TEST-1"} == set(catalog) and catalog.files[-1] == extra.resolve()
    with pytest.raises(ConfigError, match="TEST-1"):
        servo_datasheet("TEST-1")  # not in the product's catalog


def test_a_robot_catalog_overrides_a_product_model_under_all_its_names_with_a_warning(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    extra = write(tmp_path / ROBOT_SERVO_MODELS_FILE, model_toml("MX-28(2.0)", stall_12v="2.7"))
    with caplog.at_level(logging.WARNING, logger="robot_rise.servo"):
        catalog = servo_catalog(extra)
    assert any("overrides" in r.getMessage() and "MX-28" in r.getMessage() for r in caplog.records)
    assert catalog["MX-28(2.0)"].stall_torque_nm == 2.7
    assert catalog["MX-28"] is catalog["MX-28(2.0)"]  # the product's name reaches the robot's figures too
    assert "MX-28" not in set(catalog) and "MX-28(2.0)" in set(catalog)
    assert servo_datasheet("MX-28").stall_torque_nm == 2.5  # the product catalog itself is unchanged


def test_a_missing_robot_catalog_is_ignored(tmp_path: Path) -> None:
    assert set(servo_catalog(tmp_path / ROBOT_SERVO_MODELS_FILE)) == set(servo_catalog())
    assert servo_datasheet("XM430-W350", extra_catalog=tmp_path / "nope.toml").stall_torque_nm == 4.1


def test_the_catalog_is_cached_per_file_and_reread_when_the_file_changes(tmp_path: Path) -> None:
    extra = write(tmp_path / ROBOT_SERVO_MODELS_FILE, model_toml(stall_12v="2.0"))
    first = servo_catalog(extra)
    assert servo_catalog(extra) is first and servo_catalog() is servo_catalog()
    write(extra, model_toml(stall_12v="2.25"))
    st = extra.stat()
    os.utime(extra, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert servo_catalog(extra)["TEST-1"].stall_torque_nm == 2.25


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (model_toml(fmt="robot-rise/servo-catalog@2"), "format is 'robot-rise/servo-catalog@2'"),
        (model_toml(drop="gear_ratio"), "model 'TEST-1': missing field(s) gear_ratio"),
        (model_toml(stall_12v="-2.0"), "model 'TEST-1': performance[1].stall_torque_nm must be a number > 0, got -2.0"),
        (model_toml().replace('position_p_gain = "estimate: test figure"', ""), "model 'TEST-1': sources.position_p_gain must be"),
        (model_toml().replace('gear_ratio = "estimate: test figure"', 'gear_ratio = "from memory"'), "sources.gear_ratio must be"),
        (model_toml().replace("nominal_voltage_v = 12.0", "nominal_voltage_v = 12.5"), "nominal_voltage_v 12.5 is not one of the"),
        (model_toml().replace("position_p_gain = 700", "position_p_gain = 70000"), "position_p_gain must be an integer 1 ~ 16383"),
        (model_toml().replace("gear_ratio = 200.0", "gear_ratio = 200.0\ngear = 3"), "unknown field(s) gear"),
        (model_toml().replace("voltage_v = 11.1", "voltage_v = 13.0"), "performance[1].voltage_v must be above the row before it"),
        (model_toml(aliases='["TEST-1"]'), "aliases repeat the model name"),
        (model_toml("TEST-0") + model_toml(aliases='["TEST-0"]').split("\n", 1)[1], "model 'TEST-1': name 'TEST-0' is already taken by model 'TEST-0'"),
        ("format = [", "not valid TOML"),
    ],
)
def test_a_malformed_catalog_is_one_line_naming_the_file_and_the_model(tmp_path: Path, text: str, expected: str) -> None:
    bad = write(tmp_path / ROBOT_SERVO_MODELS_FILE, text)
    with pytest.raises(ConfigError) as info:
        servo_datasheet("XM430-W350", extra_catalog=bad)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(bad.resolve())) and expected in message, message
    with pytest.raises(ConfigError, match="servo_models.toml"):
        read_servo_catalog(bad)


def test_an_unknown_model_lists_the_known_ones_and_says_where_to_add_it(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        servo_datasheet("XM999")
    message = str(info.value)
    assert "unknown servo model 'XM999'" in message and "\n" not in message
    assert all(name in message for name in MODELS) and "MX-28 (MX-28(2.0))" in message
    assert info.value.hint == f"add it to <robot dir>/servo_models.toml (format {SERVO_CATALOG_FORMAT})"
    extra = tmp_path / ROBOT_SERVO_MODELS_FILE
    with pytest.raises(ConfigError) as info:
        servo_datasheet("XM999", extra_catalog=extra)
    assert info.value.hint == f"add it to {extra} (format {SERVO_CATALOG_FORMAT})"


def test_the_catalog_follows_the_configs_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "servos").mkdir()
    shutil.copy(product_catalog_path(), tmp_path / "servos" / "catalog.toml")
    monkeypatch.setenv("ROBOT_RISE_CONFIGS", str(tmp_path))
    assert product_catalog_path() == tmp_path / "servos" / "catalog.toml"
    assert servo_catalog().files == ((tmp_path / "servos" / "catalog.toml").resolve(),)
    (tmp_path / "servos" / "catalog.toml").unlink()
    with pytest.raises(ConfigError, match="missing servo catalog"):
        servo_catalog()


def test_the_emulated_servos_run_on_the_catalogs_figures_and_the_control_tables_hold_none() -> None:
    """One place for a servo's physical figures: the emulator's load model reads the catalog the simulator reads."""
    from drivers.control_table import SUPPORTED_MODELS, SUPPORTED_MODELS_1, control_table
    from drivers.mockbus.emulated_servo import LOAD_MODEL_SUPPLY_V, motor_figures

    for protocol, models in ((2.0, SUPPORTED_MODELS), (1.0, SUPPORTED_MODELS_1)):
        for model in models:
            table = control_table(model, protocol)
            sheet = servo_datasheet(table.model)
            assert motor_figures(table.model) == (sheet.stall_torque_at(LOAD_MODEL_SUPPLY_V), sheet.no_load_speed_at(LOAD_MODEL_SUPPLY_V))
            assert not hasattr(table, "stall_torque_nm") and not hasattr(table, "no_load_speed_rad_s")
    assert motor_figures("XM430-W350") == (4.1, rpm(46.0))  # the figures the emulator had in code
