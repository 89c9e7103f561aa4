"""Training on another device (`--device`, NEUROTAC_DEVICE): every force network keeps its state and
constants on the device its parameters are on, the choice is checked before any work, and a GPU's
trainings are cached apart from the CPU's. The "meta" device stands in for a GPU: it runs the same
device-generic code (not the ConvLSTM's CPU loops) and computes shapes only."""

import pytest
import torch
from click.testing import CliRunner

from neurotac_cli.cli import cli
from neurotac_cli.errors import ModelError, UsageError
from neurotac_cli.model.core import _module
from neurotac_cli.model.fit import DEVICE_VARIABLE, training_device
from neurotac_cli.study import task_key
from tests.model.helpers import tiny_frames, write_stream


@pytest.mark.parametrize("name", ["tdnn", "lstm", "cnnlstm", "convlstm", "deform-gru"])
def test_a_network_on_another_device_keeps_its_state_there_forward_and_backward(name):
    module = _module(name)
    net = module.Net(module.Config(), (2, 12, 10)).to("meta").train()
    counts = torch.zeros(3, 5, 2, 12, 10, device="meta")
    out, state = net(counts, torch.zeros(3, 5, dtype=torch.float64, device="meta"))
    out.sum().backward()
    assert out.shape == (3, 5) and out.device.type == "meta"
    assert {value.device.type for value in state.values()} == {"meta"}
    assert all(p.grad is not None and p.grad.device.type == "meta" for p in net.parameters() if p.requires_grad)


def test_the_device_is_the_cpu_unless_named(monkeypatch):
    monkeypatch.delenv(DEVICE_VARIABLE, raising=False)
    assert training_device() == torch.device("cpu")
    monkeypatch.setenv(DEVICE_VARIABLE, "bogus")
    with pytest.raises(UsageError, match="unknown device 'bogus'"):
        training_device()
    monkeypatch.setenv(DEVICE_VARIABLE, "mps")
    with pytest.raises(UsageError, match="cpu or cuda"):
        training_device()


@pytest.mark.skipif(torch.cuda.is_available(), reason="this torch sees a CUDA GPU")
def test_a_gpu_asked_of_a_cpu_build_is_one_line_and_exit_1(tmp_path, monkeypatch):
    monkeypatch.setenv(DEVICE_VARIABLE, "cuda")
    with pytest.raises(ModelError, match="sees no CUDA GPU"):
        training_device()
    frames = write_stream(tiny_frames(), tmp_path / "frames.arrows")
    result = CliRunner().invoke(cli, ["train", "--model", "lstm", "--device", "cuda", "-o", str(tmp_path / "m.model"), str(frames)])
    assert result.exit_code == 1 and "sees no CUDA GPU" in result.output
    assert not (tmp_path / "m.model").exists()


def test_an_unknown_device_is_a_usage_error_before_any_work(tmp_path, monkeypatch):
    monkeypatch.setenv(DEVICE_VARIABLE, "cpu")  # restored after the command sets it
    frames = write_stream(tiny_frames(), tmp_path / "frames.arrows")
    result = CliRunner().invoke(cli, ["study", "--model-spec", "lstm", "--device", "tpu:0", str(frames)])
    assert result.exit_code == 2 and "device" in result.output


def test_gpu_trainings_are_cached_apart_from_cpu_ones(monkeypatch):
    task = {"fold": 3, "seed": 1}
    monkeypatch.delenv(DEVICE_VARIABLE, raising=False)
    plain = task_key(test_gpu_trainings_are_cached_apart_from_cpu_ones, task)
    monkeypatch.setenv(DEVICE_VARIABLE, "cpu")
    assert task_key(test_gpu_trainings_are_cached_apart_from_cpu_ones, task) == plain
    monkeypatch.setenv(DEVICE_VARIABLE, "cuda")
    assert task_key(test_gpu_trainings_are_cached_apart_from_cpu_ones, task) != plain


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA GPU here")
@pytest.mark.parametrize("name", ["convlstm", "deform-gru"])
def test_a_gpu_training_matches_the_cpu_one_to_float32_rounding_and_comes_back_to_the_cpu(name, monkeypatch):
    from neurotac_cli import model as models

    curves = {}
    for device in ("cpu", "cuda"):
        monkeypatch.setenv(DEVICE_VARIABLE, device)
        trained = models.train(tiny_frames(), models.make_spec(name, epochs=2, dropout=0.0), seed=0)
        assert {p.device.type for p in trained.net.parameters()} == {"cpu"}
        assert trained.training.get("device", "cpu").startswith(device)
        curves[device] = [row["train_loss"] for row in trained.training["curve"]]
    assert curves["cuda"] == pytest.approx(curves["cpu"], rel=1e-3)
