"""`neurotac simulate` end to end: the rig's files, the synced table, same seed same bytes, user errors."""

import csv
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

from neurotac_cli.cli import cli
from neurotac_cli.io.writers import aedat2_bytes, write_aedat2

SMALL = ["--preset", "ch4", "--trials", "2", "--set", "hold_us=40ms", "--set", "max_duration_us=0us"]


def decode_aedat2(data: bytes, height=180):
    """A tiny independent AEDAT 2.0 decoder: skip `#` lines, big-endian (address, timestamp) pairs."""
    offset = 0
    while data[offset:offset + 1] == b"#":
        offset = data.index(b"\n", offset) + 1
    words = np.frombuffer(data[offset:], dtype=">u4").reshape(-1, 2)
    address, t = words[:, 0].astype(np.int64), words[:, 1].astype(np.int64)
    return t, (address >> 12) & 0x3FF, height - 1 - ((address >> 22) & 0x1FF), (address >> 11) & 1


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sim")
    done = subprocess.run(["neurotac", "simulate", *SMALL, "--seed", "7", "--out", str(folder)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    assert done.stderr == b"" and done.stdout == b""  # no progress off a terminal, no data on stdout
    return folder


def test_aedat2_writer_round_trips_through_an_independent_decoder(tmp_path):
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, 2**32 - 1, 500))
    x, y, p = rng.integers(0, 240, 500), rng.integers(0, 180, 500), rng.integers(0, 2, 500)
    write_aedat2(tmp_path / "a.aedat", t, x, y, p)
    data = (tmp_path / "a.aedat").read_bytes()
    assert data.startswith(b"#!AER-DAT2.0\r\n")
    for got, want in zip(decode_aedat2(data), (t, x, y, p)):
        np.testing.assert_array_equal(got, want)
    assert aedat2_bytes(t, x, y, p) == data


def test_aedat2_writer_refuses_what_the_format_cannot_hold():
    from neurotac_cli.errors import NeurotacError

    with pytest.raises(NeurotacError, match="outside"):
        aedat2_bytes([0], [240], [0], [1])
    with pytest.raises(NeurotacError, match="32-bit"):
        aedat2_bytes([2**32], [0], [0], [1])
    with pytest.raises(NeurotacError, match="time order"):
        aedat2_bytes([5, 4], [0, 0], [0, 0], [1, 1])


def test_out_writes_camera_files_force_logs_still_and_manifest(dataset):
    with open(dataset / "manifest.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2
    assert list(rows[0])[:7] == ["trial", "events", "force", "material", "object", "size_mm", "true_t0_us"]
    assert (dataset / "still.aedat").is_file()
    for row in rows:
        t, x, y, p = decode_aedat2((dataset / row["events"]).read_bytes())
        t0 = int(row["true_t0_us"])
        assert t[0] > 1_000_000 and np.all(np.diff(t) >= 0)  # the camera's own clock
        assert x.max() < 240 and y.max() < 180
        off = t[p == 0]
        counts, edges = np.histogram(off, np.arange(t[0], t[-1] + 1000, 1000))
        assert abs(edges[np.argmax(counts)] - t0) <= 1000  # the OFF spike is at the manifest's LED-off
        with open(dataset / row["force"]) as handle:
            lines = handle.read().splitlines()
        assert lines[0] == "t_ms,force_N"
        times = np.array([float(line.split(",")[0]) for line in lines[1:]])
        assert times[0] == 0 and np.all(np.diff(times) == 2)  # 500 Hz from LED-off
        assert times[-1] < float(row["true_duration_ms"]) <= times[-1] + 2
        assert t[-1] < t0 + float(row["true_duration_ms"]) * 1000


def test_camera_files_read_back_with_the_project_reader(dataset):
    from neurotac_cli import io
    with open(dataset / "manifest.csv") as handle:
        row = next(csv.DictReader(handle))
    table = io.read_events_table(str(dataset / row["events"]))
    t, x, y, p = decode_aedat2((dataset / row["events"]).read_bytes())
    np.testing.assert_array_equal(table.column("t").to_numpy(), t)
    np.testing.assert_array_equal(table.column("x").to_numpy(), x)
    np.testing.assert_array_equal(table.column("y").to_numpy(), y)
    np.testing.assert_array_equal(table.column("p").to_numpy(), p)


def test_same_seed_same_bytes(dataset, tmp_path):
    again = tmp_path / "again"
    done = subprocess.run(["neurotac", "simulate", *SMALL, "--seed", "7", "--out", str(again)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    names = sorted(path.name for path in dataset.iterdir())
    assert names == sorted(path.name for path in again.iterdir())
    for name in names:
        assert (dataset / name).read_bytes() == (again / name).read_bytes(), name
    other = tmp_path / "other"
    subprocess.run(["neurotac", "simulate", *SMALL, "--seed", "8", "--out", str(other)], check=True)
    assert (other / "manifest.csv").read_bytes() != (dataset / "manifest.csv").read_bytes()


def test_synced_writes_a_recordings_table_relative_to_led_off(tmp_path):
    from neurotac_cli import schema, tables

    out = tmp_path / "rec.arrows"
    result = CliRunner().invoke(cli, ["simulate", *SMALL, "--seed", "7", "--synced", "--keep-led", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = tables.read([str(out)])
    assert schema.kind_of(table.schema) == "recordings"
    assert schema.sensor_of(table.schema) == (240, 180)
    assert table.num_rows == 2
    assert {"material", "object", "size_mm"} <= set(schema.label_columns(table.schema))
    events = table.column("events")[0].values
    t = events.field("t").to_numpy()
    p = events.field("p").to_numpy()
    assert t.min() < 0 < t.max()  # kept: the LED blink is before t0, the grasp after
    assert np.sum((p == 0) & (t >= 0) & (t < 2_000)) > 1000  # kept: the LED-off spike right at t0
    force = table.column("force")[0].values
    assert force.field("t").to_numpy()[0] == 0
    history = schema.get_meta(table.schema, schema.HISTORY)
    assert history[-1]["command"] == "simulate" and history[-1]["args"]["seed"] == 7


def test_the_objects_option_and_labels(tmp_path):
    result = CliRunner().invoke(cli, ["simulate", "--objects", "foam:hex:1,rubber:sphere10:1:grip=soft,steel:hex7:1",
                                      "--set", "hold_us=20ms", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    with open(tmp_path / "manifest.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["material"], r["object"], r["size_mm"]) for r in rows] == [
        ("foam", "hex", "7.5x6.5x35.5"), ("rubber", "sphere10", "10"), ("steel", "hex7", "7")]
    assert rows[1]["grip"] == "soft"


@pytest.mark.parametrize(
    "args, message",
    [
        ([], "nothing to write"),
        (["--synced", "--set", "bogus=1"], "unknown simulator parameter"),
        (["--synced", "--set", "hold_us=700"], "carries its unit"),
        (["--synced", "--objects", "steel:cube3:2"], "unknown object"),
        (["--synced", "--objects", "wood:hex:2"], "unknown material"),
        (["--synced", "--force-range", "3..1"], "force range"),
        (["--out", "x", "-o", "y.arrows"], "-o writes the --synced table"),
        (["--synced", "--vary", "bogus"], "unknown parameter family 'bogus'"),
        (["--synced", "--vary", ""], "empty family name"),
        (["--synced", "--hold-out", "bogus"], "unknown parameter family 'bogus'"),
        (["--synced", "--sensor", "0x0"], "Invalid value for '--sensor': cannot read size '0x0'"),
        (["--synced", "--hold-out", "membrane", "--unseen", "membrane"], "not both"),
        (["--synced", "--force-range", "1e9..1e10"], "force_max_n must be at most 450 N"),
        (["--synced", "--set", "force_max_n=500"], "force_max_n must be at most 450 N"),
        (["--session", "--grasps", "100000000", "--out", "x"], "100000000 is not in the range 0<=x<=85899"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(args, message, tmp_path):
    result = CliRunner().invoke(cli, ["simulate", *args])
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("args", [["--grasps", "2000"], ["--grasps", "0", "--duration", "2h"]])
def test_a_session_longer_than_its_file_s_clock_is_refused_before_it_is_simulated(args, tmp_path):
    """It simulated the 71 minutes that fit an AEDAT 2.0 file's 32-bit µs clock, some 25 minutes of
    work, and then failed on the first event past it."""
    out = tmp_path / "s"
    result = CliRunner().invoke(cli, ["simulate", "--session", *args, "--out", str(out)])
    assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
    assert "session00 would record" in result.output and "past the 71.6 min of an AEDAT 2.0 file's clock" in result.output
    assert not out.exists()


def test_the_bounds_the_help_states_are_those_the_simulator_keeps():
    from neurotac_cli.commands.simulate import MAX_FORCE_N, MAX_GRASPS
    from neurotac_cli.io.writers import AEDAT2_LAST_US
    from neurotac_cli.ops.forcelog import RANGE_N
    from neurotac_cli.sim.config import SESSION_REST_FLOOR_US

    assert (MAX_GRASPS, MAX_FORCE_N) == (AEDAT2_LAST_US // SESSION_REST_FLOOR_US, RANGE_N)


def test_a_run_failing_part_way_over_a_folder_leaves_the_earlier_run_whole(dataset, tmp_path):
    # the files written before the failure replaced the earlier run's: a folder of two seeds under one manifest
    other = tmp_path / "other"
    subprocess.run(["neurotac", "simulate", *SMALL, "--seed", "8", "--out", str(other)], check=True, capture_output=True)
    with open(other / "manifest.csv") as manifest:
        written_first = next(csv.DictReader(manifest))["events"]
    limit_kb = -(-(other / written_first).stat().st_size // 1024)
    assert max(path.stat().st_size for path in other.glob("*.aedat")) > limit_kb * 1024, \
        "the first camera file written must fit under the limit and a later one not"
    folder = tmp_path / "sim"
    subprocess.run(["cp", "-r", str(dataset), str(folder)], check=True)
    before = {path.name: path.read_bytes() for path in folder.iterdir()}
    done = subprocess.run(["bash", "-c", f"ulimit -f {limit_kb}; neurotac simulate {' '.join(SMALL)} --seed 8 --out {folder}"],
                          capture_output=True, text=True)
    assert done.returncode == 1 and done.stderr.count("\n") == 1 and "file too large" in done.stderr, done.stderr
    assert {path.name: path.read_bytes() for path in folder.iterdir()} == before
