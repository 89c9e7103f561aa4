"""`ours`'s coarse spatial layout is `--layout-grid` (it was `--grid`, now the study grid of eval):
the option, the spec field, and model files written under the old name all still work; so do files
written before the depth-level features existed."""

import json

import pytest

torch = pytest.importorskip("torch")

from click.testing import CliRunner  # noqa: E402

from neurotac_cli import model as models  # noqa: E402
from neurotac_cli.errors import ModelError  # noqa: E402
from tests.test_model_helpers import tiny_frames, write_stream  # noqa: E402


def test_train_layout_grid_option_reaches_the_model_file(tmp_path):
    from neurotac_cli.cli import cli

    frames = write_stream(tiny_frames(trials=4), tmp_path / "f.arrows")
    done = CliRunner().invoke(cli, ["train", "--model", "deform-gru", "--layout-grid", "2", "--epochs", "1", str(frames),
                                    "-o", str(tmp_path / "m.model")])
    assert done.exit_code == 0, done.output
    assert models.load(str(tmp_path / "m.model")).config.layout_grid == 2
    old = CliRunner().invoke(cli, ["train", "--model", "deform-gru", "--grid", "2", str(frames), "-o", str(tmp_path / "x.model")])
    assert old.exit_code == 2 and "--layout-grid" in old.output  # click suggests the new name


def test_a_model_file_written_with_the_old_field_name_loads(tmp_path):
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    model = models.train(tiny_frames(trials=4), models.make_spec("deform-gru", layout_grid=2, epochs=1), val_fraction=0.25)
    path = tmp_path / "new.model"
    models.save(model, str(path))
    with safe_open(str(path), framework="pt") as handle:
        header = json.loads(handle.metadata()["neurotac"])
    architecture = header["architecture"]
    architecture["grid"] = architecture.pop("layout_grid")
    old = tmp_path / "old.model"
    save_file(load_file(str(path)), str(old), metadata={"neurotac": json.dumps(header)})
    loaded = models.load(str(old))
    assert loaded.config.layout_grid == 2


def test_a_model_file_written_before_the_depth_levels_loads_and_predicts_the_same(tmp_path):
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("deform-gru", levels=0, epochs=1), val_fraction=0.25)
    path = tmp_path / "new.model"
    models.save(model, str(path))
    with safe_open(str(path), framework="pt") as handle:
        header = json.loads(handle.metadata()["neurotac"])
    del header["architecture"]["levels"]  # the header and tensors of a file from before the field
    tensors = {name: tensor for name, tensor in load_file(str(path)).items() if name != "level_unit"}
    old = tmp_path / "old.model"
    save_file(tensors, str(old), metadata={"neurotac": json.dumps(header)})
    loaded = models.load(str(old))
    assert loaded.config.levels == 0
    expected = models.predict_table(model, frames).column("force_pred")
    assert models.predict_table(loaded, frames).column("force_pred").equals(expected)


def test_the_spec_field_is_layout_grid():
    assert models.make_spec("deform-gru", layout_grid=4)["layout_grid"] == 4
    with pytest.raises(ModelError, match="no option 'grid'"):
        models.make_spec("deform-gru", grid=4)
