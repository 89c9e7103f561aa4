"""Domain randomisation: physics drawn per trial or session within documented ranges, one family held out."""

import csv
import subprocess

import numpy as np
import pytest

from neurotac_cli.errors import NeurotacError
from neurotac_cli.sim.config import preset_config
from neurotac_cli.sim.grasp import plan_grasps, true_force
from neurotac_cli.sim.physics import FAMILIES, SEEN_SHARE, Variation, _base, parse_variation
from neurotac_cli.sim.run import simulate


def position_in_range(spec, base, value):
    """Where `value` lies in its range, 0..1 in the drawing scale."""
    value = value / base if spec.factor else value
    if spec.log:
        return (np.log(value) - np.log(spec.low)) / (np.log(spec.high) - np.log(spec.low))
    return (value - spec.low) / (spec.high - spec.low)


@pytest.mark.parametrize("preset", ["ch3", "ch5"])
def test_every_drawn_parameter_lies_in_its_range_and_held_out_sides_do_not_meet(preset):
    config = preset_config(preset)
    for side in ("seen", "unseen"):
        variation = Variation(tuple(FAMILIES), "membrane", side)
        for seed in range(40):
            varied, values = variation.draw(config, np.random.default_rng(seed))
            assert set(values) == {name for specs in FAMILIES.values() for name in specs}
            for family, specs in FAMILIES.items():
                for name, spec in specs.items():
                    assert getattr(varied, name) == values[name]
                    u = position_in_range(spec, _base(config, name), values[name])
                    slack = 0.02 if spec.integer else 1e-9  # integers are rounded
                    assert -slack <= u <= 1 + slack, (name, values[name])
                    if family == "membrane":
                        assert (u <= SEEN_SHARE + 1e-9) if side == "seen" else (u >= SEEN_SHARE - 1e-9), (name, u)


def test_the_variation_is_parsed_from_the_options():
    assert parse_variation(None) is None
    assert parse_variation("all").families == tuple(FAMILIES)
    held = parse_variation("pixels", held_out="membrane")
    assert held.families == ("pixels", "membrane") and (held.held_out, held.side) == ("membrane", "seen")
    assert parse_variation(None, unseen="optics") == Variation(("optics",), "optics", "unseen")
    for args in (("pixels,shadows",), ("all", "membrane", "membrane")):
        with pytest.raises(NeurotacError):
            parse_variation(*args)


def test_thresholds_from_the_unseen_side_fire_fewer_events_than_from_the_seen_side():
    config = preset_config("ch4", hold_us=60_000, max_duration_us=0)
    counts = {}
    for side in ("seen", "unseen"):
        trials = simulate(config, seed=3, trials=2, variation=Variation(("pixels",), "pixels", side)).trials
        counts[side] = sum(trial.t.size for trial in trials)
        for trial in trials:
            drawn = trial.grasp.extra["physics"]["on_threshold"]
            assert (drawn < 0.15 + SEEN_SHARE * 0.35) == (side == "seen")
    assert counts["unseen"] < 0.8 * counts["seen"]


def test_vary_keeps_each_trial_id_and_labels_and_writes_the_drawn_physics(tmp_path):
    args = ["--preset", "ch3", "--trials", "2", "--set", "hold_us=40ms", "--seed", "4"]
    for name, extra in (("plain", []), ("varied", ["--vary", "noise,sensor"])):
        done = subprocess.run(["neurotac", "simulate", *args, *extra, "--out", str(tmp_path / name)], capture_output=True)
        assert done.returncode == 0, done.stderr.decode()
    rows = {name: list(csv.DictReader(open(tmp_path / name / "manifest.csv"))) for name in ("plain", "varied")}
    assert [(r["trial"], r["material"], r["true_peak_force_n"]) for r in rows["plain"]] == \
        [(r["trial"], r["material"], r["true_peak_force_n"]) for r in rows["varied"]]
    rates = [float(r["true_background_rate_hz"]) for r in rows["varied"]]
    assert all(0.02 <= rate <= 1.0 for rate in rates) and rates[0] != rates[1]
    assert "true_on_threshold" not in rows["varied"][0]  # only the families asked for are drawn


def test_a_force_controlled_gripper_holds_the_peak_whatever_the_material():
    ratios = {}
    for gripper in ("position", "force"):
        config = preset_config("ch3", groups=("foam:hex:1",), gripper=gripper)
        (grasp,) = plan_grasps(config, np.random.default_rng(0))
        held = true_force(config, grasp, np.array([grasp.loaded_us, grasp.release_us - 1.0]))
        ratios[gripper] = held[1] / held[0]
    assert ratios["position"] < 0.85  # the squeezed foam relaxes by its 22% over a 700 ms hold
    assert ratios["force"] == pytest.approx(1.0, abs=0.06)  # the grip holds its force (the hold's ripple aside)


def test_a_session_draws_the_objects_family_per_grasp_and_the_sensor_once():
    from neurotac_cli.sim.session import plan_session

    variation = parse_variation("all", unseen="objects")
    assert variation.without("objects").families == ("pixels", "membrane", "optics", "noise", "sensor")
    session = plan_session(preset_config("ch4"), np.random.default_rng(0), 6, variation=variation)
    tilts = [planned.physics["tilt_deg"] for planned in session.grasps]
    assert len(set(tilts)) == 6 and all(SEEN_SHARE * 0.6 <= tilt <= 0.6 for tilt in tilts)  # the unseen third
    assert all(planned.config.tilt_deg == planned.physics["tilt_deg"] for planned in session.grasps)
    assert all(planned.config.on_threshold == 0.30 for planned in session.grasps)  # plan_session leaves the sensor to the session


def test_rigs_share_one_draw_of_the_physics_among_their_grasps_and_label_them(tmp_path):
    args = ["neurotac", "simulate", "--preset", "ch3", "--trials", "8", "--set", "hold_us=40ms", "--seed", "4",
            "--vary", "pixels,membrane", "--rigs", "2"]
    for name in ("a", "b"):
        done = subprocess.run([*args, "--out", str(tmp_path / name)], capture_output=True)
        assert done.returncode == 0, done.stderr.decode()
    rows = list(csv.DictReader(open(tmp_path / "a" / "manifest.csv")))
    names = [r["rig"] for r in rows]
    assert names[:2] != names[2:] and names == names[:2] * 4  # dealt in turn: each rig gets a grasp of every group
    assert [name.split("-")[0] for name in names[:2]] == ["rig1", "rig2"]
    for rig in names[:2]:
        assert sorted(r["material"] for r in rows if r["rig"] == rig) == ["foam", "rubber", "silicone", "steel"]
        assert len({r["true_on_threshold"] for r in rows if r["rig"] == rig}) == 1  # one sensor per rig
    assert len({r["true_membrane_youngs_pa"] for r in rows}) == 2
    # the name is the sensor's: another run drawing other physics for its first rig names it otherwise
    other = subprocess.run([*args[:-2], "--unseen", "membrane", "--rigs", "2", "--out", str(tmp_path / "c")], capture_output=True)
    assert other.returncode == 0, other.stderr.decode()
    assert not {r["rig"] for r in csv.DictReader(open(tmp_path / "c" / "manifest.csv"))} & set(names)
    assert (tmp_path / "a" / "manifest.csv").read_bytes() == (tmp_path / "b" / "manifest.csv").read_bytes()
    for bad in (["--rigs", "2"], ["--vary", "all", "--rigs", "9"]):
        done = subprocess.run(["neurotac", "simulate", "--preset", "ch3", "--trials", "8", "--synced", *bad], capture_output=True)
        assert done.returncode == 2 and len(done.stderr.decode().strip().splitlines()) == 1, done.stderr


def test_rigs_get_every_group_however_the_groups_divide_and_too_many_rigs_are_refused():
    from neurotac_cli.errors import UsageError
    from neurotac_cli.sim.run import _dealt

    grasps = plan_grasps(preset_config("ch3"), np.random.default_rng(0), 24)  # 6 of each material, in blocks
    rigs = _dealt(grasps, 4)
    for rig in range(4):
        materials = sorted(g.material for g, r in zip(grasps, rigs) if r == rig)
        assert set(materials) == {"foam", "rubber", "silicone", "steel"} and len(materials) in (4, 8)
    with pytest.raises(UsageError, match="--rigs 7: the group .* has 6 grasp"):
        _dealt(grasps, 7)
