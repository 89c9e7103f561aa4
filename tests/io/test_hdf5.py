"""HDF5 event files: a real recording's events written here in each layout in use (Metavision's
CD/events, DSEC's events/{x,y,t,p} with its t_offset, e2vid's events/{xs,ys,ts,ps} in seconds), read
back exactly; damaged and foreign files refused in one line."""

import subprocess
import sys

import h5py
import hdf5plugin
import numpy as np
import pytest

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError
from neurotac_cli.io import read_events_table
from tests.conftest import real_file


@pytest.fixture(scope="module")
def real():
    """(t, x, y, p, width, height) of a real DAVIS346 recording."""
    table = read_events_table(real_file("davis346_aestream.aedat4"))
    return (*(table.column(c).to_numpy() for c in "txyp"), *sch.sensor_of(table.schema))


def write(path, layout, t, x, y, p, width=None, height=None, **compression):
    with h5py.File(path, "w") as handle:
        if layout == "metavision":
            rows = np.zeros(len(t), np.dtype([("x", "<u2"), ("y", "<u2"), ("p", "<i2"), ("t", "<i8")]))
            rows["x"], rows["y"], rows["p"], rows["t"] = x, y, p, t
            handle.create_group("CD").create_dataset("events", data=rows, chunks=True, **compression)
            if width:
                handle.attrs["geometry"] = f"{width}x{height}"
        elif layout == "dsec":
            group = handle.create_group("events")
            offset = int(t[0]) if len(t) else 0
            for name, values in (("x", x.astype(np.uint16)), ("y", y.astype(np.uint16)), ("t", (t - offset).astype(np.uint32)),
                                 ("p", p.astype(np.uint8))):
                group.create_dataset(name, data=values, chunks=True if len(values) else None, **compression)
            handle.create_dataset("t_offset", data=np.int64(offset))
        else:  # e2vid: seconds, polarity -1/1, the size as attributes
            group = handle.create_group("events")
            group["xs"], group["ys"] = x.astype(np.uint16), y.astype(np.uint16)
            group["ts"], group["ps"] = t / 1e6, np.where(p > 0, 1, -1).astype(np.int8)
            if width:
                handle.attrs["width"], handle.attrs["height"] = width, height


@pytest.mark.parametrize("layout", ["metavision", "dsec", "e2vid"])
def test_a_real_recording_in_each_layout_reads_back_exactly(real, layout, tmp_path):
    t, x, y, p, width, height = real
    path = tmp_path / "rec.h5"
    write(path, layout, t, x, y, p, width, height, **(hdf5plugin.Blosc(cname="zstd") if layout == "dsec" else {}))
    table = read_events_table(path)
    for name, values in zip("txyp", (t, x, y, p)):
        assert np.array_equal(table.column(name).to_numpy(), values), name
    if layout == "dsec":  # DSEC does not say its size: the events' extent
        assert sch.sensor_of(table.schema) == (int(x.max()) + 1, int(y.max()) + 1)
    else:
        assert sch.sensor_of(table.schema) == (width, height)


def test_slices_give_the_same_events_as_one_read(real, tmp_path, monkeypatch):
    from neurotac_cli.io import hdf5

    t, x, y, p, width, height = real
    write(tmp_path / "rec.hdf5", "metavision", t, x, y, p, width, height)
    monkeypatch.setattr(hdf5, "SLICE_EVENTS", 1000)
    assert np.array_equal(read_events_table(tmp_path / "rec.hdf5").column("t").to_numpy(), t)


def test_through_stdin_and_refused_when_followed(real, tmp_path):
    t, x, y, p, width, height = real
    path = tmp_path / "rec.h5"
    write(path, "metavision", t[:500], x[:500], y[:500], p[:500], width, height)
    run = lambda *args, **kw: subprocess.run(["neurotac", *args], capture_output=True, **kw)  # noqa: E731
    with open(path, "rb") as handle:
        piped = run("import", "-", "-o", str(tmp_path / "e.arrow"), stdin=handle)
    assert piped.returncode == 0, piped.stderr
    followed = run("import", "--follow", str(path), "-o", str(tmp_path / "f.arrow"))
    assert followed.returncode == 1 and b"read whole, not followed" in followed.stderr and b"Traceback" not in followed.stderr


def refusal(path) -> str:
    with pytest.raises(NeurotacError) as error:
        read_events_table(path)
    message = str(error.value)
    assert "\n" not in message
    return message


def test_damaged_and_foreign_files_are_one_line(tmp_path):
    def make(name, build):
        path = tmp_path / name
        with h5py.File(path, "w") as handle:
            build(handle)
        return path

    def fields(**values):
        return lambda handle: [handle.create_dataset(f"events/{k}", data=v) for k, v in values.items()]

    three = np.arange(3)
    assert "without events in a layout" in refusal(make("a.h5", lambda h: h.create_dataset("images", data=np.zeros((2, 2)))))
    assert "not four lists of one length" in refusal(make("b.h5", fields(x=three, y=three[:2], t=three, p=three)))
    assert "not one number per event" in refusal(make("c.h5", fields(x=np.array([b"a", b"b", b"c"]), y=three, t=three, p=three)))
    assert "not a time a camera writes" in refusal(make("d.h5", fields(xs=three, ys=three, ts=np.array([0, np.nan, 1.0]), ps=three)))
    assert "outside any sensor" in refusal(make("e.h5", fields(x=-three, y=three, t=three, p=three)))
    assert "has no field 'p'" in refusal(make("f.hdf5", lambda h: h.create_dataset(
        "CD/events", data=np.zeros(3, np.dtype([("x", "<u2"), ("y", "<u2"), ("t", "<i8")])))))
    assert "/CD/events is a group, not Metavision's compound" in refusal(make("f2.h5", lambda h: h.create_dataset("CD/events/x", data=three)))
    assert "/CD/events is a dataset of int64" in refusal(make("f3.h5", lambda h: h.create_dataset("CD/events", data=three)))

    def geometry(handle):
        fields(x=three, y=three, t=three, p=three)(handle)
        handle.attrs["geometry"] = "wide"

    assert "geometry attribute" in refusal(make("g.h5", geometry))
    assert "holds both" in refusal(make("i.h5", fields(x=three, y=three, t=three, p=three, xs=three, ys=three, ts=three, ps=three)))
    assert "x, y, t but not a whole set" in refusal(make("j.h5", fields(x=three, y=three, t=three)))
    assert "columns this reader cannot name" in refusal(make("k.h5", lambda h: h.create_dataset("events", data=np.zeros((3, 4)))))
    assert "not a whole pixel" in refusal(make("l.h5", fields(x=three + 0.5, y=three, t=three, p=three)))

    def offset(value):
        return lambda handle: (fields(x=three, y=three, t=three, p=three)(handle), handle.create_dataset("t_offset", data=value))

    assert "one whole number of µs" in refusal(make("m.h5", offset(np.float64(12.5))))
    assert "one whole number of µs" in refusal(make("n.h5", offset(np.array([1, 2]))))
    assert "not a time a camera writes" in refusal(make("o.h5", offset(np.int64(2**63 - 1000))))

    def unwritten(handle):  # room for a million events, none written: HDF5 would read zeros
        for name in "xytp":
            handle.create_dataset(f"events/{name}", shape=(1_000_000,), dtype=np.int64, chunks=(65536,))

    assert "blocks were written" in refusal(make("q.h5", unwritten))
    whole = make("h.h5", fields(x=np.arange(5000), y=np.arange(5000), t=np.arange(5000), p=np.arange(5000)))
    (tmp_path / "cut.h5").write_bytes(whole.read_bytes()[:2000])
    assert "not a valid HDF5 events file" in refusal(tmp_path / "cut.h5")


def test_a_codec_hdf5_cannot_load_is_named(real, tmp_path):
    """Without hdf5plugin HDF5 has no LZ4 filter, as without Prophesee's plugin it has no ECF: the
    file and the way out are named, not HDF5's plugin-directory message."""
    t, x, y, p, width, height = real
    path = tmp_path / "lz4.hdf5"
    write(path, "metavision", t[:100], x[:100], y[:100], p[:100], width, height, **hdf5plugin.LZ4())
    code = ("import sys; sys.modules['hdf5plugin'] = None\n"
            "from neurotac_cli.cli import cli\n"
            f"cli(['import', {str(path)!r}, '-o', {str(tmp_path / 'e.arrow')!r}])")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 1 and "HDF5 filter 32004" in result.stderr and "install its plugin" in result.stderr
    assert result.stderr.strip().count("\n") == 0


def test_links_to_other_files_are_refused(tmp_path):
    """Events in another file would depend on the folder the link is read from, and escape the hash."""
    with h5py.File(tmp_path / "target.h5", "w") as handle:
        for name in "xytp":
            handle.create_dataset(f"events/{name}", data=np.arange(3))
    with h5py.File(tmp_path / "link.h5", "w") as handle:
        handle["events"] = h5py.ExternalLink("target.h5", "/events")
    assert "is a link to target.h5" in refusal(tmp_path / "link.h5")
    with h5py.File(tmp_path / "virtual.h5", "w") as handle:
        for name in "xytp":
            layout = h5py.VirtualLayout(shape=(3,), dtype=np.int64)
            layout[:] = h5py.VirtualSource(str(tmp_path / "target.h5"), f"events/{name}", shape=(3,))
            handle.create_virtual_dataset(f"events/{name}", layout)
    assert "virtual dataset" in refusal(tmp_path / "virtual.h5")


def test_float_times_whole_numbers_are_microseconds_fractions_seconds(real, tmp_path):
    """e2vid writes seconds; evlib the same names with whole-number µs in float64."""
    t, x, y, p, width, height = real
    for name, times in (("seconds.h5", (t - t[0]) / 1e6), ("micro.h5", (t - t[0]).astype(np.float64))):
        with h5py.File(tmp_path / name, "w") as handle:
            handle["events/xs"], handle["events/ys"], handle["events/ts"], handle["events/ps"] = x, y, times, p
        assert np.array_equal(read_events_table(tmp_path / name).column("t").to_numpy(), t - t[0]), name


def test_times_in_32_bit_floats_say_what_they_lost(tmp_path):
    from neurotac_cli.io.events import source_notes

    with h5py.File(tmp_path / "f32.h5", "w") as handle:
        handle["events/xs"], handle["events/ys"], handle["events/ps"] = np.zeros(3), np.zeros(3), np.ones(3)
        handle["events/ts"] = np.array([100.0, 100.0001, 100.0002], dtype=np.float32)
    table = read_events_table(tmp_path / "f32.h5")
    (note,) = source_notes(table.schema)
    assert "32-bit floats" in note and "tell apart only 8 µs" in note


def test_a_file_held_open_by_a_writer_is_told_as_such(tmp_path):
    path = tmp_path / "open.h5"
    with h5py.File(path, "w") as handle:
        for name in "xytp":
            handle.create_dataset(f"events/{name}", data=np.arange(3))
    writer = subprocess.Popen([sys.executable, "-c", f"import h5py, time; h = h5py.File({str(path)!r}, 'a'); print(1, flush=True); time.sleep(30)"],
                              stdout=subprocess.PIPE)
    try:
        writer.stdout.readline()
        try:
            read_events_table(path)
        except NeurotacError as error:
            assert "holds the file open for writing" in str(error)
        else:
            pytest.skip("HDF5's file locks are not enforced here (HDF5_USE_FILE_LOCKING, or the file system)")
    finally:
        writer.kill()
        writer.wait()


def test_what_the_review_found_read_as_something_else(tmp_path):
    def make(name, build):
        with h5py.File(tmp_path / name, "w") as handle:
            build(handle)
        return tmp_path / name

    def e2vid(ts, ps=None):
        n = len(ts)
        return lambda h: [h.create_dataset(f"events/{k}", data=v) for k, v in
                          (("xs", np.zeros(n, np.uint16)), ("ys", np.zeros(n, np.uint16)), ("ts", ts), ("ps", np.ones(n) if ps is None else ps))]

    # e2vid seconds whose first thousands are 0.0: the middle and the tail say seconds
    ts = np.concatenate([np.zeros(5000), np.linspace(0.001, 2.5, 5000)])
    table = read_events_table(make("zeros_first.h5", e2vid(ts)))
    assert table.column("t").to_numpy()[-1] == 2_500_000
    assert "cannot be told" in refusal(make("f32_whole.h5", e2vid(np.array([2e7, 3e7], dtype=np.float32))))
    assert "not a number" in refusal(make("nan_p.h5", e2vid(np.array([0.1, 0.2]), np.array([1.0, np.nan]))))
    subarray = np.dtype([("x", "<u2", (2,)), ("y", "<u2"), ("p", "<i2"), ("t", "<i8")])
    assert "not one number per event" in refusal(make("sub.hdf5", lambda h: h.create_dataset("CD/events", data=np.zeros(3, subarray))))
    raw = tmp_path / "x.bin"
    raw.write_bytes(np.arange(3, dtype=np.int64).tobytes())

    def external(handle):
        handle.create_dataset("events/x", shape=(3,), dtype=np.int64, external=[(str(raw), 0, 24)])
        for name in "ytp":
            handle.create_dataset(f"events/{name}", data=np.arange(3))

    assert "external storage" in refusal(make("ext.h5", external))

    def metavision_with_offset(handle):  # DSEC's t_offset belongs to DSEC's layout, not Metavision's
        rows = np.zeros(2, np.dtype([("x", "<u2"), ("y", "<u2"), ("p", "<i2"), ("t", "<i8")]))
        rows["t"] = [5, 9]
        handle.create_dataset("CD/events", data=rows)
        handle.create_dataset("t_offset", data=np.int64(1000))

    assert list(read_events_table(make("mv_offset.hdf5", metavision_with_offset)).column("t").to_numpy()) == [5, 9]
