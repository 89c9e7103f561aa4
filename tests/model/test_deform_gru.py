"""deform-gru's coarse spatial layout is `--layout-grid` (`--grid` is the study grid of eval and
study): the option reaches the model file, and the spec field has that name."""

import pytest

torch = pytest.importorskip("torch")

from click.testing import CliRunner  # noqa: E402

from neurotac_cli import model as models  # noqa: E402
from neurotac_cli.errors import UsageError  # noqa: E402
from neurotac_cli.model.core import split_spec  # noqa: E402
from tests.model.helpers import tiny_frames, write_stream  # noqa: E402


def test_train_layout_grid_option_reaches_the_model_file(tmp_path):
    from neurotac_cli.cli import cli

    frames = write_stream(tiny_frames(trials=4), tmp_path / "f.arrows")
    done = CliRunner().invoke(cli, ["train", "--model", "deform-gru", "--layout-grid", "2", "--epochs", "1", str(frames),
                                    "-o", str(tmp_path / "m.model")])
    assert done.exit_code == 0, done.output
    assert models.load(str(tmp_path / "m.model")).config.layout_grid == 2
    old = CliRunner().invoke(cli, ["train", "--model", "deform-gru", "--grid", "2", str(frames), "-o", str(tmp_path / "x.model")])
    assert old.exit_code == 2 and "--layout-grid" in old.output  # click suggests the new name


def test_the_spec_field_is_layout_grid():
    assert models.make_spec("deform-gru", layout_grid=4)["layout_grid"] == 4
    with pytest.raises(UsageError, match="no option 'grid'"):
        models.make_spec("deform-gru", grid=4)


def _without_setting(model, path, key: str):
    """`model` saved to `path` with `key` left out of its header's architecture, as a file written
    before that setting existed; loaded back."""
    import json

    from safetensors import safe_open
    from safetensors.torch import save_file

    from neurotac_cli.model.store import HEADER_KEY

    models.save(model, str(path))
    with safe_open(str(path), framework="pt") as handle:
        header = json.loads(handle.metadata()[HEADER_KEY])
        tensors = {key: handle.get_tensor(key) for key in handle.keys()}
    del header["architecture"][key]
    save_file(tensors, str(path), metadata={HEADER_KEY: json.dumps(header)})
    return models.load(str(path))


def test_a_file_from_before_the_excess_masses_loads_as_it_was_trained(tmp_path):
    """A header without `excess` means the feature set of its time (no excess masses), not today's default."""
    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("deform-gru", excess=False, epochs=1), seed=0)
    loaded = _without_setting(model, tmp_path / "old.model", "excess")
    assert loaded.config.excess is False
    expected = models.predict_table(model, frames).column("force_pred").to_numpy()
    assert (models.predict_table(loaded, frames).column("force_pred").to_numpy() == expected).all()
    assert models.make_spec("deform-gru") == {"model": "deform-gru"} and split_spec({"model": "deform-gru"})[1].excess


def test_deform_gru_waits_longer_than_the_thesis_protocol_unless_told():
    assert split_spec({"model": "deform-gru"})[2].patience == 40
    assert split_spec({"model": "deform-gru", "patience": 7})[2].patience == 7
    assert split_spec({"model": "lstm"})[2].patience == 20


def test_a_cross_validation_task_carries_every_default_it_trains_with():
    """Study caches key trainings by their task: a model's changed default must change the key."""
    from neurotac_cli.model.cv import fold_tasks
    from neurotac_cli.model.data import sequences

    data = sequences(tiny_frames(trials=4))
    _, tasks = fold_tasks(data, {"model": "deform-gru"}, "kfold:2", 1, 0, 0.1, None)
    assert tasks[0]["spec"]["patience"] == 40 and tasks[0]["spec"]["excess"] is True


@pytest.mark.parametrize("memory_frames", [0, 50])
def test_long_runs_of_large_frames_are_featured_in_pieces_of_time_with_the_same_result(monkeypatch, memory_frames):
    # a whole contact at full sensor size took all of a 24 GB machine's memory at once
    from neurotac_cli.model import deform_gru

    net = deform_gru.Net(deform_gru.Config(memory_frames=memory_frames), (2, 30, 40))
    counts = torch.randint(0, 5, (3, 60, 2, 30, 40)).float()
    whole, after = net.features(counts, net.init_state(3))
    monkeypatch.setattr(deform_gru, "FEATURE_VALUES", 30 * 40 * 8 * 3 * 7)  # 7 frames a piece
    pieces, after_pieces = net.features(counts, net.init_state(3))
    assert torch.allclose(whole, pieces, atol=1e-5) and torch.allclose(after["deformation"], after_pieces["deformation"])


def test_members_validate_on_draws_of_their_own_and_together_train_on_every_trial():
    import numpy as np

    from neurotac_cli.model.data import padded, sequences

    frames = tiny_frames(trials=12)
    model = models.train(frames, models.make_spec("deform-gru", members=3, epochs=3), val_fraction=0.2, seed=0)
    trials = model.training["trials"]
    draws = [trials["validation"], *trials["member_validation"]]
    assert len(draws) == 3 and len({tuple(sorted(d)) for d in draws}) > 1
    # the record's split is the first member's, as a one-GRU model's with the same seed
    assert sorted(trials["train"]) == sorted({f"t{i}" for i in range(12)} - set(trials["validation"]))
    one = models.train(frames, models.make_spec("deform-gru", members=1, epochs=3), val_fraction=0.2, seed=0)
    assert one.training["trials"]["validation"] == trials["validation"]
    assert torch.equal(one.net.feature_mean, model.net.feature_mean)
    assert len(model.training["member_best_epochs"]) == 3
    # the estimate is the members' mean, and each member was trained (no two alike)
    net = model.net
    features = net.encode(torch.as_tensor(padded(sequences(frames).counts)), None)
    each = torch.stack([net.forward_encoded(features, member=i) for i in range(3)])
    assert torch.allclose(net.forward_encoded(features), each.mean(dim=0), atol=1e-6)
    assert not torch.allclose(each[0], each[1]) and np.isfinite(each.detach().numpy()).all()


def test_a_members_model_streams_frame_by_frame_as_it_reads_whole_trials(tmp_path):
    import numpy as np

    from neurotac_cli.model.data import sequences

    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("deform-gru", members=2, epochs=2), seed=1)
    models.save(model, str(tmp_path / "m.model"))
    loaded = models.load(str(tmp_path / "m.model"))
    assert loaded.config.members == 2
    whole = models.predict_table(loaded, frames).column("force_pred").to_numpy()
    counts = torch.as_tensor(sequences(frames).counts[0][None]).float()
    state, steps = None, []
    with torch.no_grad():
        for k in range(counts.shape[1]):
            out, state = loaded.net(counts[:, k : k + 1], None, state)
            steps.append(float(out[0, 0]) * loaded.force_scale)
    first = frames.column("trial").to_numpy(zero_copy_only=False) == "t0"
    assert abs(np.array(steps) - whole[first]).max() < 1e-4 * max(1.0, abs(whole).max())


def test_a_file_without_members_is_one_gru(tmp_path):
    """A header without `members` is a file of one GRU, loaded and read as it was trained."""
    from neurotac_cli.model import deform_gru

    assert deform_gru.ABSENT_MEANS["members"] == 1
    assert len(deform_gru.Net(deform_gru.Config(members=1), (2, 5, 5)).members()) == 1
    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("deform-gru", members=1, epochs=1), seed=0)
    loaded = _without_setting(model, tmp_path / "one.model", "members")
    assert loaded.config.members == 1
    expected = models.predict_table(model, frames).column("force_pred").to_numpy()
    assert (models.predict_table(loaded, frames).column("force_pred").to_numpy() == expected).all()


def test_info_names_the_members_and_their_best_epochs(tmp_path):
    from neurotac_cli.describe import _model_lines, describe_model

    model = models.train(tiny_frames(trials=6), models.make_spec("deform-gru", members=2, epochs=2), val_fraction=0.3, seed=0)
    models.save(model, str(tmp_path / "m.model"))
    training = dict(pair for pair in _model_lines(describe_model(str(tmp_path / "m.model"))) if isinstance(pair, tuple))["training"]
    epochs = ", ".join(map(str, model.training["member_best_epochs"]))
    assert training.endswith(f"; 2 members, each validating on a draw of its own, best epochs {epochs}")


def test_every_members_curve_is_kept_tabled_and_drawn(tmp_path):
    from PIL import Image

    from neurotac_cli.model.curve import best_epoch, member_curves
    from neurotac_cli.model.plots import curve_figure
    from neurotac_cli.model.training import train_model

    trained = train_model(tiny_frames(trials=6), "deform-gru", {"members": 3, "epochs": 3}, val_fraction=0.3, seed=0)
    curves = trained.model.training["member_curves"]
    assert len(curves) == 3 and curves[0] == trained.model.training["curve"]
    assert [best_epoch(c)["epoch"] for c in curves] == trained.model.training["member_best_epochs"]
    models.save(trained.model, str(tmp_path / "m.model"))
    assert models.load(str(tmp_path / "m.model")).training["member_curves"] == curves
    table = trained.curve.to_pydict()
    for i, curve in enumerate(curves):
        mine = [value for model, value in zip(table["model"], table["value"]) if model == f"deform-gru member {i + 1}/3"]
        assert mine == [row[key] for row in curve for key in ("train_loss", "val_loss")]
    assert list(member_curves(trained.model.training)) == ["member 1/3", "member 2/3", "member 3/3"]
    curve_figure(member_curves(trained.model.training), str(tmp_path / "c.png"), title="deform-gru training curve")
    with Image.open(tmp_path / "c.png") as image:
        assert image.format == "PNG"


def test_a_one_network_curve_table_names_the_model_alone():
    from neurotac_cli.model.training import train_model

    trained = train_model(tiny_frames(trials=4), "deform-gru", {"members": 1, "epochs": 2}, seed=0)
    assert "member_curves" not in trained.model.training
    assert set(trained.curve.column("model").to_pylist()) == {"deform-gru"}


def test_info_says_when_members_shared_one_validation_draw(tmp_path):
    from neurotac_cli.describe import _model_lines, describe_model

    model = models.train(tiny_frames(trials=6), models.make_spec("deform-gru", members=3, epochs=1), val_trials=["t0"], seed=0)
    assert model.training["trials"]["member_validation"] == [["t0"], ["t0"]]
    models.save(model, str(tmp_path / "m.model"))
    training = dict(pair for pair in _model_lines(describe_model(str(tmp_path / "m.model"))) if isinstance(pair, tuple))["training"]
    assert "3 members, validating on 1 distinct draw(s), best epochs" in training


def test_info_claims_no_validation_draw_for_members_that_had_none(tmp_path):
    from neurotac_cli.describe import _model_lines, describe_model

    model = models.train(tiny_frames(trials=6), models.make_spec("deform-gru", members=3, epochs=1), val_fraction=0, seed=0)
    assert model.training["trials"]["validation"] == [] and model.training["trials"]["member_validation"] == [[], []]
    models.save(model, str(tmp_path / "m.model"))
    training = dict(pair for pair in _model_lines(describe_model(str(tmp_path / "m.model"))) if isinstance(pair, tuple))["training"]
    assert "(no validation trials); 3 members, best epochs" in training and "validating on" not in training
