"""deform-gru's coarse spatial layout is `--layout-grid` (`--grid` is the study grid of eval and
study): the option reaches the model file, and the spec field has that name."""

import pytest

torch = pytest.importorskip("torch")

from click.testing import CliRunner  # noqa: E402

from neurotac_cli import model as models  # noqa: E402
from neurotac_cli.errors import ModelError  # noqa: E402
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
    with pytest.raises(ModelError, match="no option 'grid'"):
        models.make_spec("deform-gru", grid=4)
