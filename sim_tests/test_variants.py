"""Model variants (robot_rise.sim.variants) and the ensemble proof (robot_rise.proof.ensemble)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from robot_rise.cli import main
from robot_rise.proof import EnsembleResult, Proof, VariantVerdict, with_ensemble
from robot_rise.model import compose, model_index
from robot_rise.posture import stand_posture
from robot_rise.sim.player import Player
from robot_rise.sim.variants import ENSEMBLE, TICK_RAD, VARIANT_RANGES, ModelVariant, apply_to_model, random_variants, variant_start, variant_trajectory
from robot_rise.trajectory import Trajectory, read_trajectory


def _model(robot, variant=None):
    m = compose(robot, "flat")
    idx = model_index(m, robot)
    if variant is not None:
        apply_to_model(m, idx, variant)
    return m, idx


def test_that_the_ensemble_has_at_least_twelve_named_variants_covering_the_issues_list():
    labels = [v.label for v in ENSEMBLE]
    assert len(labels) >= 12 and len(set(labels)) == len(labels)
    for word in ("masses", "centres of mass", "inertias", "total mass", "friction", "supply", "P gain", "armature",
                 "gear friction", "latency", "ticks", "+3 mm", "-3 mm", "start"):
        assert any(word in label for label in labels), word


def test_that_each_variant_changes_the_model_as_its_label_says(robot):
    m0, idx = _model(robot)
    robot_bodies = np.flatnonzero(m0.body_rootid == m0.body_rootid[idx.root_body])
    heavier = next(v for v in ENSEMBLE if "heavier" in v.label)
    m, _ = _model(robot, heavier)
    assert m.body_mass[robot_bodies].sum() == pytest.approx(m0.body_mass[robot_bodies].sum() / 0.9)
    per_link = next(v for v in ENSEMBLE if "masses" in v.label)
    m, _ = _model(robot, per_link)
    ratio = m.body_mass[robot_bodies] / m0.body_mass[robot_bodies]
    assert ratio.min() >= 0.9 - 1e-12 and ratio.max() <= 1.1 + 1e-12 and ratio.std() > 0.01  # per link, not one scale
    m, _ = _model(robot, ModelVariant("f", friction=0.5))
    assert np.all(m.geom_friction[:, 0] == 0.5)
    m, _ = _model(robot, ModelVariant("kp", kp_scale=0.8))
    np.testing.assert_allclose(m.actuator_gainprm[idx.actuators, 0], 0.8 * m0.actuator_gainprm[idx.actuators, 0])
    np.testing.assert_allclose(m.actuator_biasprm[idx.actuators, 1], 0.8 * m0.actuator_biasprm[idx.actuators, 1])
    m, _ = _model(robot, ModelVariant("grow", geom_grow_m=0.003))
    spheres = [g for g in idx.robot_geoms if m0.geom_type[g] != 6]  # primitives (6 = box)
    assert np.allclose(m.geom_size[spheres, 0] - m0.geom_size[spheres, 0], 0.003)
    m, _ = _model(robot, ModelVariant("com", seed=3, com_spread_m=0.005))
    moved = np.abs(m.body_ipos[robot_bodies] - m0.body_ipos[robot_bodies])
    assert moved.max() <= 0.005 + 1e-12 and moved.max() > 0.002
    # the nominal model is untouched by a variant that changes only inputs
    m, _ = _model(robot, ModelVariant("lat", latency_s=0.01))
    assert np.array_equal(m.body_mass, m0.body_mass) and np.array_equal(m.geom_size, m0.geom_size)


def test_that_latency_ticks_and_start_change_what_reaches_the_model(robot):
    start = stand_posture(robot)
    q0 = start.joint_vector(robot.joint_names)
    tr = Trajectory(robot.name, robot.joint_names, np.array([0.0, 1.0]), np.stack([q0, q0 + 0.1234567]), start, {})
    late = variant_trajectory(tr, ModelVariant("l", latency_s=0.02))
    assert late.t[0] == 0.0 and late.t[-1] == pytest.approx(1.02) and np.array_equal(late.q[-1], tr.q[-1])
    ticks = variant_trajectory(tr, ModelVariant("t", quantize_ticks=True))
    assert np.allclose(np.round(ticks.q / TICK_RAD), ticks.q / TICK_RAD) and np.abs(ticks.q - tr.q).max() <= TICK_RAD / 2 + 1e-12
    moved = variant_start(start, robot, ModelVariant("s", seed=5, start_spread_rad=math.radians(0.5)))
    d = moved.joint_vector(robot.joint_names) - q0
    assert np.abs(d).max() <= math.radians(0.5) + 1e-12 and np.abs(d).max() > math.radians(0.1)
    again = variant_start(start, robot, ModelVariant("s", seed=5, start_spread_rad=math.radians(0.5)))
    assert again.joints == moved.joints  # seeded


def test_that_random_variants_are_seeded_and_inside_the_ranges():
    a, b, c = random_variants(20, 1), random_variants(20, 1), random_variants(20, 2)
    assert a == b and a != c
    r = VARIANT_RANGES
    for v in a:
        assert r.friction[0] <= v.friction <= r.friction[1]
        assert r.supply_scale[0] <= v.supply_scale <= r.supply_scale[1]
        assert 1 - r.kp_spread <= v.kp_scale <= 1 + r.kp_spread
        assert abs(v.geom_grow_m) <= r.geom_grow_m and v.quantize_ticks
        assert v.latency_s in (0.0, 0.01, 0.02)


def test_that_a_variant_that_falls_unproves_the_proof_and_the_proof_keeps_every_verdict(tmp_path):
    from robot_rise.paths import configs_dir

    tr = read_trajectory(configs_dir() / "motions" / "op3" / "prone_elbow_knees_quick.json")
    stands = VariantVerdict("a", True, "", 3.0, 0.99, 0.95, -0.02)
    falls = VariantVerdict("b", False, "not standing: torso tilted 90 deg", 90.0, 0.3, 1.0, None)
    base = Proof.from_dict({**tr.report, "proven": True, "problems": []}) if "proven" in tr.report else None
    if base is None:
        pytest.skip("library file carries no proof yet")
    proof = with_ensemble(base, EnsembleResult((stands, falls)))
    assert not proof.proven and any("variant 'b'" in p for p in proof.problems)
    assert proof.ensemble_standing == 1 and proof.worst_tilt_deg == 90.0 and proof.worst_zmp_margin_m == -0.02
    back = Proof.from_dict(proof.to_dict())
    assert back == proof
    assert with_ensemble(base, EnsembleResult((stands,))).proven


def test_that_the_player_composes_the_variants_supply(robot):
    low = Player(robot, "flat", variant=ModelVariant("v", supply_scale=11.1 / 12.0))
    nominal = Player(robot, "flat")
    acts = nominal.index.actuators
    assert np.all(low.model.actuator_forcerange[acts, 1] < nominal.model.actuator_forcerange[acts, 1])


def test_that_check_replays_the_ensemble_and_random_variants_and_reports_the_share(tmp_path, capsys):
    from robot_rise.paths import configs_dir

    path = configs_dir() / "motions" / "op3" / "prone_elbow_knees_quick.json"
    code = main(["check", str(path), "--variants", "3", "--seed", "1"])
    out = capsys.readouterr().out
    assert f"of {len(ENSEMBLE)} model variants stand" in out
    assert "random variants (seed 1):" in out and "of 3 stand" in out
    assert code in (0, 1)


def test_that_dataclass_fields_of_a_variant_are_plain_values():
    for v in ENSEMBLE + random_variants(3, 0):
        for f in dataclasses.fields(v):
            assert isinstance(getattr(v, f.name), (str, int, float, bool, type(None))), f.name


def test_that_combined_variants_are_fixed_draws_that_a_proof_replays_and_check_replays_again(tmp_path, capsys):
    import json

    from robot_rise.paths import configs_dir
    from robot_rise.sim.variants import COMBINED_SEED, combined_variants
    from robot_rise.trajectory import write_trajectory

    two = combined_variants(2)
    assert [v.label for v in two] == ["combined variant 0", "combined variant 1"]
    assert [dataclasses.replace(v, label="") for v in two] == [dataclasses.replace(v, label="") for v in random_variants(2, COMBINED_SEED)]
    tr = read_trajectory(configs_dir() / "motions" / "op3" / "supine_situp_rock_robust.json")
    path = tmp_path / "t.json"
    write_trajectory(path, dataclasses.replace(tr, report={**tr.report, "combined_variants": 2}))
    main(["check", str(path), "--json"])
    report = json.loads(capsys.readouterr().out)
    labels = [v["label"] for v in report["ensemble"]["variants"]]
    assert len(labels) == len(ENSEMBLE) + 2 and labels[-2:] == ["combined variant 0", "combined variant 1"]
    # and a file proven without them replays the ensemble alone
    main(["check", str(configs_dir() / "motions" / "op3" / "supine_situp_rock_robust.json"), "--json"])
    assert json.loads(capsys.readouterr().out)["ensemble"]["size"] == len(ENSEMBLE)
