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

    def geometry(handle):
        fields(x=three, y=three, t=three, p=three)(handle)
        handle.attrs["geometry"] = "wide"

    assert "geometry attribute" in refusal(make("g.h5", geometry))
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
