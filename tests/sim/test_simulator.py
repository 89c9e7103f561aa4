"""The grasp simulator: physics pins (thesis ch. 3-5), the rig's files, determinism."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from neurotac_cli.sim import contact
from neurotac_cli.sim.config import preset_config
from neurotac_cli.sim.run import simulate

# Short holds keep these tests fast; the physics of loading and release does not depend on the hold.
FAST = dict(hold_us=60_000, release_us=40_000, tail_us=10_000, duration_jitter=0.0)


def ch4(**overrides):
    return preset_config("ch4", **{**FAST, **overrides})


def loading_off_events(trial):
    """OFF events from first touch to 10 ms after the end of loading (the LED blink is before)."""
    g = trial.grasp
    rel = trial.t - g.led_off_camera_us
    window = (rel >= g.contact_us) & (rel < g.loaded_us + 10_000)
    return int(((trial.p == 0) & window).sum())


def one_grasp(objects, low, high, seed=1, **overrides):
    return simulate(ch4(groups=(objects,), force_min_n=low, force_max_n=high, **overrides), seed=seed).trials


# ---------------------------------------------------------------- contact mechanics


def test_hertz_contact_radius_grows_as_the_cube_root_of_force():
    forces = np.array([0.25, 0.5, 1.0, 2.0, 4.0, 8.0])
    e_star = contact.effective_modulus(1e6, 0.48, 200e9, 0.3)
    radius = contact.hertz_radius_m(forces, 5e-3, e_star)
    slope = np.polyfit(np.log(forces), np.log(radius), 1)[0]
    assert slope == pytest.approx(1 / 3, abs=1e-9)
    # and the closed form itself: a = (3 F R / 4 E*)^(1/3)
    assert radius[2] == pytest.approx((3 * 1.0 * 5e-3 / (4 * e_star)) ** (1 / 3))


def test_simulated_hertz_patch_area_follows_the_force_to_the_two_thirds():
    # a sphere on the membrane, saturation and creep off: the darkened patch is pi a^2 ~ F^(2/3)
    settings_ = dict(saturation_force_n=1e6, creep=0.0, background_rate_hz=0.0, hot_pixels=0, settle_px=0.0,
                     vibration_px=0.0, drift_px=0.0, force_vibration=0.0)
    areas = []
    for force in (0.5, 4.0):
        (trial,) = one_grasp("steel:sphere20:1", force, force, **settings_)
        g = trial.grasp
        rel = trial.t - g.led_off_camera_us
        during = (trial.p == 0) & (rel >= g.contact_us) & (rel < g.release_us)
        areas.append(np.unique(trial.y[during].astype(int) * 240 + trial.x[during]).size)
    ratio = areas[1] / areas[0]
    assert ratio == pytest.approx(8 ** (2 / 3), rel=0.25)


def test_off_events_during_loading_grow_with_the_force_increase():
    counts = [loading_off_events(one_grasp("steel:bolt12:1", f, f)[0]) for f in (0.4, 1.2, 3.0)]
    assert counts[0] < counts[1] < counts[2]


def test_a_bright_object_makes_its_press_of_on_events():
    """object_contrast below 0: the contact brightens (a white object, a membrane lit from behind)."""
    def loading(trial, polarity):
        g = trial.grasp
        rel = trial.t - g.led_off_camera_us
        return int(((trial.p == polarity) & (rel >= g.contact_us) & (rel < g.loaded_us + 10_000)).sum())
    dark, bright = (one_grasp("steel:bolt12:1", 2.0, 2.0, object_contrast=c)[0] for c in (0.85, -1.0))
    assert loading(dark, 0) > 3 * loading(dark, 1)
    assert loading(bright, 1) > 3 * loading(bright, 0)


def test_the_membrane_saturates_beyond_about_5_newtons():
    counts = {f: loading_off_events(one_grasp("steel:bolt12:1", f, f)[0]) for f in (1.0, 2.0, 5.0, 10.0)}
    assert counts[2.0] / counts[1.0] > 1.5
    assert counts[10.0] / counts[5.0] < 1.15


def test_off_events_during_loading_grow_with_object_size():
    counts = [loading_off_events(one_grasp(f"steel:bolt{size}:1", 2.5, 2.5)[0]) for size in (8, 12, 16)]
    assert counts[0] < counts[1] < counts[2]


def test_softer_materials_give_distinguishable_accumulation_curves_at_equal_force():
    groups = tuple(f"{m}:hex:3" for m in ("foam", "rubber", "silicone", "steel"))
    config = preset_config("ch3", groups=groups, force_min_n=2.9, force_max_n=3.1, hold_us=150_000,
                           release_us=60_000, tail_us=10_000)
    features, labels = [], []
    for trial in simulate(config, seed=4).trials:
        rel = trial.t - trial.grasp.led_off_camera_us
        edges = np.arange(1, 23) * 7_000  # accumulated OFF and ON at each frame of the grasping phase
        off = np.searchsorted(np.sort(rel[(trial.p == 0) & (rel > 2_000)]), edges)
        on = np.searchsorted(np.sort(rel[(trial.p == 1) & (rel > 2_000)]), edges)
        features.append(np.concatenate([off, on]) / 1000.0)
        labels.append(trial.grasp.material)
    features, labels = np.array(features), np.array(labels)
    # leave-one-out nearest class mean on the accumulation curves
    correct = 0
    for i in range(len(labels)):
        rest = np.arange(len(labels)) != i
        names = sorted(set(labels))
        centres = [features[rest & (labels == name)].mean(axis=0) for name in names]
        guess = names[int(np.argmin([np.linalg.norm(features[i] - c) for c in centres]))]
        correct += guess == labels[i]
    assert correct / len(labels) >= 0.75
    # the softest loads slowest: foam reaches half its grasping-phase OFF count later than steel
    def half_time(name):
        curves = features[labels == name][:, :22]
        return np.mean([np.searchsorted(c, c[-1] / 2) for c in curves])

    assert half_time("foam") > half_time("steel")


# ---------------------------------------------------------------- pixels and noise


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), jitter=st.sampled_from([0.0, 40.0, 90.0]))
def test_no_event_outside_the_sensor_even_for_objects_at_the_edge(seed, jitter):
    config = preset_config("ch4", **{**FAST, "hold_us": 20_000}, position_jitter_px=jitter, sensor_width=160, sensor_height=120,
                           groups=("steel:bolt16:2",))
    simulation = simulate(config, seed=seed)
    for trial in simulation.trials:
        assert trial.x.max() < 160 and trial.y.max() < 120
        assert np.all(np.diff(trial.t) >= 0)
    assert simulation.still[1].max() < 160 and simulation.still[2].max() < 120


@pytest.mark.parametrize("rate", [0.1, 0.5])
def test_background_rate_matches_the_setting(rate):
    config = ch4(groups=("steel:bolt8:1",), background_rate_hz=rate, hot_pixels=0, still_us=3_000_000)
    t, x, y, p = simulate(config, seed=2).still
    measured = t.size / (240 * 180 * 3.0)
    assert measured == pytest.approx(rate, rel=0.05)
    assert p.mean() == pytest.approx(0.8, abs=0.03)  # mostly ON


def test_hot_pixels_fire_at_their_rate():
    config = ch4(groups=("steel:bolt8:1",), background_rate_hz=0.0, hot_pixels=2, hot_rate_hz=50.0, still_us=2_000_000)
    t, x, y, p = simulate(config, seed=2).still
    pixels, counts = np.unique(y.astype(int) * 240 + x, return_counts=True)
    assert pixels.size == 2
    assert counts.sum() / (2 * 2.0) == pytest.approx(50.0, rel=0.15)


def test_led_off_is_the_spike_of_off_events():
    trial = simulate(ch4(groups=("steel:bolt12:1",)), seed=3).trials[0]
    t0 = trial.grasp.led_off_camera_us
    off = trial.t[trial.p == 0]
    bins = np.arange(trial.t[0], trial.t[-1] + 1000, 1000)
    counts, _ = np.histogram(off, bins)
    peak = bins[np.argmax(counts)]
    assert t0 - 1000 <= peak <= t0 + 1000
    assert counts.max() > 20 * np.median(counts[counts > 0])
    assert trial.t[0] > 1_000_000  # the camera clock does not start at 0


def test_led_box_confines_the_blink():
    trial = simulate(ch4(groups=("steel:bolt12:1",), led_box=(0, 0, 40, 180)), seed=3).trials[0]
    rel = trial.t - trial.grasp.led_off_camera_us
    spike = (trial.p == 0) & (rel >= 0) & (rel < 3_000)
    assert spike.sum() > 5_000
    assert np.mean(trial.x[spike] < 40) > 0.99  # a few background events fall anywhere


# ---------------------------------------------------------------- force sensors


def _force_lag_ms(trial):
    """Delay of the logged force behind the true force while loading, by least squares over shifts."""
    true = trial.true_force_n.astype(float)
    logged = trial.force_n.astype(float)
    n = int(np.argmax(true)) + 5
    errors = [np.mean((logged[s:n + s] - true[:n]) ** 2) for s in range(0, 40)]
    return 2.0 * int(np.argmin(errors))  # 2 ms samples


def test_force_log_lag_matches_the_chosen_sensor():
    nano = one_grasp("steel:bolt12:1", 3.0, 3.0, force_sensor="nano17")[0]
    flexi = one_grasp("steel:bolt12:1", 3.0, 3.0, force_sensor="flexiforce")[0]
    slow = one_grasp("steel:bolt12:1", 3.0, 3.0, force_sensor="flexiforce", force_lag_us=50_000)[0]
    assert _force_lag_ms(nano) <= 2
    assert 10 <= _force_lag_ms(flexi) <= 40  # default 25 ms
    assert 30 <= _force_lag_ms(slow) <= 70
    assert nano.force_t_us[0] == 0 and np.all(np.diff(nano.force_t_us) == 2_000)  # 500 Hz from LED-off


# ---------------------------------------------------------------- presets


def test_trials_beyond_the_groups_are_refused_and_a_few_of_a_huge_group_are_planned_at_once():
    """More trials than the groups hold were written as fewer without a word; one trial of a group of
    10^12 grasps queued all of them first (out of memory)."""
    from neurotac_cli.errors import UsageError
    from neurotac_cli.sim.grasp import plan_grasps

    with pytest.raises(UsageError, match="--trials 36 is more than the 35 grasps"):
        plan_grasps(preset_config("ch4"), np.random.default_rng(0), 36)
    assert len(plan_grasps(preset_config("ch4"), np.random.default_rng(0), 35)) == 35
    (grasp,) = plan_grasps(preset_config("ch4", groups=("steel:hex:1000000000000",)), np.random.default_rng(0), 1)
    assert grasp.material == "steel"
    with pytest.raises(UsageError, match="100000000 trials is more than the 20000 one run simulates"):  # ran until memory ran out
        plan_grasps(preset_config("ch4", groups=("steel:hex:100000000",)), np.random.default_rng(0))
    from neurotac_cli.commands.simulate import command
    from neurotac_cli.sim.grasp import MAX_TRIALS

    assert f"at most {MAX_TRIALS} trials" in next(p.help for p in command.params if p.name == "groups")


def test_presets_follow_the_thesis_designs():
    from neurotac_cli.sim.grasp import plan_grasps

    plans = {name: plan_grasps(preset_config(name), np.random.default_rng(0)) for name in ("ch3", "ch4", "ch5")}
    materials = [g.material for g in plans["ch3"]]
    assert {m: materials.count(m) for m in set(materials)} == {"foam": 11, "rubber": 9, "silicone": 14, "steel": 14}
    assert max(g.end_us for g in plans["ch3"]) <= 144 * 7_000 + 10_000
    assert len(plans["ch4"]) == 35 and max(g.end_us for g in plans["ch4"]) <= 410_000
    assert max(g.peak_force_n for g in plans["ch4"]) <= 3.12
    assert len(plans["ch5"]) == 60 and max(g.end_us for g in plans["ch5"]) <= 360_000
    sizes = [g.labels["size_mm"] for g in plans["ch5"]]
    assert sizes.count("12") == sizes.count("15") == sizes.count("18") == 20
    low = [g.peak_force_n for g in plans["ch5"] if g.labels["gripper_force"] == "low"]
    high = [g.peak_force_n for g in plans["ch5"] if g.labels["gripper_force"] == "high"]
    assert max(low) < min(high) and max(high) <= 25.0
    assert len({g.trial for g in plans["ch5"]}) == 60


@pytest.mark.parametrize("groups, said", [(("steel:bolt1000:1",), "object bolt1000 is wider than the camera's view"),
                                          (("steel:bolt8:1:trial=x",), "label name 'trial' is a column"),
                                          (("steel:bolt8:0",), "counts 0 grasps: nothing to simulate")])
def test_objects_that_cannot_be_simulated_are_usage_errors(groups, said):
    """An object wider than the picture ran for minutes into gigabytes; a label named like a column
    exited 1 where other option errors exit 2; no grasp at all was advised `--trials 0 or fewer`."""
    from neurotac_cli.errors import UsageError
    from neurotac_cli.sim.config import validate
    from neurotac_cli.sim.grasp import plan_grasps

    with pytest.raises(UsageError, match=said):
        config = preset_config("ch4", groups=groups)
        validate(config)
        plan_grasps(config, np.random.default_rng(0), 1)
