"""The Python API: docs/python.md's examples run, in order, in an empty folder."""

import pathlib
import re

import pytest

DOC = pathlib.Path(__file__).resolve().parent.parent / "docs" / "python.md"


def test_the_python_page_runs(tmp_path, monkeypatch):
    pytest.importorskip("tonic")
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) >= 4
    namespace = {}
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), namespace)
    for made in ("frames.parquet", "rotated.png", "slices.png", "predictions.csv", "force.model"):
        assert (tmp_path / made).stat().st_size > 0


def test_the_package_is_cheap_to_import():
    import subprocess
    import sys

    code = "import sys, neurotac_cli; print(sorted(m for m in ('pyarrow', 'torch', 'numpy') if m in sys.modules))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "[]"


def test_the_package_gives_the_api_functions_on_first_use():
    import neurotac_cli
    from neurotac_cli import api

    assert neurotac_cli.frame is api.frame and neurotac_cli.Stepper is api.Stepper
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        neurotac_cli.nothing_here  # noqa: B018


def test_every_api_name_is_listed_in_the_package():
    import inspect

    import neurotac_cli
    from neurotac_cli import api

    public = {name for name, value in vars(api).items() if not name.startswith("_")
              and (inspect.isfunction(value) or inspect.isclass(value))
              and value.__module__ in ("neurotac_cli.api", "neurotac_cli.ops.augment")}
    assert public | {"TONIC_DTYPE"} == set(neurotac_cli.API)


def test_odd_arguments_give_a_neurotac_error(tmp_path):
    import numpy as np

    from neurotac_cli import api
    from neurotac_cli.errors import NeurotacError

    recordings = api.simulate("ch4", trials=2, seed=1)
    frames = api.crop(api.frame(recordings, "10ms"), size=(30, 30), center="auto", pool=(3, 3))
    model = api.train(frames, "tdnn", epochs=1)
    calls = [
        lambda: api.simulate("ch4", trials=-1),
        lambda: api.write([1, 2], str(tmp_path / "x.parquet")),
        lambda: api.frame(frames, "10ms"),
        lambda: api.frame(recordings, "10ms", bogus=1),
        lambda: api.frame(recordings, "10ms", start_us=0),
        lambda: api.crop(frames, size=(6, 6), center="10;10"),
        lambda: api.augment(frames, "rotate"),
        lambda: api.augment(frames.slice(0, 0), api.Rotate(0, 10)),
        lambda: api.counts(recordings),
        lambda: api.train(frames, "tdnn", val_fraction=1.5),
        lambda: api.evaluate("force.model", frames),
        lambda: api.save_model("x", str(tmp_path / "y.model")),
        lambda: api.Stepper(model).step(np.zeros((2, 5, 5)), 0),
        lambda: api.to_tonic(frames),
        lambda: api.from_tonic(np.zeros(3), (10, 10, 2)),
        lambda: api.events_of(frames, "x"),
        lambda: api.render(frames, str(tmp_path / "x.png"), bogus=1),
        lambda: api.render(frames.slice(0, 0), str(tmp_path / "x.png")),
        # once a numpy, Arrow or Python error from deeper down
        lambda: api.simulate("ch4", trials=1, seed=-1),
        lambda: api.simulate("ch4", trials=1.5),
        lambda: api.train(frames, "tdnn", seed=-1, epochs=1),
        lambda: api.augment(frames, api.FrameShift(1), copies="2"),
        lambda: api.augment(frames, api.FrameShift(1), seed="a"),
        lambda: api.crop(frames, size=(0, 0), center="auto"),
        lambda: api.crop(frames, size=(-5, 5), center="auto"),
        lambda: api.crop(frames, size="6x6", center="auto"),
        lambda: api.crop(frames, size=(6, 6), center=(1, 2, 3)),
        lambda: api.counts(frames, trial=5),
        lambda: api.counts(frames, trial="no such trial"),
        lambda: api.events_of(recordings, 5),
        lambda: api.Rotate(float("nan"), 30),
        lambda: api.Resize(float("inf")),
        lambda: api.FrameShift(1.5),
        lambda: api.EventShift(1, "x"),
        lambda: api.import_camera(str(tmp_path / "x.csv"), sensor=(240,)),
        lambda: api.import_camera(str(tmp_path / "x.csv"), sensor=(70_000, 70_000)),
        lambda: api.tonic_sensor_size(None),
    ]
    for call in calls:  # each raises the library's error with its message, not another exception
        with pytest.raises(NeurotacError):
            call()
    events = api.events_of(recordings, recordings.column("trial")[0].as_py())
    tonic = api.to_tonic(events)
    tonic["x"][0] = 300  # beyond the 240-pixel-wide sensor
    with pytest.raises(NeurotacError, match="outside"):
        api.from_tonic(tonic, api.tonic_sensor_size(events))


def test_sync_pairs_a_camera_file_with_its_force_log(tmp_path):
    import subprocess

    from neurotac_cli import api, schema as sch
    from neurotac_cli.errors import NeurotacError

    done = subprocess.run(["neurotac", "simulate", "--preset", "ch4", "--trials", "1", "--seed", "4", "--out", str(tmp_path)],
                          capture_output=True)
    assert done.returncode == 0, done.stderr
    camera = next(tmp_path.glob("steel-*.aedat"))
    recordings = api.sync(str(camera), str(camera.with_name(camera.stem + "_force.csv")))
    assert sch.kind_of(recordings.schema) == "recordings" and recordings.num_rows == 1
    with pytest.raises(NeurotacError, match="labels must be a dict"):
        api.sync(str(camera), str(camera.with_name(camera.stem + "_force.csv")), labels=["material=foam"])
