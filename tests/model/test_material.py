"""The material classifiers' timing features: what a slower loading and a larger force do to them."""

import numpy as np
import pytest

from neurotac_cli.model import material


def grasp(rise_frames: int, force: float, frames: int = 60) -> tuple:
    """Per-frame ON and OFF counts of a grasp: an LED OFF spike in frame 0, ON events over a loading
    of `rise_frames` frames growing with the force, a few events while held, OFF events on release."""
    rates = np.zeros((frames, 2))
    rates[0, 1] = 500.0
    rates[5:5 + rise_frames, 0] = force * 100.0 / rise_frames
    rates[5 + rise_frames:45, 0] = force * 0.5
    rates[45:50, 1] = force * 80.0 / 5
    pixels = np.zeros((frames, 2, 16))
    pixels[:, :, :4] = rates[:, :, None] / 4
    return rates, pixels.reshape(frames, -1)


def test_a_slower_loading_delays_every_rise_time_and_the_force_leaves_them_alone():
    fast, slow = (material.dynamics(grasp(rise, 2.0)[0]) for rise in (3, 9))
    assert fast.shape == (material.DYNAMICS,)
    assert (slow[:6] > fast[:6]).all()  # 10-70% of the ON events come later into a softer object
    weak, strong = (material.dynamics(grasp(5, force)[0]) for force in (1.0, 4.0))
    np.testing.assert_allclose(weak[:6], strong[:6], atol=1e-9)  # timing does not follow the amount
    assert strong[6] > weak[6]  # the amount does


def test_the_led_spike_before_the_loading_is_not_counted_as_release():
    rates, _ = grasp(5, 2.0)
    without = rates.copy()
    without[0, 1] = 0.0
    np.testing.assert_allclose(material.dynamics(rates), material.dynamics(without))


def test_a_trial_without_events_gives_zeros_and_widths_match_the_features():
    assert not material.dynamics(np.zeros((10, 2))).any()
    counts = grasp(5, 2.0)[1]
    for inputs in ("timing", "curves", "rises"):
        config = material.Config(inputs=inputs)
        x = material._trial_features(counts, np.zeros(60), config)
        assert x.shape == (material.feature_count(config),) and np.isfinite(x).all()
    rises = material._trial_features(counts, np.zeros(60), material.PRESETS["material-rises"])
    timing = material._trial_features(counts, np.zeros(60), material.PRESETS["material-timing"])
    np.testing.assert_array_equal(rises, timing[:6])  # the rise times, without the amounts


def test_the_discriminant_separates_classes_that_differ_along_a_correlated_direction():
    rng = np.random.default_rng(0)
    shared = rng.standard_normal((200, 1))
    z = np.hstack([shared, shared + 0.05 * rng.standard_normal((200, 1))])  # two nearly equal features
    y = np.repeat([0, 1], 100)
    z[y == 1, 1] += 0.3  # the classes differ only in the small difference between them
    weight, bias = material.discriminant(z, y, 3)
    predicted = np.argmax(z @ weight.T + bias, axis=1)
    assert (predicted == y).mean() > 0.95
    assert bias[2] < -1e8  # a class absent from training never wins


def test_features_are_standardised_per_domain_and_an_unknown_domain_takes_the_pooled_figures():
    x = np.array([[1.0, 10.0], [3.0, 30.0], [101.0, 0.0], [103.0, 2.0], [7.0, 7.0]])
    domains = np.array(["a", "a", "b", "b", "c"], dtype=object)
    stats = material.domain_stats(x[:4], domains[:4])
    z = material.standardised(x, domains, stats, pooled=(np.zeros(2), np.ones(2)))
    np.testing.assert_allclose(z[:4], [[-1, -1], [1, 1], [-1, -1], [1, 1]])
    np.testing.assert_allclose(z[4], [7.0, 7.0])
    assert set(material.domain_stats(x, domains, least=2)) == {"a", "b"}


def domain_frames(sizes, per_class=6, seed=0, forces=None):
    """Grasps of two materials on object sizes that slow every loading alike: a stiffer material
    loads in `rise` frames, a softer one in twice as many, and each size multiplies both. `forces`:
    {material: (low, high)} peak forces, 1-4 for both by default."""
    import pyarrow as pa

    from neurotac_cli import schema as sch

    rng = np.random.default_rng(seed)
    rows, counts = {name: [] for name in ("trial", "frame", "t", "force", "phase", "object", "material")}, []
    for size, scale in sizes.items():
        for name, rise in (("steel", 3), ("foam", 6)):
            for copy in range(per_class):
                _, pixels = grasp(int(round(rise * scale + rng.integers(0, 2))), float(rng.uniform(*(forces or {}).get(name, (1, 4)))), frames=80)
                pixels = rng.poisson(pixels + 0.05)
                trial = f"{size}-{name}-{copy}"
                for k, frame in enumerate(pixels.reshape(80, 2, 4, 4)):
                    counts.append(frame)
                    for key, value in (("trial", trial), ("frame", k), ("t", k * 7000), ("force", None), ("phase", None),
                                       ("object", size), ("material", name)):
                        rows[key].append(value)
    schema = sch.frames_schema(4, 4, labels=["object", "material"], window_us=7000)
    columns = {"trial": pa.array(rows["trial"]), "frame": pa.array(rows["frame"], pa.int32()), "t": pa.array(rows["t"], pa.int64()),
               "counts": sch.counts_array(np.asarray(counts, dtype=np.uint16)), "force": pa.array(rows["force"], pa.float32(), from_pandas=True),
               "phase": pa.array(rows["phase"], pa.string()), "object": pa.array(rows["object"]), "material": pa.array(rows["material"])}
    return pa.Table.from_arrays([columns[field.name] for field in schema], schema=schema)


def test_a_size_training_never_saw_is_read_against_its_own_grasps_with_adapt_by():
    """Trained on sizes whose loadings take 1x and 1.5x the frames, tested on one that takes 3x: every
    grasp of the new size loads more slowly than any training grasp of either material, so the plain
    discriminant calls them all the softer one; standardised within the size, the two materials part."""
    from neurotac_cli import model as models
    from neurotac_cli.model import core

    training = domain_frames({"small": 1.0, "medium": 1.5})
    test = domain_frames({"large": 3.0}, seed=1)
    accuracy = {}
    for adapt in (None, "object"):
        model = models.train(training, models.make_spec("material-timing", adapt_by=adapt), seed=0)
        predicted = core.classify_table(model, test)
        accuracy[adapt] = np.mean(np.asarray(predicted["material_pred"].to_pylist()) == np.asarray(predicted["material"].to_pylist()))
    assert accuracy[None] <= 0.6 and accuracy["object"] >= 0.9
    few = core.classify_table(model, test.slice(0, 80 * 3))  # 3 grasps: too few to stand for their size
    assert "large" not in model.input_spec["adapt"]["stats"] and few.num_rows == 3
    # 3 grasps of a size training saw take that size's training figures: as the size's 12 training
    # grasps given together, which are standardised over themselves, the same figures
    probability = [name for name in few.column_names if name.startswith("prob_")]
    alone = core.classify_table(model, training.slice(0, 80 * 3)).select(probability).to_pandas().to_numpy()
    together = core.classify_table(model, training).select(probability).to_pandas().to_numpy()[:3]
    np.testing.assert_allclose(alone, together, rtol=1e-5, atol=1e-6)


def test_adapting_needs_every_trial_s_domain_and_a_label_other_than_the_class_and_says_what_fell_back():
    import pyarrow as pa

    from neurotac_cli import model as models
    from neurotac_cli.errors import ModelError, UsageError
    from neurotac_cli.model import core

    training = domain_frames({"small": 1.0, "medium": 1.5})
    with pytest.raises(UsageError, match="--adapt-by material: that is the label the classifier predicts"):
        models.train(training, models.make_spec("material-timing", adapt_by="material"), seed=0)
    objects = training.column("object").to_pylist()
    unlabelled = training.set_column(training.schema.get_field_index("object"), training.schema.field("object"),
                                     pa.array([None] * 80 + objects[80:], pa.string()))
    with pytest.raises(ModelError, match="1 trial\\(s\\) with no object \\(small-steel-0\\)"):
        models.train(unlabelled, models.make_spec("material-timing", adapt_by="object"), seed=0)
    model = models.train(training, models.make_spec("material-timing", adapt_by="object"), seed=0)
    notes = []
    core.classify_table(model, domain_frames({"large": 3.0}, seed=1).slice(0, 80 * 3), notes)
    assert len(notes) == 1 and notes[0].startswith("object large: 3 trial(s), fewer than the 8") and "pooled" in notes[0]
    notes = []
    core.classify_table(model, domain_frames({"large": 3.0}, seed=1), notes)
    assert notes == []  # 12 grasps: standardised over their own


def test_the_rise_times_alone_name_a_size_whose_event_amounts_training_never_saw():
    """Trained where the squeeze follows the material (steel pressed harder, more events), the
    amounts name the material as well as the rise times do; on a larger face every grasp makes more
    events, so `material-timing` reads the new size's foam as steel, while the rise times alone do
    not move and `material-rises` reads them as on the sizes it trained on."""
    from neurotac_cli import model as models, schema as sch
    from neurotac_cli.model import core

    tied = {"steel": (3.0, 4.0), "foam": (1.0, 1.5)}
    training = domain_frames({"small": 1.0, "medium": 1.0}, forces=tied)
    test = domain_frames({"large": 1.0}, seed=1, forces=tied)
    bigger = sch.counts_array(sch.counts_numpy(test.column("counts")) * 4)
    test = test.set_column(test.schema.get_field_index("counts"), test.schema.field("counts"), bigger)
    accuracy = {}
    for name in ("material-timing", "material-rises"):
        model = models.train(training, models.make_spec(name), seed=0)
        predicted = core.classify_table(model, test)
        accuracy[name] = np.mean(np.asarray(predicted["material_pred"].to_pylist()) == np.asarray(predicted["material"].to_pylist()))
    assert accuracy["material-rises"] >= 0.9 and accuracy["material-timing"] <= 0.6, accuracy


def test_a_bright_objects_grasp_reads_as_a_dark_ones_with_its_polarities_swapped():
    """A bright object brightens the membrane as it presses (ON first, OFF as it lets go): every
    classifier reads the polarity its press made first as the press, so one trained on dark objects
    reads a bright one's grasp by the same features."""
    _, counts = grasp(5, 2.0)
    counts = counts.reshape(60, 2, -1)
    counts[0, 1] = 0.0  # no LED spike: events before a trial's sync instant are not framed
    bright = counts[:, ::-1]
    for name in ("material-dnn", "material-curves", "material-timing", "material-rises"):
        config = material.PRESETS[name]
        dark_x, bright_x = (material._trial_features(c.reshape(60, -1), np.zeros(60), config) for c in (counts, bright))
        np.testing.assert_allclose(dark_x, bright_x)
    accumulated = material.Config(inputs="curves", accumulate=False)
    dark_x, bright_x = (material._trial_features(np.cumsum(c, axis=0).reshape(60, -1), np.zeros(60), accumulated) for c in (counts, bright))
    np.testing.assert_allclose(dark_x, bright_x)


def test_a_material_model_written_before_the_polarity_was_read_keeps_reading_trials_as_framed(tmp_path):
    from neurotac_cli import model as models
    from tests.model.test_deform_gru import _without_setting

    model = models.train(domain_frames({"small": 1.0}), models.make_spec("material-timing"), seed=0)
    assert model.config.press_first
    old = _without_setting(model, tmp_path / "old.model", "press_first")
    assert old.config.press_first is False
