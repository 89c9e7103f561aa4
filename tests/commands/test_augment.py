"""`neurotac augment` as a user runs it: options, errors, history, bytes."""

import re
import subprocess

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch
from neurotac_cli.cli import cli
from tests.ops.test_augment import make_frames


@pytest.fixture
def frames_file(tmp_path):
    path = tmp_path / "frames.parquet"
    pq.write_table(make_frames(), path)
    return path


def run(*args):
    return CliRunner().invoke(cli, ["augment", *map(str, args)], catch_exceptions=False)


def read(path) -> pa.Table:
    return pq.read_table(path)


def test_negative_shifts_parse_and_copies_are_written(frames_file, tmp_path):
    out = tmp_path / "out.parquet"
    done = run("--tes", -2, 0.5, "--copies", 2, "-o", out, frames_file)
    assert done.exit_code == 0, done.output
    table = read(out)
    assert sorted(set(table["augment"].to_pylist())) == ["", "tes(-2,0.5)#1", "tes(-2,0.5)#2"]
    history = sch.get_meta(table.schema, sch.HISTORY)
    step = history[-1]
    assert step["command"] == "augment" and step["args"]["tes"] == [-2, 0.5]
    counted = step["args"]["counted"]["tes"]
    assert counted["copies"] == 6 and counted["events_moved"] > 0 and "events_lost" in counted


def test_same_seed_writes_the_same_bytes(frames_file, tmp_path):
    outputs = []
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        out = tmp_path / f"{name}.arrows"
        assert run("--rotate-range", 0, 45, "--tes", -2, 0.5, "--seed", seed, "-o", out, frames_file).exit_code == 0
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1] and outputs[0] != outputs[2]


def test_noise_file_of_another_size_is_a_clear_error(frames_file, tmp_path):
    noise = tmp_path / "still.parquet"
    pq.write_table(make_frames(trials=1, height=8, width=8), noise)
    done = CliRunner().invoke(cli, ["augment", "--noise", str(noise), str(frames_file)])
    assert done.exit_code == 1
    assert "noise frames are 8x8" in done.output and "Traceback" not in done.output


def test_noise_file_adds_copies(frames_file, tmp_path):
    noise, out = tmp_path / "still.parquet", tmp_path / "out.parquet"
    pq.write_table(make_frames(trials=1, frames=30, seed=3), noise)
    assert run("--noise", noise, "--only-augmented", "-o", out, frames_file).exit_code == 0
    assert set(read(out)["augment"].to_pylist()) == {"noise#1"}


@pytest.mark.parametrize(
    "args, message",
    [
        ([], "give at least one"),
        (["--tes", "1", "1.5"], "1.5"),
        (["--resize", "0"], "0"),
        (["--rotate", "10", "--rotate-range", "0", "45"], "not both"),
        (["--rotate-range", "45", "0"], "smaller angle first"),
        (["--copies", "0", "--fs", "1"], "0"),
    ],
)
def test_bad_options_exit_2(frames_file, args, message):
    done = CliRunner().invoke(cli, ["augment", *args, str(frames_file)])
    assert done.exit_code == 2 and message in done.output


def test_losing_many_events_past_the_ends_is_warned_about(frames_file, tmp_path):
    done = CliRunner().invoke(cli, ["augment", "--fs", "4", "-o", str(tmp_path / "o.parquet"), str(frames_file)])
    assert done.exit_code == 0 and "warning: fs pushed" in done.output


def test_wrong_kind_is_refused(tmp_path):
    events = tmp_path / "events.parquet"
    pq.write_table(sch.events_table([0, 1], [1, 2], [1, 2], [0, 1]), events)
    done = CliRunner().invoke(cli, ["augment", "--fs", "1", str(events)])
    assert done.exit_code == 1 and "frame --window" in done.output


def test_in_a_real_pipe(frames_file):
    command = f"neurotac augment --fs -1 --tes -2 0.5 --copies 2 {frames_file} | neurotac augment --rotate 10 --only-augmented"
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command + " | cat > /dev/null"], capture_output=True)
    assert done.returncode == 0 and b"error" not in done.stderr
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True)
    table = pa.ipc.open_stream(done.stdout).read_all()
    assert table.num_rows == 3 * 8 * 5
    assert set(table["source_trial"].to_pylist()) == {"bolt0", "bolt1", "bolt2"}
    assert np.all(sch.counts_numpy(table["counts"]) >= 0)


@pytest.mark.slow
def test_the_chapter_5_pipe_from_simulator_to_info():
    import importlib.util

    missing = [c for c in ("simulate", "frame", "crop", "info") if importlib.util.find_spec(f"neurotac_cli.commands.{c}") is None]
    if missing:
        pytest.skip(f"neurotac {', '.join(missing)} not built yet")
    command = (
        "neurotac simulate --preset ch5 --trials 3 --synced | neurotac frame --window 10ms "
        "| neurotac crop --size 140x150 --center auto --pool 2x2 | neurotac augment --tes -2 0.5 --copies 2 "
        "| neurotac info -"
    )
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert re.search(r"trials\s+9\n", done.stdout) and "2x75x70" in done.stdout
