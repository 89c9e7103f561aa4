import pathlib
import subprocess
import sys

import numpy as np
import pytest

from neurotac_cli import schema as sch, tables

BOX = ["--size", "60x60", "--center", "120,90", "--pool", "4x4"]


def neurotac(*args, stdin=None):
    code = "from neurotac_cli.cli import main; main()"
    return subprocess.run([sys.executable, "-c", code, *args], stdin=stdin, capture_output=True, text=True, timeout=300)


def shell(command: str):
    code = f'{sys.executable} -c "from neurotac_cli.cli import main; main()"'
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command.replace("neurotac ", code + " ")], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """Two simulated ch4 grasps, their camera file, and a deform-gru trained on their frames for one epoch."""
    folder = tmp_path_factory.mktemp("sense")
    shell(f"neurotac simulate --preset ch4 --trials 2 --seed 3 --out {folder}/sim")
    shell(f"neurotac sync --manifest {folder}/sim/manifest.csv | neurotac frame --window 10ms "
          f"| neurotac crop {' '.join(BOX)} -o {folder}/frames.parquet")
    shell(f"neurotac train --model deform-gru --epochs 1 {folder}/frames.parquet -o {folder}/m.model")
    camera = sorted(pathlib.Path(folder, "sim").glob("*.aedat"))[0]
    return folder, camera


def test_sense_writes_the_rows_of_the_four_process_pipe(rig):
    folder, camera = rig
    shell(f"neurotac import {camera} | neurotac frame --window 10ms | neurotac crop {' '.join(BOX)} "
          f"| neurotac predict --model {folder}/m.model -o {folder}/pipe.arrows")
    done = neurotac("sense", str(camera), "--model", f"{folder}/m.model", "--window", "10ms", *BOX, "-o", f"{folder}/one.arrows")
    assert done.returncode == 0, done.stderr
    pipe, one = tables.read([f"{folder}/pipe.arrows"]), tables.read([f"{folder}/one.arrows"])
    assert one.num_rows == pipe.num_rows > 30
    assert one.column("trial").to_pylist() == pipe.column("trial").to_pylist()
    assert one.column("frame").to_pylist() == pipe.column("frame").to_pylist()
    np.testing.assert_allclose(one.column("force_pred").to_numpy(), pipe.column("force_pred").to_numpy(), atol=1e-6)
    assert "cut" in done.stderr  # what the box left out is counted, as crop counts it


def test_sense_reads_a_camera_on_stdin(rig):
    folder, camera = rig
    with open(camera, "rb") as source:  # decoded as its bytes arrive, as from a camera driver
        done = neurotac("sense", "-", "--model", f"{folder}/m.model", *BOX, "-o", f"{folder}/stdin.arrows", stdin=source)
    assert done.returncode == 0, done.stderr
    whole = neurotac("sense", str(camera), "--model", f"{folder}/m.model", *BOX, "-o", f"{folder}/file.arrows")
    assert whole.returncode == 0, whole.stderr
    a, b = tables.read([f"{folder}/stdin.arrows"]), tables.read([f"{folder}/file.arrows"])
    np.testing.assert_allclose(a.column("force_pred").to_numpy(), b.column("force_pred").to_numpy(), atol=1e-6)


@pytest.mark.parametrize("args, words", [
    (["--center", "auto", "--size", "60x60"], "--center auto needs the whole input"),
    (["--speed", "2"], "--speed sets the pace of a replay"),
    (["--center", "120,90"], "--center needs --size"),
])
def test_sense_refuses_what_cannot_stream_in_one_line(rig, args, words):
    folder, camera = rig
    done = neurotac("sense", str(camera), "--model", f"{folder}/m.model", *args)
    assert done.returncode == 2 and words in done.stderr and "Traceback" not in done.stderr


def test_sense_refuses_an_idle_timeout_without_follow(tmp_path):
    """It was ignored without a word: only a followed camera file is waited for."""
    done = neurotac("sense", str(tmp_path / "cam.raw"), "--model", str(tmp_path / "m.model"), "--idle-timeout", "2s")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "--idle-timeout ends a followed file once it stops growing: give it with --follow" in done.stderr


def test_sense_refuses_a_missing_model_in_one_line(rig, tmp_path):
    _, camera = rig
    done = neurotac("sense", str(camera), "--model", str(tmp_path / "none.model"), *BOX)
    assert done.returncode == 1 and len(done.stderr.strip().splitlines()) == 1


def test_sense_without_a_box_feeds_whole_frames_to_a_model_trained_on_them(rig):
    folder, camera = rig
    shell(f"neurotac sync --manifest {folder}/sim/manifest.csv | neurotac frame --window 10ms "
          f"| neurotac train --model tdnn --epochs 1 -o {folder}/whole.model")
    shell(f"neurotac import {camera} | neurotac frame --window 10ms | neurotac predict --model {folder}/whole.model -o {folder}/wpipe.arrows")
    done = neurotac("sense", str(camera), "--model", f"{folder}/whole.model", "-o", f"{folder}/wone.arrows")
    assert done.returncode == 0, done.stderr
    pipe, one = tables.read([f"{folder}/wpipe.arrows"]), tables.read([f"{folder}/wone.arrows"])
    np.testing.assert_allclose(one.column("force_pred").to_numpy(), pipe.column("force_pred").to_numpy(), atol=1e-6)


def test_sense_tells_its_own_options_when_the_box_differs_from_the_training_frames(rig):
    folder, camera = rig
    done = neurotac("sense", str(camera), "--model", f"{folder}/m.model", "--size", "40x40", "--center", "120,90", "--pool", "4x4")
    assert done.returncode == 1 and "give `sense` the training's --window" in done.stderr and "neurotac crop" not in done.stderr


def test_sense_s_framing_errors_offer_no_option_sense_lacks():
    from neurotac_cli.errors import NeurotacError
    from neurotac_cli.ops import frame as fr

    t = np.array([0, 5_000, 12_000, 10**12])
    events = sch.events_table(t, np.zeros(4, int), np.zeros(4, int), np.zeros(4, int), 8, 8)
    schema, batches = fr.frame_events(events.schema, events.to_batches(max_chunksize=1),
                                      fr.Framing(window_us=10_000, frame_options=False), fr.FramingReport())
    with pytest.raises(NeurotacError) as caught:
        list(batches)
    assert "--max-frames" not in str(caught.value) and "a gap of" in str(caught.value)
    back = sch.events_table(np.array([0, 50_000, 10_000]), np.zeros(3, int), np.zeros(3, int), np.zeros(3, int), 8, 8)
    schema, batches = fr.frame_events(back.schema, back.to_batches(max_chunksize=1),
                                      fr.Framing(window_us=10_000, frame_options=False), fr.FramingReport())
    with pytest.raises(NeurotacError) as caught:
        list(batches)
    assert "with --sort" not in str(caught.value) and "`neurotac frame --sort`" in str(caught.value)


def test_sense_refuses_a_pooling_the_model_was_not_trained_on_as_predict_does(rig, tmp_path):
    """A box half the size pooled half as much makes frames of the training's shape: the pipe's
    `predict` read the pooling from the frames' history and refused them, `sense` ran on."""
    folder, camera = rig
    shell(f"neurotac simulate --preset ch4 --trials 1 --seed 4 --synced | neurotac frame --window 10ms "
          f"| neurotac crop --size 116x116 --center 120,90 --pool 4x4 -o {tmp_path}/pooled.parquet")
    shell(f"neurotac train --model deform-gru --epochs 1 {tmp_path}/pooled.parquet -o {tmp_path}/pooled.model")
    done = neurotac("sense", str(camera), "--model", f"{tmp_path}/pooled.model", "--size", "58x58", "--center", "120,90", "--pool", "2x2")
    assert done.returncode == 1 and "(different pooling)" in done.stderr and done.stderr.count("\n") == 1, done.stderr
    same = neurotac("sense", str(camera), "--model", f"{tmp_path}/pooled.model", "--size", "116x116", "--center", "120,90", "--pool", "4x4",
                    "-o", f"{tmp_path}/p.arrows")
    assert same.returncode == 0, same.stderr


def test_sense_on_a_camera_file_cut_before_its_first_event_says_what_was_left_out(rig, tmp_path):
    """It said only that the events table was empty; `import` of the same file said that a record
    was cut short."""
    folder, camera = rig
    data = camera.read_bytes()
    header = 0
    while data.startswith(b"#", header):  # AEDAT 2.0's header: lines that begin with '#'
        header = data.index(b"\n", header) + 1
    cut = tmp_path / "cut.aedat"
    cut.write_bytes(data[:header + 5])  # the header and five bytes of an 8-byte event
    done = neurotac("sense", str(cut), "--model", f"{folder}/m.model", *BOX, "-o", str(tmp_path / "out.arrows"))
    lines = done.stderr.splitlines()
    assert done.returncode == 1 and len(lines) == 1, done.stderr
    assert "cut.aedat: no events in the camera input" in lines[0] and "cut short" in lines[0], lines
    # another error before the first window is itself, not "no events"
    done = neurotac("sense", str(camera), "--model", f"{folder}/m.model", *BOX, "-o", str(tmp_path / "missing" / "out.arrows"))
    assert done.returncode == 1 and "does not exist" in done.stderr and "no events" not in done.stderr, done.stderr


def test_sense_says_where_the_size_it_refuses_is_only_the_extent_of_the_events(rig, tmp_path):
    """A DAT file without its geometry: the sensor is the events' extent, a guess the errors about
    sizes did not name."""
    folder, _ = rig
    rng = np.random.default_rng(0)
    x, y = rng.integers(0, 54, 2000), rng.integers(0, 61, 2000)
    words = np.stack([np.sort(rng.integers(0, 100_000, 2000)), (1 << 28) | (y << 14) | x], axis=1).astype("<u4")
    camera = tmp_path / "c.dat"
    camera.write_bytes(b"% Data file containing CD events.\n% Version 2\n" + bytes([0x0C, 8]) + words.tobytes())
    for args in ([], ["--pool", "4x4"]):  # whole frames against the model's; a pool of the whole sensor
        done = neurotac("sense", str(camera), "--model", f"{folder}/m.model", *args, "-o", str(tmp_path / "out.arrows"))
        lines = done.stderr.splitlines()
        assert done.returncode == 1 and len(lines) == 1, done.stderr
        assert "54x61 is the extent of the events" in lines[0] and "--sensor WxH" in lines[0], lines
