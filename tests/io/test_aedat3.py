"""AEDAT 3.1 (cAER): files written here from the format's description (inivation's AEDAT 3.1 page and
libcaer's event headers), read as files, followed while written, and against tonic's reader."""

import struct
import subprocess

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from neurotac_cli import schema as sch
from neurotac_cli.io import live, read_events_table
from tests.io.test_fuzz import FUZZ, outcome
from tests.io.test_live import collect, events, write_in_pieces

HEADER = b"#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DVS128\r\n#Start-Time: 2026-11-27 10:00:00 (TZ+0000)\r\n#!END-HEADER\r\n"


def polarity(x, y, p, valid=1):
    return (int(x) << 17) | (int(y) << 2) | (int(p) << 1) | valid


def packet(kind, records, overflow=0, source=1, size=8):
    """A packet of (data, timestamp) records (of `size` bytes each, zero-padded) in libcaer's layout."""
    valid = sum(data & 1 for data, _ in records)
    body = b"".join(struct.pack("<Ii", data, ts).ljust(size, b"\0") for data, ts in records)
    return struct.pack("<hhiiiiii", kind, source, size, 4, overflow, len(records), len(records), valid) + body


def recording(seed=0, packets=6, per=50):
    """(file bytes, expected t, x, y, p): polarity packets of 128x128 events, the third with an overflow
    of 1, a filtered-out event in each, a special packet (a wrap, which is no trigger, and a rising
    edge) and a frame packet between them."""
    rng = np.random.default_rng(seed)
    data, expected, t = [HEADER], [], 0
    for k in range(packets):
        overflow = 1 if k >= 2 else 0
        records = []
        for _ in range(per):
            t += int(rng.integers(1, 50))
            x, y, p = rng.integers(0, 128), rng.integers(0, 128), rng.integers(0, 2)
            records.append((polarity(x, y, p), t))
            expected.append(((overflow << 31) | t, x, y, p))
        records.append((polarity(3, 4, 1, valid=0), t))  # removed by a filter in cAER
        data.append(packet(1, records, overflow))
        if k == 1:
            data.append(packet(0, [((0 << 1) | 1, t), ((2 << 1) | 1, t + 5)]))  # a timestamp wrap, a rising edge
            data.append(packet(2, [(0, t)], size=40))  # an APS frame: skipped
    return b"".join(data), tuple(np.array(column) for column in zip(*expected))


def write(tmp_path, data, name="rec.aedat"):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def test_polarity_events_triggers_and_sensor_are_read(tmp_path):
    data, (t, x, y, p) = recording()
    table = read_events_table(str(write(tmp_path, data)))
    assert [table[c].to_numpy().astype(np.int64).tolist() for c in "txyp"] == [c.astype(np.int64).tolist() for c in (t, x, y, p)]
    assert sch.sensor_of(table.schema) == (128, 128)
    assert sch.get_meta(table.schema, "neurotac:triggers") == [{"t": int(t[99]) + 5, "type": "rising", "id": 0}]
    source = sch.camera_sources(table.schema)[0]
    assert source["format"] == "aedat3" and source["camera"] == "DVS128" and source["sensor_from"] == "file"


def test_equal_to_tonics_reader(tmp_path):
    io = pytest.importorskip("tonic.io")
    rng = np.random.default_rng(1)
    records = [(polarity(rng.integers(0, 128), rng.integers(0, 128), rng.integers(0, 2)), 10 * i) for i in range(300)]
    path = write(tmp_path, HEADER + packet(1, records[:120]) + packet(1, records[120:]))
    version, start, _ = io.read_aedat_header_from_file(str(path))
    theirs = io.get_aer_events_from_file(str(path), version, start)
    address = theirs["address"]
    table = read_events_table(str(path))
    assert table["t"].to_pylist() == theirs["timeStamp"].astype(np.int64).tolist()
    assert table["x"].to_pylist() == ((address >> 17) & 0x7FFF).tolist()
    assert table["y"].to_pylist() == ((address >> 2) & 0x7FFF).tolist()
    assert table["p"].to_pylist() == ((address >> 1) & 1).tolist()


def test_a_file_cut_mid_packet_keeps_its_whole_packets_and_says_so(tmp_path):
    data, (t, *_) = recording()
    cut = len(data) - 100
    path = write(tmp_path, data[:cut])
    done = subprocess.run(["neurotac", "import", str(path), "-o", str(tmp_path / "e.parquet")], capture_output=True, text=True)
    assert done.returncode == 0 and "warning" in done.stderr and "cut" in done.stderr
    table = read_events_table(str(path))
    assert table["t"].to_pylist() == t[:250].astype(np.int64).tolist()  # the last packet of 50 was cut
    assert sch.camera_sources(table.schema)[0]["cut_bytes"] == cut - (len(data) - (28 + 51 * 8))


def test_following_a_file_written_in_pieces_gives_the_finished_files_events(tmp_path):
    data, _ = recording(packets=12)
    path = tmp_path / "live.aedat"
    path.write_bytes(b"")
    writer = write_in_pieces(data, path)
    table, batches = collect(live.open_stream(str(path), follow=True, idle_timeout=0.5))
    writer.join()
    whole = read_events_table(str(write(tmp_path, data, "whole.aedat")))
    assert events(table).equals(events(whole)) and batches > 1
    assert sch.sensor_of(table.schema) == (128, 128)


def test_a_second_cameras_events_are_left_out_and_counted(tmp_path):
    ours = packet(1, [(polarity(1, 2, 1), 10), (polarity(2, 3, 0), 20)])
    other = packet(1, [(polarity(5, 5, 1), 15)] * 3, source=2)
    for order in ([ours, other], [other, ours]):  # the header's source is read, whichever packet comes first
        table = read_events_table(str(write(tmp_path, HEADER + b"".join(order))))
        assert table["t"].to_pylist() == [10, 20]
        source = sch.camera_sources(table.schema)[0]
        assert source["events_of_other_sources"] == 3 and source["camera"] == "DVS128"
    table = read_events_table(str(write(tmp_path, HEADER + other)))  # none of the named source's: no camera claimed
    assert table["t"].to_pylist() == [15] * 3 and "camera" not in sch.camera_sources(table.schema)[0]


def test_each_external_input_keeps_its_id():
    from neurotac_cli.io.aedat3 import Packets

    reader = Packets()
    reader.decode(packet(0, [((2 << 1) | 1, 5), ((6 << 1) | 1, 6), ((10 << 1) | 1, 7), ((1 << 1) | 1, 8)]))
    assert reader.triggers == [{"t": 5, "type": "rising", "id": 0}, {"t": 6, "type": "rising", "id": 1},
                               {"t": 7, "type": "falling", "id": 2}, {"t": 8, "type": "timestamp_reset"}]


def test_the_format_can_be_named():
    from neurotac_cli.io.camera import FORMATS
    from neurotac_cli.options import CAMERA_FORMATS

    assert CAMERA_FORMATS == list(FORMATS)


@pytest.mark.parametrize("damage, said", [
    (lambda d: d.replace(b"#!END-HEADER\r\n", b""), "no `#!END-HEADER` line"),
    (lambda d: d[: len(HEADER) + 16] + struct.pack("<i", -5) + d[len(HEADER) + 20 :], "packet header is damaged"),
    (lambda d: d[: len(HEADER) + 8] + struct.pack("<i", 0) + d[len(HEADER) + 12 :], "timestamps at byte 0"),
    (lambda d: d[: len(HEADER) + 4] + struct.pack("<i", 12) + d[len(HEADER) + 8 :], "12-byte events"),
])
def test_a_damaged_file_is_one_line(tmp_path, damage, said):
    data, _ = recording()
    path = write(tmp_path, damage(data))
    done = subprocess.run(["neurotac", "import", str(path), "-o", str(tmp_path / "e.parquet")], capture_output=True, text=True)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 1 and len(lines) == 1 and said in lines[0], done.stderr


@FUZZ
@given(flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 7)), min_size=1, max_size=8),
       cut=st.floats(0.5, 1))
def test_a_bit_flipped_or_cut_file_is_a_table_or_one_error(flips, cut):
    data = bytearray(recording(packets=3)[0])
    for where, bit in flips:
        data[int(where * len(data))] ^= 1 << bit
    outcome(bytes(data[: int(len(data) * cut)]), ".aedat")


def test_a_file_truncated_while_it_is_read_is_one_error_not_a_bus_error(tmp_path):
    """Another program truncating the file between the packet walk and the events: a memory-mapped
    file killed the process with SIGBUS; in a child process, so that this test's process survives it."""
    import sys

    data, *_ = recording(packets=50, per=2000)
    path = tmp_path / "cut.aedat"
    path.write_bytes(data)
    code = ("import os\nfrom neurotac_cli.io.aedat3 import open_aedat3\nfrom neurotac_cli.errors import FormatError\n"
            f"decoded = open_aedat3({str(path)!r}, open({str(path)!r}, 'rb').read(1 << 16), None)\n"
            f"os.truncate({str(path)!r}, {len(data) // 3})\n"
            "try:\n    [c for c in decoded.chunks()]\nexcept FormatError as error:\n    print(error)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout.strip()) == (0, "the file was cut short while it was read (another program truncated it)"), done.stderr[-300:]
