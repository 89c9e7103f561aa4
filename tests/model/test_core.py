import json

import numpy as np
import pyarrow as pa
import pytest

from neurotac_cli import model as models
from neurotac_cli.errors import ModelError, UsageError
from neurotac_cli.model import store
from tests.model.helpers import tiny_frames

ALL = models.FORCE_MODELS + models.MATERIAL_MODELS
FAST = {"epochs": 3, "batch_size": 4}


@pytest.fixture(scope="module")
def frames():
    return tiny_frames()


def _outputs(model, table):
    if model.task == "force":
        return models.predict_table(model, table).column("force_pred").to_numpy()
    result = models.classify_table(model, table)
    return np.stack([result.column(f"prob_{c}").to_numpy() for c in model.classes])


@pytest.mark.parametrize("name", ALL)
def test_every_model_trains_and_round_trips_with_identical_predictions(name, frames, tmp_path):
    options = dict(FAST) if name != "gp" else {"restarts": 0, "max_points": 200}
    model = models.train(frames, models.make_spec(name, **options), val_fraction=0.3, seed=1)
    path = tmp_path / f"{name}.model"
    models.save(model, str(path))
    loaded = models.load(str(path))
    assert loaded.name == name and loaded.task == model.task
    np.testing.assert_array_equal(_outputs(model, frames), _outputs(loaded, frames))


def test_model_file_is_safetensors_with_a_json_header_and_no_pickle(frames, tmp_path):
    model = models.train(frames, models.make_spec("convlstm", **FAST), val_fraction=0.3, seed=0)
    path = tmp_path / "m.model"
    models.save(model, str(path))
    raw = path.read_bytes()
    assert b"\x80\x04" not in raw[:16]  # no pickle protocol header
    header = store.read_header(str(path))
    assert header["architecture"] == {"layers": 4, "filters": 3, "kernel": 3, "dropout": 0.4, "dense": 0}
    assert header["input"]["height"] == 9 and header["input"]["window_us"] == 10000
    assert header["input"]["channels"] == ["off", "on"]
    assert "count_scale" in header["input"]["normalisation"]
    assert set(header["training"]["trials"]) == {"train", "validation"}
    json.dumps(header)


def test_gp_is_stored_as_arrays(frames, tmp_path):
    model = models.train(frames, models.make_spec("gp", restarts=1, max_points=50), seed=0)
    path = tmp_path / "gp.model"
    models.save(model, str(path))
    from safetensors.torch import load_file

    tensors = load_file(str(path))
    assert tensors["inputs"].shape == (50, 3) and tensors["dual"].shape == (50,)
    assert tensors["length_scale"].shape == (3,)


def test_a_gp_reports_its_held_out_error_and_no_epochs(frames):
    from neurotac_cli.model.training import train_model

    trained = train_model(frames, "gp", {"restarts": 1, "max_points": 50}, val_fraction=0.3, seed=0)
    (row,) = trained.model.training["curve"]
    assert row["val_loss"] == row["val_loss"] and row["val_loss"] > 0  # measured on the held-out trials
    assert trained.summary.startswith("gp: fitted in closed form (train ") and ", validation " in trained.summary
    assert "epoch" not in trained.summary


def test_same_seed_same_model(frames):
    a = models.train(frames, models.make_spec("deform-gru", **FAST), val_fraction=0.3, seed=5)
    b = models.train(frames, models.make_spec("deform-gru", **FAST), val_fraction=0.3, seed=5)
    np.testing.assert_array_equal(_outputs(a, frames), _outputs(b, frames))


def test_normalisation_is_fitted_on_training_trials_only(frames):
    from neurotac_cli.model.data import sequences

    data = sequences(frames)
    model = models.train(frames, models.make_spec("convlstm", epochs=1), val_trials=["t0", "t1"], seed=0)
    train = [c for c, trial in zip(data.counts, data.trials) if trial not in ("t0", "t1")]
    expected = np.max([c.reshape(len(c), 2, -1).max(axis=(0, 2)) for c in train], axis=0)
    np.testing.assert_array_equal(model.net.count_scale.numpy(), expected.astype(np.float32))
    assert model.training["trials"]["validation"] == ["t0", "t1"]


def test_early_stopping_restores_best_weights(frames):
    import pyarrow as pa
    import pyarrow.compute as pc

    # one member: its curve is the whole model's (a model of several keeps the first member's)
    model = models.train(frames, models.make_spec("deform-gru", epochs=40, patience=2, lr=0.05, members=1), val_fraction=0.3, seed=0)
    curve = model.training["curve"]
    best = min(row["val_loss"] for row in curve)
    assert len(curve) < 40 or curve[-1]["val_loss"] == best
    predictions = models.predict_table(model, frames)
    assert predictions.num_rows == frames.num_rows
    # the weights kept score the validation trials as the best epoch did, not as the last one did
    assert curve[-1]["val_loss"] > best * 1.01, "this run never got worse after its best epoch: nothing to restore"
    held = predictions.filter(pc.is_in(predictions.column("trial"), value_set=pa.array(model.training["trials"]["validation"])))
    force, estimate = (held.column(name).to_numpy(zero_copy_only=False) for name in ("force", "force_pred"))
    measured = ~np.isnan(force)
    restored = np.mean(((estimate[measured] - force[measured]) / model.force_scale) ** 2)
    assert restored == pytest.approx(best, rel=1e-4)


def test_unknown_option_and_model_are_refused():
    with pytest.raises(UsageError, match="no option 'delays'"):
        models.make_spec("convlstm", delays=3)
    with pytest.raises(ModelError, match="unknown model"):
        models.make_spec("resnet")


def test_a_foreign_file_is_refused_clearly(tmp_path):
    path = tmp_path / "bad.model"
    path.write_bytes(b"not a model at all")
    with pytest.raises(ModelError, match="not a neurotac model file"):
        models.load(str(path))


def test_ours_trained_on_features_computed_once_equals_the_full_forward():
    import torch

    from neurotac_cli.model import deform_gru

    net = deform_gru.Net(deform_gru.Config(hidden=8), (2, 12, 10))
    generator = torch.Generator().manual_seed(3)
    counts = torch.poisson(torch.full((5, 7, 2, 12, 10), 0.7), generator=generator)
    t_s = torch.arange(7, dtype=torch.float64).repeat(5, 1) * 0.01
    net.calibrate([c.numpy() for c in counts], [t.numpy() for t in t_s])
    with torch.no_grad():
        full, _ = net(counts, t_s)
        encoded = net.forward_encoded(net.encode(counts, t_s, chunk=2))
    assert torch.allclose(full, encoded, atol=1e-5)


@pytest.mark.parametrize("with_validation", [True, False])
def test_a_training_that_diverges_is_refused_not_written_as_its_untrained_weights(with_validation):
    import torch

    from neurotac_cli.model.fit import FitConfig, fit

    net = torch.nn.Linear(1, 1)
    x = torch.ones(4, 1)

    def batch_loss(indices):
        return (net(x[indices]) * float("nan")).sum()

    def val_loss():
        return float((net(x) * float("inf")).sum()) if with_validation else None

    with pytest.raises(ModelError, match="diverged at epoch 1 .* lower --lr"):
        fit(net, batch_loss, 4, val_loss, FitConfig(epochs=3), torch.Generator().manual_seed(0))


def test_an_interrupted_fit_keeps_its_best_epoch_where_the_caller_asks_and_begins_no_member_after_it():
    import torch

    from neurotac_cli.model.fit import FitConfig, fit, kept_on_interrupt

    net = torch.nn.Linear(1, 1)
    x, y = torch.ones(4, 1), torch.full((4, 1), 3.0)
    calls, states = [0], []

    def batch_loss(indices):
        calls[0] += 1
        if calls[0] == 9:  # in the fifth epoch (2 batches of 2 each)
            raise KeyboardInterrupt
        return ((net(x[indices]) - y[indices]) ** 2).mean()

    def val_loss():
        states.append({key: value.clone() for key, value in net.state_dict().items()})
        return float(((net(x) - y) ** 2).mean())

    config = FitConfig(epochs=50, batch_size=2, lr=0.1)
    with pytest.raises(KeyboardInterrupt):  # a fit of a study, or of a command that does not keep it: lost
        fit(net, batch_loss, 4, val_loss, config, torch.Generator().manual_seed(0))
    calls[0], states[:] = 0, []
    with kept_on_interrupt() as stops:
        curve = fit(net, batch_loss, 4, val_loss, config, torch.Generator().manual_seed(0))
        assert len(curve) == 4 and [(label, epochs) for label, epochs, _ in stops] == [("train", 4)]
        best = min(range(4), key=lambda k: curve[k]["val_loss"])
        assert all(torch.equal(net.state_dict()[key], states[best][key]) for key in states[best])
        with pytest.raises(KeyboardInterrupt):  # the next member would be untrained: not begun
            fit(net, batch_loss, 4, val_loss, config, torch.Generator().manual_seed(0))
    calls[0] = 8  # interrupted in its first epoch: nothing to keep
    with kept_on_interrupt() as stops, pytest.raises(KeyboardInterrupt):
        fit(net, batch_loss, 4, val_loss, config, torch.Generator().manual_seed(0))


@pytest.mark.parametrize("setting, value", [("layers", 100_000), ("lr", 1e39), ("weight_decay", 1e39), ("units", 10**9)])
def test_sizes_and_rates_far_past_any_network_are_refused(setting, value):
    with pytest.raises(UsageError, match=f"--{setting.replace('_', '-')} must be a finite number"):
        models.make_spec("tdnn", **{setting: value})


def test_a_force_reading_classifier_refuses_trials_whose_force_was_not_measured(frames):
    model = models.train(frames, models.make_spec("material-force", epochs=2), seed=0)
    force = frames.schema.get_field_index("force")
    blind = frames.set_column(force, frames.schema.field(force), pa.nulls(frames.num_rows, pa.float32()))
    with pytest.raises(ModelError, match=r"material-force reads the measured force, and \d+ trials .* have none"):
        models.classify_table(model, blind.replace_schema_metadata(frames.schema.metadata))


def _cropped(box):
    return [{"command": "frame", "args": {"window_us": 10000}}, {"command": "crop", "args": {"report": {"box": list(box)}}}]


def test_frames_cropped_elsewhere_on_the_sensor_or_of_no_stated_window_are_named():
    from neurotac_cli import schema as sch
    from neurotac_cli.model.core import input_notes

    schema = sch.set_meta(sch.frames_schema(32, 32, window_us=10000), history=_cropped((0, 0, 32, 32)))
    spec = {"window_us": 10000}
    (note,) = input_notes(spec, _cropped((104, 74, 32, 32)), schema)
    assert "cropped to the box 0,0,32,32 of the sensor, the model's training frames to 104,74,32,32" in note
    assert input_notes(spec, _cropped((4, 2, 32, 32)), schema) == []  # an automatic centre a few pixels off
    assert input_notes(spec, [], schema) == []  # a history that does not say
    (note,) = input_notes({"window_us": None}, [], schema)
    assert "the model does not record the window of its training frames" in note


def test_classify_names_trials_much_shorter_than_any_it_learnt_from(frames):
    import pyarrow.compute as pc

    model = models.train(frames, models.make_spec("material-dnn", epochs=2), seed=0)
    assert model.training["trial_frames"] == [12, 12]
    notes = []
    models.classify_table(model, frames, notes)
    assert notes == []
    cut = frames.filter(pc.less(frames.column("frame"), 3))
    models.classify_table(model, cut, notes)
    assert len(notes) == 1 and "hold fewer than half the frames of the shortest training trial (12)" in notes[0]


def _without_force(frames, trials):
    import pyarrow.compute as pc

    force = frames.schema.get_field_index("force")
    gone = pc.is_in(frames.column("trial"), pa.array(trials))
    column = pc.if_else(gone, pa.nulls(frames.num_rows, pa.float32()), frames.column("force"))
    return frames.set_column(force, frames.schema.field(force), column).replace_schema_metadata(frames.schema.metadata)


@pytest.mark.parametrize("name", ["tdnn", "gp"])
def test_trials_without_any_force_are_left_out_of_training_and_validation_and_counted(name, frames):
    blind = _without_force(frames, ["t1", "t3", "t5", "t7"])  # every "large" trial: a draw per object validates on them
    options = dict(FAST) if name != "gp" else {"restarts": 0, "max_points": 200}
    messages = []
    model = models.train(blind, models.make_spec(name, **options), val_fraction=0.3, seed=1, progress=messages.append)
    held = model.training["trials"]
    assert not {"t1", "t3", "t5", "t7"} & set(held["train"] + held["validation"])
    assert any("4 trials without a measured force" in m and "left out of training and validation" in m for m in messages)
    assert all(row["val_loss"] != 0 for row in model.training["curve"])  # nothing is never scored as a perfect 0
    with pytest.raises(ModelError, match="validation trial 't3' has no measured force"):
        models.train(blind, models.make_spec(name, **options), val_trials=["t3"], seed=1)


def _flip_weights(path):
    """What tests/h2's flip.py does: the high byte of every fourth byte of the weights changed, finite but absurd."""
    import struct

    data = bytearray(path.read_bytes())
    (header,) = struct.unpack("<Q", data[:8])
    for i in range(8 + header + 3, len(data), 4):
        data[i] ^= 0x7F
    path.write_bytes(bytes(data))


def test_a_model_whose_weights_were_damaged_is_refused_on_load(frames, tmp_path):
    path = tmp_path / "tdnn.model"
    models.save(models.train(frames, models.make_spec("tdnn", **FAST), seed=0), str(path))
    _flip_weights(path)
    with pytest.raises(ModelError, match="do not match the checksum written with them"):
        models.load(str(path))


def test_a_gp_out_of_its_fitting_bounds_is_refused_on_load(frames, tmp_path):
    import torch

    model = models.train(frames, models.make_spec("gp", restarts=0, max_points=100), seed=0)
    model.net.length_scale = torch.tensor([5e4, 1.0, 1.0], dtype=torch.float64)
    path = tmp_path / "gp.model"
    models.save(model, str(path))
    with pytest.raises(ModelError, match=r"length scale 5e\+04 is outside 0.01..1000"):
        models.load(str(path))


def test_nan_forces_and_nan_class_probabilities_are_refused_not_written(frames):
    import torch

    force = models.train(frames, models.make_spec("tdnn", **FAST), seed=0)
    classifier = models.train(frames, models.make_spec("material-dnn", epochs=2), seed=0)
    for model in (force, classifier):
        with torch.no_grad():
            next(model.net.parameters()).fill_(float("nan"))
    with pytest.raises(ModelError, match="gives a NaN or infinite force"):
        models.predict_table(force, frames)
    with pytest.raises(ModelError, match="gives NaN class probabilities"):
        models.classify_table(classifier, frames)


def test_a_force_that_varies_below_the_scale_floor_is_refused_with_its_range(frames):
    force = frames.schema.get_field_index("force")
    tiny = frames.set_column(force, frames.schema.field(force), pa.array(frames.column("force").to_numpy() * 1e-9, pa.float32()))
    with pytest.raises(ModelError, match=r"varies over 3e-09 N only, below the 1e-06 N .* give the force in newtons"):
        models.train(tiny.replace_schema_metadata(frames.schema.metadata), models.make_spec("tdnn", **FAST), seed=0)


def test_a_discriminant_refuses_classes_of_one_training_trial_each_and_reports_its_fit_as_closed_form(frames):
    from neurotac_cli.model.training import train_model

    messages = []
    with pytest.raises(ModelError, match=r"material-timing pools a spread within each material and needs a material with at "
                                         r"least 2 training trials; training holds one of each \(foam, steel\)"):
        models.train(frames, models.make_spec("material-timing", epochs=2), val_trials=["t0", "t1", "t2", "t3", "t4", "t5"],
                     seed=0, progress=messages.append)
    assert messages == []  # the refusal is the only line
    models.train(frames, models.make_spec("material-timing", epochs=2), val_trials=["t0", "t1", "t2", "t3", "t4"], seed=0)
    trained = train_model(frames, "material-timing", {"epochs": 2}, seed=0)
    assert trained.summary.startswith("material-timing: discriminant fitted in closed form, the scale of its probabilities in ")


def test_frames_whose_time_goes_back_are_refused_before_any_warning_about_their_gaps(frames):
    from neurotac_cli.errors import SchemaError
    from neurotac_cli.model.core import missing_frames

    index = frames.schema.get_field_index("frame")
    numbers = frames.column("frame").to_numpy().copy()
    numbers[0] = 100  # t0's first frame renumbered after the others, a gap before it, its t unchanged: time goes back
    shifted = frames.set_column(index, frames.schema.field(index), pa.array(numbers, pa.int32()))
    assert missing_frames(frames) == {f"t{i}": 0 for i in range(8)}
    with pytest.raises(SchemaError, match="trial 't0': t goes back"):
        missing_frames(shifted.replace_schema_metadata(frames.schema.metadata))
    gapped = frames.filter(pa.array([not (trial == "t1" and frame in (3, 4)) for trial, frame
                                     in zip(frames.column("trial").to_pylist(), frames.column("frame").to_pylist())]))
    twice = pa.concat_tables([gapped, gapped.slice(0, 2)])  # a frame given twice is one frame, not a gap filled
    assert missing_frames(gapped) == missing_frames(twice) == {**{f"t{i}": 0 for i in range(8)}, "t1": 2}


def test_a_gp_of_a_handful_of_points_is_refused_and_delays_past_every_trial_are_named(frames):
    with pytest.raises(UsageError, match="--max-points must be a finite number from 10 to 20000, got 1"):
        models.make_spec("gp", max_points=1)
    messages = []
    models.train(frames, models.make_spec("tdnn", delays=12, epochs=1), seed=0, progress=messages.append)
    assert any(m.startswith("warning: --delays 12 reaches past the start of every training trial (the longest has 12 frames)")
               for m in messages)


def test_a_gp_fitted_on_fewer_points_than_today_s_least_still_loads(frames, tmp_path):
    """--max-points now starts at 10; a model fitted on 5 before that is no less a model."""
    import json

    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    from neurotac_cli.model.store import DIGEST_KEY, HEADER_KEY

    models.save(models.train(frames, models.make_spec("gp", restarts=0, max_points=50), seed=0), str(tmp_path / "m.model"))
    with safe_open(str(tmp_path / "m.model"), "pt") as handle:
        header = json.loads(handle.metadata()[HEADER_KEY])
    header["architecture"]["max_points"] = 5
    del header[DIGEST_KEY]
    save_file(load_file(str(tmp_path / "m.model")), str(tmp_path / "old.model"), metadata={HEADER_KEY: json.dumps(header)})
    assert models.load(str(tmp_path / "old.model")).config.max_points == 5
