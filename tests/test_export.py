"""Camera files out: EVT 3.0 and AEDAT 2.0 written from events tables read back equal."""

import numpy as np
import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.errors import NeurotacError
from neurotac_cli.export import evt3_bytes, export
from neurotac_cli.io.events import read_events_table


def events(n=2000, start=3_000_000, gap=0, seed=0, width=640, height=480):
    rng = np.random.default_rng(seed)
    t = np.sort(start + rng.integers(0, 200_000, n))
    t[n // 2:] += gap
    return sch.events_table(t, rng.integers(0, width, n), rng.integers(0, height, n), rng.integers(0, 2, n), width, height)


def columns(table):
    return [table.column(name).to_numpy().astype(np.int64) for name in ("t", "x", "y", "p")]


@pytest.mark.parametrize("suffix", [".raw", ".aedat", ".aedat4", ".h5"])
def test_written_files_read_back_equal(tmp_path, suffix):
    table = events(width=240, height=180)
    path = str(tmp_path / f"e{suffix}")
    assert export(table, path)["shift_us"] == 0
    back = read_events_table(path)
    for a, b in zip(columns(back), columns(table)):
        np.testing.assert_array_equal(a, b)
    assert sch.sensor_of(back.schema) == (240, 180)


def test_evt3_keeps_time_over_many_loops_and_gaps(tmp_path):
    table = events(start=5_000_000, gap=70_000_000)  # a 70 s gap: four 2^24 µs loops without events
    (tmp_path / "g.raw").write_bytes(evt3_bytes(*columns(table), 640, 480)[0])
    for a, b in zip(columns(read_events_table(str(tmp_path / "g.raw"))), columns(table)):
        np.testing.assert_array_equal(a, b)


def test_evt3_of_unix_time_drops_whole_loops(tmp_path):
    table = events(start=1_600_000_000_000_000)
    data, shift = evt3_bytes(*columns(table), 640, 480)
    (tmp_path / "u.raw").write_bytes(data)
    assert shift % (1 << 24) == 0 and shift > 0
    np.testing.assert_array_equal(columns(read_events_table(str(tmp_path / "u.raw")))[0] + shift, columns(table)[0])


def test_refusals(tmp_path):
    backwards = sch.events_table([5, 3], [0, 0], [0, 0], [1, 1], 4, 4)
    with pytest.raises(NeurotacError, match="not in time order"):
        evt3_bytes(*columns(backwards), 4, 4)
    source = str(tmp_path / "e.arrows")
    tables.write(source, events())
    result = CliRunner().invoke(cli, ["export", source, "-o", str(tmp_path / "e.dat")])
    assert result.exit_code == 2 and "use .raw for EVT 3.0, .aedat4 for AEDAT 4.0" in result.output


def test_a_trial_of_recordings_goes_back_on_the_camera_clock(tmp_path):
    recordings = sch.recordings_table([{"trial": "g", "t0": 1_000_000, "events": ([-50, 0, 10], [1, 2, 3], [4, 5, 6], [1, 0, 1]),
                                        "force": ([0], [0.5])}], width=240, height=180)
    source = str(tmp_path / "r.arrows")
    tables.write(source, recordings)
    result = CliRunner().invoke(cli, ["export", source, "-o", str(tmp_path / "g.raw")])
    assert result.exit_code == 0, result.output
    assert read_events_table(str(tmp_path / "g.raw")).column("t").to_pylist() == [999_950, 1_000_000, 1_000_010]


def test_aedat4_is_read_by_the_reference_decoder(tmp_path):
    aedat = pytest.importorskip("aedat")
    table = events(n=70_000, width=346, height=260)  # three packets
    export(table, str(tmp_path / "e.aedat4"))
    decoder = aedat.Decoder(str(tmp_path / "e.aedat4"))
    assert decoder.id_to_stream() == {0: {"type": "events", "width": 346, "height": 260}}
    decoded = np.concatenate([packet["events"] for packet in decoder])
    for name, column in zip(("t", "x", "y", "on"), columns(table)):
        np.testing.assert_array_equal(decoded[name].astype(np.int64), column)


def test_evt3_is_read_back_equal_by_evlib(tmp_path):
    evlib = pytest.importorskip("evlib")
    table = events()
    export(table, str(tmp_path / "e.raw"))
    theirs = evlib.load_events(str(tmp_path / "e.raw"))
    theirs = theirs.collect() if hasattr(theirs, "collect") else theirs
    t = theirs["t"]
    t = t.dt.total_microseconds() if t.dtype.is_temporal() else t
    assert t.to_numpy().tolist() == table.column("t").to_pylist()
    assert theirs["x"].to_numpy().tolist() == table.column("x").to_pylist()
    assert theirs["y"].to_numpy().tolist() == table.column("y").to_pylist()
    assert (theirs["polarity"].to_numpy() > 0).astype(int).tolist() == table.column("p").to_pylist()


@pytest.mark.parametrize("suffix", [".h5", ".aedat4", ".raw"])
def test_a_time_import_would_refuse_is_not_exported(tmp_path, suffix):
    table = sch.events_table([2**62, 2**62 + 5], [0, 1], [0, 1], [1, 0], 4, 4)
    with pytest.raises(NeurotacError, match="not one a camera writes"):
        export(table, str(tmp_path / f"e{suffix}"))
    assert not (tmp_path / f"e{suffix}").exists()


def test_events_before_time_zero_are_refused_in_one_line(tmp_path):
    table = sch.events_table([-5, 3], [0, 1], [0, 1], [1, 0], 4, 4)
    with pytest.raises(NeurotacError, match="first event is at -5"):
        evt3_bytes(*columns(table), 4, 4)


def test_hdf5_ms_to_idx_written_in_blocks_equals_the_index_computed_whole(tmp_path, monkeypatch):
    import h5py

    from neurotac_cli import export as ex

    t = np.sort(np.random.default_rng(2).integers(0, 250_000, 3_000))
    monkeypatch.setattr(ex, "MS_BLOCK", 7)  # 252 milliseconds in 36 blocks, the last one short
    with h5py.File(tmp_path / "b.h5", "w") as handle:
        ex._write_ms_to_idx(handle, t)
        index = handle["ms_to_idx"][()]
    assert np.array_equal(index, np.searchsorted(t, np.arange(t[-1] // 1000 + 2) * 1000))


def test_hdf5_is_dsecs_layout_as_its_readers_take_it(tmp_path):
    """What DSEC's loaders do (tonic's: events/x,y,t,p plus t_offset; seeking by ms_to_idx) gives the events back."""
    import h5py

    table = events(seed=3)
    t, x, y, p = columns(table)
    assert not export(table, str(tmp_path / "e.h5"))["unindexed"]
    with h5py.File(tmp_path / "e.h5", "r") as handle:
        group = handle["events"]
        assert np.array_equal(group["t"][()] + handle["t_offset"][()], t)
        assert np.array_equal(group["x"][()], x) and np.array_equal(group["y"][()], y) and np.array_equal(group["p"][()], p)
        index = handle["ms_to_idx"][()]
        for ms in (0, 50, 199):
            assert np.all(group["t"][()][index[ms]:] >= ms * 1000) and np.all(group["t"][()][:index[ms]] < ms * 1000)
        assert handle.attrs["geometry"] == "640x480"
    shuffled = table.take(np.random.default_rng(0).permutation(table.num_rows))
    tables.write(str(tmp_path / "s.parquet"), shuffled)
    result = CliRunner().invoke(cli, ["export", "-o", str(tmp_path / "s.h5"), str(tmp_path / "s.parquet")])
    assert result.exit_code == 0 and "no ms_to_idx index was written" in result.stderr
    assert np.array_equal(read_events_table(tmp_path / "s.h5").column("t").to_numpy(), shuffled.column("t").to_numpy())


def test_hdf5_the_disk_cannot_hold_is_one_line_and_keeps_the_old_file(tmp_path):
    # HDF5 met the size limit inside its own writes: a dozen "Exception ignored" tracebacks, then a segfault
    import subprocess

    tables.write(str(tmp_path / "e.arrows"), events(n=20_000))
    (tmp_path / "x.h5").write_bytes(b"old")
    done = subprocess.run(["bash", "-c", "ulimit -f 16; neurotac export e.arrows -o x.h5"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 1, (done.returncode, done.stderr[-500:])
    assert done.stderr.startswith("neurotac export: error: cannot write x.h5 (file too large") and done.stderr.count("\n") == 1
    assert (tmp_path / "x.h5").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.arrows", "x.h5"]
