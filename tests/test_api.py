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
        lambda: api.crop(frames, size="6by6", center="auto"),
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


@pytest.fixture(scope="module")
def small():
    """One simulated trial: its recordings, small frames of it and a one-epoch model of them."""
    from neurotac_cli import api

    recordings = api.simulate("ch4", trials=1, seed=1)
    frames = api.crop(api.frame(recordings, "10ms"), size=(30, 30), center="auto", pool=(3, 3))
    return recordings, frames, api.train(frames, "tdnn", epochs=1, val_fraction=None)


def test_a_trial_given_twice_or_no_rows_is_refused_as_the_command_line_refuses_it(small, tmp_path):
    import pyarrow as pa

    from neurotac_cli import api
    from neurotac_cli.errors import InputError, SchemaError

    recordings, frames, model = small
    api.write(frames, str(tmp_path / "f.arrows"))
    for call in (lambda: api.counts(pa.concat_tables([frames, frames])), lambda: api.evaluate(model, pa.concat_tables([frames, frames])),
                 lambda: api.crop(api.read(str(tmp_path / "f.arrows"), str(tmp_path / "f.arrows")), pool="all")):
        with pytest.raises(SchemaError, match="appears twice"):
            call()
    for call in (lambda: api.frame(recordings.slice(0, 0), "10ms"), lambda: api.crop(frames.slice(0, 0), pool="all"),
                 lambda: api.evaluate(model, frames.slice(0, 0))):
        with pytest.raises(InputError, match="has no rows"):
            call()


def test_the_command_lines_warnings_reach_the_library_as_neurotac_warnings(small):
    from neurotac_cli import api
    from neurotac_cli.errors import NeurotacWarning

    recordings, frames, _ = small
    with pytest.warns(NeurotacWarning, match="fs pushed"):
        api.augment(frames, api.FrameShift(1000))
    with pytest.warns(NeurotacWarning, match="lie outside the frames"):
        api.frame(recordings, "10ms", pad_to=2)
    huge = recordings.replace_schema_metadata({**recordings.schema.metadata, b"neurotac:sensor": b'{"width": 20000, "height": 20000}'})
    import warnings

    with warnings.catch_warnings():  # as an error: raised before the frames are made, not after 60 GB
        warnings.simplefilter("error", NeurotacWarning)
        with pytest.raises(NeurotacWarning, match="GB"):
            api.frame(huge, "10ms")


def test_the_stepper_checks_its_times(small):
    import numpy as np

    from neurotac_cli import api
    from neurotac_cli.errors import UsageError

    _, frames, model = small
    counts, t = api.counts(frames)[:3], frames["t"].to_numpy()[:3]
    stepper = api.Stepper(model)
    for args in ((counts, t[:2]), (counts[0], None), (counts[0], "10ms"), (counts[:0], t[:0]), (counts, t.astype(float))):
        with pytest.raises(UsageError):
            stepper.step(*args)
    assert stepper.step(counts, t).shape == (3,) and np.isfinite(stepper.step(counts[0], int(t[0])))


def test_odd_paths_strings_and_flags_are_refused_in_one_line(small, tmp_path, monkeypatch):
    from neurotac_cli import api
    from neurotac_cli.errors import InputError, UsageError

    recordings, frames, model = small
    picture = str(tmp_path / "x.png")
    calls = [lambda: api.train(frames, "tdnn", epochs=1, val_fraction="0.1"), lambda: api.save_model(model, None),
             lambda: api.save_model(model, str(tmp_path)), lambda: api.load_model(None), lambda: api.render(frames, None),
             lambda: api.render(frames, picture, every="2"), lambda: api.render(recordings, picture, slice_us=True),
             lambda: api.render(frames, picture, slices=3), lambda: api.render(frames, picture, fps=3),
             lambda: api.render(frames, picture, columns=1000), lambda: api.render(recordings, picture, slices=5000),
             lambda: api.render(frames, picture, size="6x6", center="auto"), lambda: api.read(),
             lambda: api.import_camera(None), lambda: api.read(picture, kind="bogus"), lambda: api.frame(recordings, True),
             lambda: api.evaluate(model, frames, nonzero="no"), lambda: api.frame(recordings, "10ms", accumulate=1)]
    for call in calls:
        with pytest.raises(UsageError):
            call()
    (tmp_path / "p.csv").write_text("trial,force\n")
    from neurotac_cli import tables

    opened = []
    original = tables.open_binary
    monkeypatch.setattr(tables, "open_binary", lambda path: opened.append(original(path)) or opened[-1])
    with pytest.raises(InputError, match="not an Arrow"):
        api.read(str(tmp_path / "p.csv"))
    assert opened and all(handle.closed for handle in opened)  # a file refused by its first bytes is closed


def test_numpy_numbers_and_the_command_lines_text_are_taken_alike(small):
    import numpy as np

    from neurotac_cli import api

    recordings, frames, _ = small
    by_tuple = api.crop(frames, size=(6, 6), center=(5, 5), pool=(2, 2))
    for size, center, pool in ((np.array([6, 6]), np.array([5, 5]), np.array([2, 2])), ("6x6", "5,5", "2x2")):
        assert api.crop(frames, size=size, center=center, pool=pool).equals(by_tuple)
    assert api.train(frames, "tdnn", epochs=np.int64(1), lr=np.float32(1e-3), val_fraction=None).name == "tdnn"


def test_render_takes_the_crop_box_as_crop_does(small, tmp_path):
    from neurotac_cli import api

    _, frames, _ = small
    assert api.render(frames, str(tmp_path / "c.png"), view="crop", size="6x6", center="auto")["view"] == "crop"


def test_tonic_arrays_keep_every_coordinate_of_a_16_bit_sensor():
    import numpy as np

    from neurotac_cli import api
    from neurotac_cli.errors import NeurotacError, UsageError

    events = np.zeros(3, np.dtype([("x", np.int32), ("y", np.int32), ("t", np.int64), ("p", np.int8)]))
    events["x"], events["t"] = [0, 40000, 5], [0, 1, 2]
    assert api.to_tonic(api.from_tonic(events, (50000, 10, 2)))["x"].tolist() == [0, 40000, 5]
    assert api.from_tonic(events, "50000x10").num_rows == 3
    for sensor in ((100000, 10, 2), (-5, -5, 2), None, "240x180"):
        with pytest.raises(UsageError if sensor != "240x180" else NeurotacError):
            api.from_tonic(events, sensor)


@pytest.mark.parametrize("kind, args", [("FrameShift", (0,)), ("EventShift", (0, 0.5)), ("EventShift", (-2, 0.0)), ("Resize", (1.0,)),
                                        ("Rotate", (360,))])
def test_a_method_that_changes_nothing_is_refused_as_the_command_refuses_it(kind, args):
    from neurotac_cli import api
    from neurotac_cli.errors import UsageError
    from tests.model.helpers import tiny_frames

    method = getattr(api, kind)(*args)

    with pytest.raises(UsageError, match="changes nothing"):
        api.augment(tiny_frames(trials=2), method)
    assert api.augment(tiny_frames(trials=2), method, api.FrameShift(1), combine="hybrid").num_rows > 0


def test_the_warnings_train_and_eval_give_about_their_frames_reach_the_library():
    import warnings

    import pyarrow.compute as pc

    from neurotac_cli import api, schema as sch
    from neurotac_cli.errors import NeurotacWarning
    from tests.model.helpers import tiny_frames

    frames = tiny_frames(trials=4)
    frames = frames.replace_schema_metadata({k: v for k, v in frames.schema.metadata.items() if k.decode() != sch.WINDOW})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NeurotacWarning)
        model = api.train(frames, "tdnn", epochs=1, val_fraction=None)
        api.evaluate(model, frames.filter(pc.not_equal(frames.column("frame"), 3)))
    said = [str(w.message) for w in caught if issubclass(w.category, NeurotacWarning)]
    assert any(m.startswith("the frames do not record their window") for m in said), said
    assert any("missing inside" in m for m in said), said


def test_frame_refuses_for_a_table_s_kind_what_the_command_refuses(small):
    """`--phases session` on plain events was refused by the command and framed by the library."""
    from neurotac_cli import api
    from neurotac_cli.errors import UsageError

    recordings, _, _ = small
    events = api.events_of(recordings, recordings["trial"][0].as_py())
    with pytest.raises(UsageError, match="--phases session reads each grasp from the force log"):
        api.frame(events, "10ms", phases="session")
    with pytest.raises(UsageError, match="--zero rest reads the force log's rest level"):
        api.frame(events, "10ms", zero="rest")
    with pytest.raises(UsageError, match="trial is for plain events tables"):
        api.frame(recordings, "10ms", trial="x")
