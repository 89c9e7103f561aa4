"""`neurotac render`: every view and picture format is written, readable, and of the size it says."""

import pathlib
import subprocess

import numpy as np
import pyarrow as pa
import pytest
from click.testing import CliRunner
from PIL import Image

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.ops.augment import augment_frames
from neurotac_cli.ops.crop import CropSpec
from neurotac_cli.rendering import RenderSpec, render, rgb


def frames_table(trials=("a", "b"), n=6, height=16, width=20):
    rng = np.random.default_rng(0)
    counts = rng.poisson(0.3, (len(trials) * n, 2, height, width)).astype(np.uint16)
    schema = sch.frames_schema(height, width, window_us=10_000)
    columns = {
        "trial": pa.array([t for t in trials for _ in range(n)]),
        "frame": pa.array(np.tile(np.arange(n, dtype=np.int32), len(trials))),
        "t": pa.array(np.tile(np.arange(n) * 10_000, len(trials))),
        "counts": sch.counts_array(counts),
        "force": pa.array(np.tile(np.linspace(0, 2, n), len(trials)).astype(np.float32)),
        "phase": pa.array(["grasping", "holding", "holding", "holding", "releasing", None] * len(trials)),
    }
    return pa.Table.from_pydict(columns, schema=schema)


def events_table(n=500):
    rng = np.random.default_rng(1)
    t = np.sort(rng.integers(0, 100_000, n))
    return sch.events_table(t, rng.integers(0, 20, n), rng.integers(0, 16, n), rng.integers(0, 2, n), width=20, height=16)


def write_input(tmp_path, table, name="in.arrows"):
    path = str(tmp_path / name)
    tables.write(path, table)
    return path


def run(*args):
    return CliRunner().invoke(cli, ["render", *args])


def test_png_montage_of_frames_is_the_size_it_reports(tmp_path):
    done = render(frames_table(), str(tmp_path / "m.png"), RenderSpec(columns=3))
    with Image.open(tmp_path / "m.png") as image:
        assert image.format == "PNG"
        assert image.size == (done["width"], done["height"])
    assert (done["trial"], done["pictures"]) == ("a", 1)


def test_gif_of_events_has_one_picture_per_slice(tmp_path):
    path = write_input(tmp_path, events_table())
    result = run(path, "--slices", "5", "-o", str(tmp_path / "e.gif"))
    assert result.exit_code == 0, result.output
    with Image.open(tmp_path / "e.gif") as image:
        assert (image.format, image.n_frames) == ("GIF", 5)
    assert "5 pictures" in result.output


def test_mp4_of_every_second_frame_has_those_frames_in_whole_macro_blocks(tmp_path):
    import imageio_ffmpeg

    done = render(frames_table(), str(tmp_path / "m.mp4"), RenderSpec(trial="b", every=2, fps=5))
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "m.mp4"))
    assert (frames, done["pictures"]) == (3, 3)
    assert seconds == pytest.approx(0.6, abs=0.05)
    assert done["width"] % 16 == 0 and done["height"] % 16 == 0


def test_slices_of_a_recording_hold_every_event_of_the_trial(tmp_path):
    from neurotac_cli.rendering import steps_of

    rng = np.random.default_rng(2)
    t = np.sort(rng.integers(-5_000, 80_000, 300))
    recordings = sch.recordings_table([{"trial": "r1", "t0": 0, "events": (t, rng.integers(0, 20, 300), rng.integers(0, 16, 300),
                                        rng.integers(0, 2, 300)), "force": (np.arange(0, 80_000, 2_000), np.ones(40))}],
                                      width=20, height=16)
    steps = steps_of(recordings, "r1", RenderSpec(slices=7))
    assert steps.counts.shape == (7, 2, 16, 20) and steps.counts.sum() == 300
    render(recordings, str(tmp_path / "r.png"), RenderSpec(slices=7))


def test_crop_view_draws_the_box_and_needs_one(tmp_path):
    spec = RenderSpec(view="crop", crop=CropSpec(size=(8, 8), center="auto"))
    done = render(frames_table(), str(tmp_path / "c.png"), spec)
    assert done["view"] == "crop"
    result = run(write_input(tmp_path, frames_table()), "--view", "crop", "-o", str(tmp_path / "c2.png"))
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == ["neurotac render: error: the crop view needs the box: --box X,Y,W,H, "
                                                  "or --size WxH with --center X,Y|auto"]


def test_augmented_view_puts_a_copy_under_its_source(tmp_path):
    from neurotac_cli.ops.augment import FrameShift

    augmented, _ = augment_frames(frames_table(), [FrameShift(1)])
    done = render(augmented, str(tmp_path / "a.gif"), RenderSpec(view="augmented", trial="b"))
    assert done["trial"].startswith("b~") and done["pictures"] == 6


def test_refusals_are_one_line(tmp_path):
    path = write_input(tmp_path, frames_table())
    for args, words, code in [(["-o", str(tmp_path / "x.jpg")], "use .png, .gif or .mp4", 2),
                               (["--trial", "zz", "-o", str(tmp_path / "x.png")], "no trial 'zz'", 1),
                               (["--view", "augmented", "-o", str(tmp_path / "x.png")], "from `neurotac augment`", 1)]:
        result = run(path, *args)
        assert result.exit_code == code and words in result.output and len(result.output.strip().splitlines()) == 1
    assert not list(tmp_path.glob("x.*"))


def test_slices_of_a_frames_table_are_a_usage_error_not_ignored(tmp_path):
    path = write_input(tmp_path, frames_table())
    for args, named in ((["--slices", "4"], "--slices cuts"), (["--slice", "50ms"], "--slice cuts")):
        result = run(path, *args, "-o", str(tmp_path / "x.png"))
        assert result.exit_code == 2 and named in result.output, result.output
    assert not list(tmp_path.glob("x.*"))
    assert run(write_input(tmp_path, events_table(), "e.arrows"), "--slices", "4", "-o", str(tmp_path / "e.png")).exit_code == 0


def test_colours_are_white_for_nothing_red_for_on_blue_for_off():
    counts = np.zeros((2, 1, 3))
    counts[1, 0, 1] = 4  # ON
    counts[0, 0, 2] = 4  # OFF
    image = rgb(counts, top=4)
    assert image[0, 0].tolist() == [1, 1, 1]
    assert image[0, 1].tolist() == [1, 0, 0]
    assert image[0, 2].tolist() == [0, 0, 1]


def test_crop_view_takes_the_centre_found_automatically_from_the_command_line(tmp_path):
    """As docs/seeing.md runs it: `render --view crop --size WxH --center auto`."""
    result = run(write_input(tmp_path, frames_table()), "--view", "crop", "--size", "8x8", "--center", "auto",
                 "-o", str(tmp_path / "c.png"))
    assert result.exit_code == 0, result.output
    assert (tmp_path / "c.png").stat().st_size > 0


def test_the_crop_view_titles_the_centre_of_the_box_it_draws_where_the_found_one_was_moved():
    from neurotac_cli.ops.crop import CropSpec
    from neurotac_cli.rendering import Steps, crop_box

    counts = np.zeros((1, 2, 16, 20), dtype=np.uint16)
    counts[0, 0, 1:3, 1:3] = 50  # the contact in a corner: an 8x8 box about it must move to fit
    table = pa.Table.from_pydict({"trial": ["a"], "frame": pa.array([0], pa.int32()), "t": [0], "counts": sch.counts_array(counts),
                                  "force": pa.array([1.0], pa.float32()), "phase": ["holding"]},
                                 schema=sch.frames_schema(16, 20, window_us=10_000))
    steps = Steps(trial="a", counts=counts, starts_ms=np.zeros(1), step_ms=10.0, what="frame")
    box, how = crop_box(table, steps, CropSpec(size=(8, 8), center="auto"))
    assert box[:2] == (0, 0) and how.startswith("centre 4,4 (auto, moved from ")


def test_every_command_on_the_seeing_page_runs_and_draws_its_picture(tmp_path):
    """docs/seeing.md's pictures come from its own commands: run them, writing the pictures here."""
    import re
    import subprocess

    page = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "seeing.md").read_text()
    blocks = re.findall(r"```bash\n(.*?)```", page, re.S)
    script = "".join(blocks).replace("docs/img/", "img/")
    pictures = re.findall(r"img/(render_\w+\.\w+)", script)
    (tmp_path / "img").mkdir()
    done = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert len(pictures) >= 5 and all((tmp_path / "img" / name).stat().st_size > 0 for name in pictures)


def test_tiles_a_png_cannot_hold_are_counted_not_dropped_silently(tmp_path, monkeypatch):
    from neurotac_cli import rendering

    monkeypatch.setattr(rendering, "MAX_TILES", 4)
    assert render(frames_table(), str(tmp_path / "m.png"), RenderSpec(trial="a"))["left_out"] == 2
    assert render(frames_table(), str(tmp_path / "m.gif"), RenderSpec(trial="a", fps=50))["left_out"] == 0


def test_an_animation_shows_its_progress_on_stderr(tmp_path):
    path = write_input(tmp_path, events_table())
    result = CliRunner().invoke(cli, ["render", path, "--slices", "7", "-o", str(tmp_path / "e.gif")],
                                env={"NEUROTAC_PROGRESS": "1"})
    assert result.exit_code == 0, result.output
    assert "gif pictures: 7/7 done" in result.output


def test_an_animation_is_laid_out_once_not_once_a_picture(tmp_path, monkeypatch):
    """Laying the figure out again for every picture made a thousand slices take minutes."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    layouts = []
    execute = ConstrainedLayoutEngine.execute
    monkeypatch.setattr(ConstrainedLayoutEngine, "execute", lambda self, figure: layouts.append(1) or execute(self, figure))
    done = render(events_table(), str(tmp_path / "e.mp4"), RenderSpec(slices=20))
    assert (done["pictures"], len(layouts)) == (20, 1)


def test_an_mp4_the_disk_cannot_hold_is_one_line_and_keeps_the_old_video(tmp_path):
    # ffmpeg's failure (here a file-size limit) was not looked at: exit 0, "wrote", a cut video
    path = write_input(tmp_path, frames_table())
    (tmp_path / "x.mp4").write_bytes(b"old video")
    done = subprocess.run(["bash", "-c", f"ulimit -f 2; neurotac render {path} -o x.mp4"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 1, done.stderr
    assert done.stderr.count("\n") == 1 and "neurotac render: error: cannot write x.mp4" in done.stderr
    assert "previous file is kept" in done.stderr
    assert (tmp_path / "x.mp4").read_bytes() == b"old video"
    assert not list(tmp_path.glob(".neurotac-*"))


def test_an_unwritable_matplotlib_config_folder_leaves_stderr_to_our_own_line(tmp_path):
    # matplotlib said so in two paragraphs of warnings, though it works on with a temporary folder
    import os

    path = write_input(tmp_path, frames_table())
    blocked = tmp_path / "not-a-folder"
    blocked.write_text("")
    env = dict(os.environ, HOME=str(blocked), MPLCONFIGDIR=str(blocked / "mpl"))
    done = subprocess.run(["neurotac", "render", path, "-o", "m.png"], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0 and done.stderr.startswith("neurotac render: wrote m.png") and done.stderr.count("\n") == 1, done.stderr


def test_a_tile_smaller_than_the_sensor_keeps_every_isolated_event():
    """Nearest-neighbour shrinking skipped whole rows and columns: a 240x180 sensor in a 150 px tile lost
    half of 690 isolated events."""
    from neurotac_cli.model.plots import pyplot
    from neurotac_cli.rendering import _image_axis

    counts = np.zeros((2, 180, 240))
    counts[1, 3::8, 3::8] = 1
    figure, axis = pyplot().subplots(figsize=(1.5, 1.2), dpi=100)
    _image_axis(axis, rgb(counts, 1.0), "")
    shown = axis.images[0].get_array()
    assert shown.shape[1] < 240 and (shown.min(axis=2) < 0.5).sum() == counts[1].sum() == 690
    assert axis.get_xlim() == (-0.5, 239.5) and axis.get_ylim() == (179.5, -0.5)
    pyplot().close(figure)


def test_a_span_of_a_few_microseconds_is_cut_into_no_more_slices_than_it_holds():
    from neurotac_cli.rendering import steps_of

    one = sch.events_table(np.array([5]), np.array([3]), np.array([4]), np.array([1]), width=20, height=16)
    steps = steps_of(one, None, RenderSpec(slices=8))
    assert len(steps.counts) == 1 and steps.caption(0) == "0.000-0.001 ms"


def test_every_picture_of_an_animation_keeps_its_isolated_event():
    """The pictures after the first are set by the animation's update: they are pooled as the first."""
    from neurotac_cli import rendering as rd

    positions = [(101 + 7 * i, 333 + 11 * i) for i in range(6)]
    counts = np.zeros((len(positions), 2, 720, 1280), np.uint16)
    for k, (y, x) in enumerate(positions):
        counts[k, 1, y, x] = 5
    steps = rd.Steps("t", counts, np.arange(len(positions)) * 10.0, 10.0, "frame", np.arange(len(positions)))
    figure, update, _, _ = rd.montage(steps, RenderSpec(), animated=True)
    axis = figure.axes[0]
    for k in range(len(positions)):
        update(k)
        figure.canvas.draw()
        pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3].astype(int)
        box = axis.get_window_extent()
        inside = pixels[int(pixels.shape[0] - box.y1) + 2:int(pixels.shape[0] - box.y0) - 2, int(box.x0) + 2:int(box.x1) - 2]
        assert (inside.min(axis=-1) < 200).any(), k


def test_a_block_of_on_and_off_pixels_shows_one_of_them_in_its_own_colour():
    """A darkest value per colour mixed a block's ON and OFF pixels into a grey no pixel has."""
    from neurotac_cli.model.plots import pyplot
    from neurotac_cli.rendering import _image_axis

    counts = np.zeros((2, 180, 240))
    counts[1, 0::4, 0::4] = 1  # ON
    counts[0, 1::4, 1::4] = 1  # OFF, beside each ON pixel
    figure, axis = pyplot().subplots(figsize=(1.5, 1.2), dpi=100)
    image = rgb(counts, 1.0)
    _image_axis(axis, image, "")
    shown = axis.images[0].get_array().reshape(-1, 3)
    pure = {tuple(image[0, 0]), tuple(image[1, 1])}
    assert {tuple(pixel) for pixel in shown} <= pure | {(1.0, 1.0, 1.0)} and len(pure) == 2
    pyplot().close(figure)


def test_the_commands_and_the_librarys_options_are_the_renderers():
    # the command and api.render state them themselves, so that they start without importing the renderer (matplotlib)
    from neurotac_cli import rendering
    from neurotac_cli.commands.render import command

    params = {p.name: p for p in command.params}
    assert (params["slices"].type.max, params["columns"].type.max) == (rendering.MAX_SLICES, rendering.MAX_COLUMNS)
    assert (params["fps"].type.min, params["fps"].type.max) == rendering.FPS
    assert tuple(params["view"].type.choices) == rendering.VIEWS
    import inspect

    from neurotac_cli import api

    spec, given = rendering.RenderSpec(), inspect.signature(api.render).parameters
    for name in ("view", "columns", "every"):
        assert params[name].default == given[name].default == getattr(spec, name), name
    assert params["slices"].default == spec.slices and params["fps"].default == spec.fps  # api: None, the spec's
