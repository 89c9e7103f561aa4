"""Every real recording decodes to exactly the events (t, x, y, p, same order) and sensor size that
independent reference readers give (../shared/data/real/README.md documents the edge cases)."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from neurotac_cli import schema as sch
from neurotac_cli.io import camera, read_events, read_events_table, reader
from tests.conftest import real_file

warnings.filterwarnings("ignore", category=DeprecationWarning)


def columns(table):
    return tuple(table.column(name).to_numpy() for name in ("t", "x", "y", "p"))


def assert_same(table, t, x, y, p):
    ours = columns(table)
    assert len(ours[0]) == len(t)
    for name, mine, theirs in zip("txyp", ours, (t, x, y, p)):
        assert np.array_equal(mine.astype(np.int64), np.asarray(theirs).astype(np.int64)), f"column {name} differs"


def faery_events(path):
    faery = pytest.importorskip("faery")
    chunks = list(faery.events_stream_from_file(str(path)))
    events = np.concatenate(chunks)
    return events["t"].astype(np.int64), events["x"], events["y"], events["on"].astype(np.uint8)


def expelliarmus_events(path, encoding):
    wizard = pytest.importorskip("expelliarmus").Wizard(encoding=encoding)
    events = wizard.read(str(path))
    return events["t"], events["x"], events["y"], events["p"]


# ---------------------------------------------------------------- AEDAT 2.0


def davis_reference(path, height):
    """tonic's AEDAT 2.0 reader for header and raw records, decoded with the README's DAVIS layout."""
    tio = pytest.importorskip("tonic.io")
    header = tio.read_aedat_header_from_file(str(path))
    version, start = header[0], header[1]
    raw = tio.get_aer_events_from_file(str(path), version, start)
    address = raw["address"].astype(np.int64)
    dvs = ((address >> 31) & 1 == 0) & ((address >> 10) & 1 == 0)
    address = address[dvs]
    return (
        raw["timeStamp"][dvs].astype(np.int64),
        (address >> 12) & 0x3FF,
        height - 1 - ((address >> 22) & 0x1FF),
        (address >> 11) & 1,
    )


def test_davis240c_aedat2_matches_the_reference_decode_with_y_flipped():
    path = real_file("davis240c_rotdisk.aedat")
    table = read_events_table(path)
    assert table.num_rows == 374_296
    assert sch.sensor_of(table.schema) == (240, 180)
    assert_same(table, *davis_reference(path, 180))
    span = table["t"].to_numpy()
    assert 3.1e6 < span.max() - span.min() < 3.2e6


def test_aedat2_numpy_statement_of_the_layout_agrees_with_the_compiled_decoder():
    from neurotac_cli.io.aedat2 import decode_davis_numpy, header_length

    data = real_file("davis240c_rotdisk.aedat").read_bytes()
    start = header_length(data)
    body = data[start : start + (len(data) - start) // 8 * 8]
    assert_same(read_events_table(real_file("davis240c_rotdisk.aedat")), *decode_davis_numpy(body, 180))


def test_header_only_aedat2_is_an_empty_table_with_its_sensor():
    table = read_events_table(real_file("header_only_tonic.aedat"))
    assert table.num_rows == 0
    assert sch.sensor_of(table.schema) == (346, 260)
    assert sch.kind_of(table.schema) == "events"


def test_aedat2_truncated_trailing_record_is_tolerated(tmp_path):
    data = real_file("davis240c_rotdisk.aedat").read_bytes()
    cut = tmp_path / "cut.aedat"
    cut.write_bytes(data[:-3])
    whole = read_events_table(real_file("davis240c_rotdisk.aedat"))
    table = read_events_table(cut)
    assert table.num_rows in (whole.num_rows, whole.num_rows - 1)
    assert table.equals(whole.slice(0, table.num_rows))


def test_aedat2_reads_the_simulator_writer_exactly(tmp_path):
    writers = pytest.importorskip("neurotac_cli.io.writers")
    rng = np.random.default_rng(3)
    n = 5000
    t = np.sort(rng.integers(1_000_000, 3_000_000_000, n))
    x, y, p = rng.integers(0, 240, n), rng.integers(0, 180, n), rng.integers(0, 2, n)
    path = tmp_path / "sim.aedat"
    writers.write_aedat2(path, t, x, y, p)
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (240, 180)
    assert_same(table, t, x, y, p)


def test_aedat2_reads_the_simulator_writer_at_other_sensor_sizes(tmp_path):
    writers = pytest.importorskip("neurotac_cli.io.writers")
    t, x, y, p = np.arange(10, 20), np.arange(10) * 30, np.arange(10) * 9, np.arange(10) % 2
    path = tmp_path / "sim346.aedat"
    writers.write_aedat2(path, t, x, y, p, width=346, height=260)
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (346, 260)
    assert_same(table, t, x, y, p)


# ---------------------------------------------------------------- AEDAT 4.0


@pytest.mark.parametrize("name, sensor", [("davis346_aestream.aedat4", (346, 260)), ("dvxplorer_tonic.aedat4", (320, 240))])
def test_aedat4_matches_faery(name, sensor):
    path = real_file(name)
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == sensor
    assert_same(table, *faery_events(path))
    assert isinstance(sch.get_meta(table.schema, "neurotac:triggers"), list)


def test_aedat4_event_counts_match_the_readme():
    assert read_events_table(real_file("davis346_aestream.aedat4")).num_rows == 117_667
    assert read_events_table(real_file("dvxplorer_tonic.aedat4")).num_rows == 111_954


# ---------------------------------------------------------------- Prophesee


def test_evt2_matches_faery_and_expelliarmus():
    path = real_file("prophesee_vga_faery.evt2.raw")
    table = read_events_table(path)
    assert table.num_rows == 521_252
    assert sch.sensor_of(table.schema) == (640, 480)
    assert_same(table, *faery_events(path))
    assert_same(table, *expelliarmus_events(path, "evt2"))


def evt3_reference(path):
    """Prophesee's EVT 3.0 decoding (OpenEB's sample decoder), one word at a time: TIME_HIGH sets the
    base and resets the low part, TIME_LOW sets the low part as written, vectors advance x."""
    data = path.read_bytes()
    start = 0
    while data[start : start + 1] == b"%":
        start = data.index(b"\n", start) + 1
    words = np.frombuffer(data[start : start + (len(data) - start) // 2 * 2], dtype="<u2").tolist()
    out = [], [], [], []
    base = None
    time = y = base_x = vector_p = 0
    for word in words:
        kind, payload = word >> 12, word & 0xFFF
        if kind == 0x8:
            base = payload << 12
            time = base
        elif kind == 0x6 and base is not None:
            time = base + payload
        elif kind == 0x0:
            y = payload & 0x7FF
        elif kind == 0x2 and base is not None:
            for column, value in zip(out, (time, payload & 0x7FF, y, payload >> 11)):
                column.append(value)
        elif kind == 0x3:
            base_x, vector_p = payload & 0x7FF, payload >> 11
        elif kind in (0x4, 0x5):
            width = 12 if kind == 0x4 else 8
            if base is not None:
                for bit in range(width):
                    if payload >> bit & 1:
                        for column, value in zip(out, (time, base_x + bit, y, vector_p)):
                            column.append(value)
            base_x += width
    return [np.array(column) for column in out]


def test_evt3_matches_prophesee_decoding_and_keeps_backward_time_low_steps():
    path = real_file("prophesee_hd_expelliarmus.evt3.raw")
    table = read_events_table(path)
    assert table.num_rows == 219_596
    assert sch.sensor_of(table.schema) == (1280, 720)
    assert_same(table, *evt3_reference(path))
    # faery and expelliarmus agree on x, y, p; on t they force monotonic time or add a 4096 µs roll
    ft, fx, fy, fp = faery_events(path)
    t, x, y, p = columns(table)
    assert np.array_equal(x, fx) and np.array_equal(y, fy) and np.array_equal(p, fp)
    ex = expelliarmus_events(path, "evt3")
    assert np.array_equal(x, ex[1]) and np.array_equal(y, ex[2]) and np.array_equal(p, ex[3])
    late = ft - t
    assert late.min() == 0 and late.max() == 11  # faery holds the larger time after a backward step


def test_evt3_file_has_nine_backward_time_low_words():
    data = real_file("prophesee_hd_expelliarmus.evt3.raw").read_bytes()
    start = 0
    while data[start : start + 1] == b"%":
        start = data.index(b"\n", start) + 1
    words = np.frombuffer(data[start : start + (len(data) - start) // 2 * 2], dtype="<u2").astype(np.int64)
    kind = words >> 12
    timing = words[(kind == 0x6) | (kind == 0x8)]
    low = (timing >> 12) == 0x6
    backward = low[1:] & low[:-1] & ((timing[1:] & 0xFFF) < (timing[:-1] & 0xFFF))
    assert int(backward.sum()) == 9


def test_dat_matches_expelliarmus_and_takes_its_sensor_from_the_events_or_the_option():
    path = real_file("atis_ncars_loris.dat")
    table = read_events_table(path)
    assert table.num_rows == 4_407
    assert_same(table, *expelliarmus_events(path, "dat"))
    assert sch.sensor_of(table.schema) == (54, 61)
    assert sch.get_meta(table.schema, "neurotac:source")["sensor_from"] == "events"
    assert sch.sensor_of(read_events_table(path, sensor=(304, 240)).schema) == (304, 240)


def test_es_matches_faery_with_the_bottom_left_origin_flipped():
    path = real_file("atis_ncars_loris.es")
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (54, 239)
    assert_same(table, *faery_events(path))
    # the same events as the .dat: times, x and polarity equal; rows mirrored by the conversion
    dat = read_events_table(real_file("atis_ncars_loris.dat"))
    for name in ("t", "x", "p"):
        assert np.array_equal(table[name].to_numpy(), dat[name].to_numpy())


# ---------------------------------------------------------------- chunking


@pytest.mark.parametrize(
    "name",
    [
        "davis240c_rotdisk.aedat",
        "prophesee_vga_faery.evt2.raw",
        "prophesee_hd_expelliarmus.evt3.raw",
        "atis_ncars_loris.dat",
        "atis_ncars_loris.es",
    ],
)
def test_small_chunks_give_the_same_events_as_one_chunk(name, monkeypatch):
    path = real_file(name)
    whole = read_events_table(path)
    monkeypatch.setattr(reader, "CHUNK_BYTES", 4099)
    schema, batches = read_events(path)
    parts = list(batches)
    assert len(parts) > 3
    import pyarrow as pa

    assert pa.Table.from_batches(parts, schema=schema).equals(whole)


def test_formats_are_told_from_their_first_bytes(real_data):
    expected = {
        "davis240c_rotdisk.aedat": "aedat2",
        "header_only_tonic.aedat": "aedat2",
        "davis346_aestream.aedat4": "aedat4",
        "dvxplorer_tonic.aedat4": "aedat4",
        "prophesee_vga_faery.evt2.raw": "evt2",
        "prophesee_hd_expelliarmus.evt3.raw": "evt3",
        "atis_ncars_loris.dat": "dat",
        "atis_ncars_loris.es": "es",
    }
    for name, fmt in expected.items():
        head = (real_data / name).read_bytes()[: 1 << 16]
        assert camera.detect_format(name, head) == fmt


# ---------------------------------------------------------------- synthetic edge cases


def _raw(tmp_path, name, header, words, dtype):
    path = tmp_path / name
    path.write_bytes(header + np.asarray(words, dtype=dtype).tobytes())
    return path


def test_evt3_time_high_wrap_adds_2_24_us_and_vectors_advance_x(tmp_path):
    words = [
        0x8000 | 0xFFF,  # TIME_HIGH 4095
        0x0000 | 7,  # ADDR_Y 7
        0x6000 | 0x010,  # TIME_LOW 16
        0x2000 | (1 << 11) | 5,  # ADDR_X x=5, ON
        0x8000 | 0x000,  # TIME_HIGH 0: a wrap
        0x3000 | 100,  # VECT_BASE_X x=100, OFF
        0x4000 | 0b100000000001,  # VECT_12: x=100 and x=111
        0x5000 | 0b10000001,  # VECT_8: x=112 and x=119
        0x6000 | 0x005,  # TIME_LOW 5
        0x6000 | 0x003,  # TIME_LOW 3: steps back, kept
        0x2000 | 9,  # ADDR_X x=9, OFF
    ]
    path = _raw(tmp_path, "w.raw", b"% evt 3.0\n% geometry 1280x720\n", words, "<u2")
    table = read_events_table(path)
    base = 1 << 24
    assert columns(table)[0].tolist() == [(4095 << 12) + 16, base, base, base, base, base + 3]
    assert columns(table)[1].tolist() == [5, 100, 111, 112, 119, 9]
    assert columns(table)[2].tolist() == [7] * 6
    assert columns(table)[3].tolist() == [1, 0, 0, 0, 0, 0]
    assert sch.sensor_of(table.schema) == (1280, 720)


def test_evt2_time_high_wrap_and_events_before_the_first_time_high(tmp_path):
    cd = lambda on, low, x, y: (on << 28) | (low << 22) | (x << 11) | y  # noqa: E731
    words = [
        cd(1, 1, 3, 4),  # no time base yet: skipped
        (0x8 << 28) | 0x0FFFFFFF,
        cd(1, 2, 5, 6),
        (0x8 << 28) | 0x1,  # wrap
        cd(0, 3, 7, 8),
    ]
    path = _raw(tmp_path, "w.raw", b"% evt 2.0\n% geometry 640x480\n", words, "<u4")
    t, x, y, p = columns(read_events_table(path))
    assert t.tolist() == [(0x0FFFFFFF << 6) + 2, (1 << 34) + (1 << 6) + 3]
    assert x.tolist() == [5, 7] and y.tolist() == [6, 8] and p.tolist() == [1, 0]


def test_aedat4_decoded_twice_when_large_gives_the_same_table(monkeypatch):
    from neurotac_cli.io import aedat4

    path = real_file("davis346_aestream.aedat4")
    once = read_events_table(path)
    monkeypatch.setattr(aedat4, "SINGLE_PASS_BYTES", 0)
    assert read_events_table(path).equals(once, check_metadata=True)


def test_aedat2_sensor_option_does_not_change_the_flip():
    path = real_file("davis240c_rotdisk.aedat")
    wider = read_events_table(path, sensor=(300, 300))
    assert sch.sensor_of(wider.schema) == (300, 300)
    assert np.array_equal(wider["y"].to_numpy(), read_events_table(path)["y"].to_numpy())


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 3000), width=st.integers(1, 1024), height=st.integers(1, 512))
def test_any_events_the_simulator_writes_read_back_exactly(tmp_path_factory, seed, n, width, height):
    writers = pytest.importorskip("neurotac_cli.io.writers")
    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(0, 2**32, n))
    x, y, p = rng.integers(0, width, n), rng.integers(0, height, n), rng.integers(0, 2, n)
    path = tmp_path_factory.mktemp("aedat") / "e.aedat"
    writers.write_aedat2(path, t, x, y, p, width=width, height=height)
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (width, height)
    assert_same(table, t, x, y, p)


def test_prophesee_external_triggers_go_to_the_metadata(tmp_path):
    words3 = [0x8000 | 5, 0x6000 | 7, 0xA000 | (2 << 8) | 1, 0x6000 | 9, 0xA000 | (2 << 8) | 0, 0x0000 | 1, 0x2000 | 3]
    table = read_events_table(_raw(tmp_path, "t3.raw", b"% evt 3.0\n", words3, "<u2"))
    base = 5 << 12
    assert sch.get_meta(table.schema, "neurotac:triggers") == [
        {"t": base + 7, "type": "rising", "id": 2},
        {"t": base + 9, "type": "falling", "id": 2},
    ]
    assert table.num_rows == 1
    words2 = [(0x8 << 28) | 3, (0xA << 28) | (4 << 22) | (1 << 8) | 1]
    table = read_events_table(_raw(tmp_path, "t2.raw", b"% evt 2.0\n", words2, "<u4"), sensor=(640, 480))
    assert sch.get_meta(table.schema, "neurotac:triggers") == [{"t": (3 << 6) + 4, "type": "rising", "id": 1}]
    assert sch.get_meta(read_events_table(real_file("prophesee_vga_faery.evt2.raw")).schema, "neurotac:triggers") is None


def test_prophesee_geometry_from_newer_headers(tmp_path):
    words = [0x8000 | 1, 0x0000 | 3, 0x2000 | 4]
    for header in (b"% format EVT3;height=720;width=1280\n", b"% evt 3.0\n% geometry 1280x720\n"):
        table = read_events_table(_raw(tmp_path, "g.raw", header, words, "<u2"))
        assert sch.sensor_of(table.schema) == (1280, 720) and table.num_rows == 1


def test_dat_geometry_from_its_header(tmp_path):
    header = b"% Data file containing CD events.\n% Version 2\n% Height 240\n% Width 304\n" + bytes([0x0C, 8])
    record = np.array([[100, (1 << 28) | (7 << 14) | 9]], dtype="<u4")
    table = read_events_table(_raw(tmp_path, "d.dat", header, record, "<u4"))
    assert sch.sensor_of(table.schema) == (304, 240)
    assert [tuple(r.values()) for r in table.to_pylist()] == [(100, 9, 7, 1)]


def test_event_stream_atis_keeps_change_detections_as_faery_does(tmp_path):
    import struct

    data = bytearray(b"Event Stream" + bytes([2, 0, 0, 2]) + struct.pack("<HH", 304, 240))

    def event(dt, on, crossing, x, y):
        data.extend([(dt << 2) | (on << 1) | crossing, x & 255, x >> 8, y & 255, y >> 8])

    event(5, 1, 0, 10, 20)
    event(3, 0, 0, 300, 7)
    event(2, 1, 1, 11, 21)  # an exposure measurement: skipped
    data.append(0xFF)  # +189 µs
    event(1, 0, 0, 12, 22)
    path = tmp_path / "atis.es"
    path.write_bytes(bytes(data))
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (304, 240)
    assert [tuple(r.values()) for r in table.to_pylist()] == [(5, 10, 219, 1), (8, 300, 232, 0), (200, 12, 217, 0)]
    pytest.importorskip("faery")
    assert_same(table, *faery_events(path))
    # cut inside the last event: the events before it, and the cut told, from a file and from a pipe
    cut = tmp_path / "cut.es"
    cut.write_bytes(bytes(data[:-2]))
    table = read_events_table(cut)
    assert table.num_rows == 2 and sch.camera_sources(table.schema)[0]["cut_bytes"] == 3
    from neurotac_cli.io import live

    stream = live.open_stream(str(cut), fmt="es", follow=True, idle_timeout=0.1)
    assert sum(batch.num_rows for batch in stream.batches) == 2 and "the last 3 bytes" in stream.notes[0]


def test_dvs128_aedat2_is_read_as_jaer_reads_it(tmp_path):
    # jAER DVS128 extractor: x = 127 - ((a >> 1) & 0x7F), y up = (a >> 8) & 0x7F, ON when raw bit 0 is 0
    header = b"#!AER-DAT2.0\r\n# AEChip: ch.unizh.ini.jaer.chip.retina.DVS128\r\n"
    records = np.array(
        [[(5 << 8) | (3 << 1) | 0, 10], [(0 << 8) | (127 << 1) | 1, 20], [0x8000, 25], [(127 << 8) | (0 << 1) | 1, 30]], dtype=">u4"
    )
    path = tmp_path / "dvs128.aedat"
    path.write_bytes(header + records.tobytes())
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (128, 128)
    assert [tuple(r.values()) for r in table.to_pylist()] == [(10, 124, 122, 1), (20, 0, 127, 0), (30, 127, 0, 0)]


def test_aedat2_32_bit_timestamps_are_unwrapped_in_a_file_and_in_a_stream(tmp_path):
    """jAER writes µs in 32 bits: after 71.6 minutes they start again at 0, and time must go on."""
    from neurotac_cli.io import live

    n = 1000
    t = (1 << 32) - 5000 + np.arange(n) * 10
    x, row = np.arange(n) % 240, np.arange(n) % 180
    words = np.empty((n, 2), ">u4")
    words[:, 0] = ((179 - row) << 22) | (x << 12) | (1 << 11)
    words[:, 1] = t & 0xFFFFFFFF
    header = b"#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.DAVIS240C\r\n"
    path = tmp_path / "long.aedat"
    path.write_bytes(header + words.tobytes())
    assert read_events_table(path).column("t").to_numpy().tolist() == t.tolist()
    decoder = live._decoder("aedat2", header, None)
    body = words.tobytes()
    streamed = np.concatenate([decoder.decode(body[: 8 * 400])[0], decoder.decode(body[8 * 400 :])[0]])
    assert streamed.tolist() == t.tolist()


@pytest.mark.parametrize("chip, given, size", [("CDAVIS", None, (640, 480)), ("DavisRGBW640", None, (640, 480)),
                                               ("DavisFuture", None, (240, 180)), ("DavisFuture", (640, 480), (640, 480))])
def test_jaer_chips_of_other_sizes_and_a_sensor_given_for_an_unknown_one(tmp_path, chip, given, size):
    n = 100
    x, row = np.arange(n) % size[0], np.arange(n) % size[1]
    words = np.empty((n, 2), ">u4")
    words[:, 0] = ((size[1] - 1 - row) << 22) | (x << 12) | (1 << 11)
    words[:, 1] = np.arange(n) * 10
    path = tmp_path / "chip.aedat"
    path.write_bytes(f"#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.{chip}\r\n".encode() + words.tobytes())
    table = read_events_table(path, sensor=given)
    assert sch.sensor_of(table.schema) == size and table.column("y").to_numpy().tolist() == row.tolist()


def test_a_dvs128_file_that_names_no_chip_is_told_from_its_addresses(tmp_path):
    rng = np.random.default_rng(1)
    n = 1000
    x, y_up, raw = rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
    words = np.empty((n, 2), ">u4")
    words[:, 0] = (y_up << 8) | ((127 - x) << 1) | raw
    words[:, 1] = np.arange(n) * 10
    path = tmp_path / "dvs128.aedat"
    path.write_bytes(b"#!AER-DAT2.0\r\n# This is a raw AE data file - do not edit\r\n" + words.tobytes())
    table = read_events_table(path)
    assert sch.sensor_of(table.schema) == (128, 128) and table.num_rows == n
    assert table.column("x").to_numpy().tolist() == x.tolist() and table.column("y").to_numpy().tolist() == (127 - y_up).tolist()
    from neurotac_cli.io import live

    stream = live.open_stream(str(path), fmt=None, follow=True, idle_timeout=0.1)  # followed: the same records, the same layout
    batches = list(stream.batches)
    streamed = {name: np.concatenate([batch.column(name).to_numpy() for batch in batches]) for name in "txyp"}
    assert sch.sensor_of(stream.schema) == (128, 128) and all(streamed[n].tolist() == table.column(n).to_pylist() for n in "txyp")
    davis = real_file("davis240c_rotdisk.aedat").read_bytes().replace(b"AEChip:", b"AEChap:", 1)
    (tmp_path / "davis.aedat").write_bytes(davis)
    assert read_events_table(tmp_path / "davis.aedat", sensor=(240, 180)).num_rows == 374_296  # still the DAVIS layout
    stream = live.open_stream(str(tmp_path / "davis.aedat"), sensor=(240, 180), follow=True, idle_timeout=0.1)
    assert sum(batch.num_rows for batch in stream.batches) == 374_296


def test_an_atis_dat_file_before_version_2_is_read_with_its_own_address_layout(tmp_path):
    from neurotac_cli.io import live

    rng = np.random.default_rng(1)
    n = 500
    x, y, p = rng.integers(0, 304, n), rng.integers(0, 240, n), rng.integers(0, 2, n)
    records = np.empty((n, 2), "<u4")
    records[:, 0], records[:, 1] = np.arange(n) * 10, x | (y << 9) | (p << 17)
    header = b"% Data file containing CD events.\n% Version 1\n"
    path = tmp_path / "v1.dat"
    path.write_bytes(header + bytes([0, 8]) + records.tobytes())
    table = read_events_table(path)
    assert [table.column(c).to_numpy().tolist() for c in "xyp"] == [x.tolist(), y.tolist(), p.tolist()]
    streamed = live._decoder("dat", header + bytes([0, 8]), None).decode(records.tobytes())
    assert streamed[1].tolist() == x.tolist() and streamed[2].tolist() == y.tolist()


def test_an_aedat4_files_second_events_stream_is_named_as_not_read(tmp_path):
    import struct

    from neurotac_cli.export import aedat4_bytes
    from neurotac_cli.io import events

    one = aedat4_bytes(np.arange(50), np.arange(50) % 64, np.arange(50) % 48, np.arange(50) % 2, 64, 48)
    length = struct.unpack("<I", one[14:18])[0]
    header, packets = one[18 : 18 + length], one[18 + length :]
    start, end = header.index(b"<dv"), header.index(b"</dv>")
    second = header[header.index(b'<node name="0"'):end - len(b"</node>")].replace(b'name="0"', b'name="1"').replace(
        b"outInfo/0/", b"outInfo/1/").replace(b">events<", b">events_undistorted<")
    description = header[start:end - len(b"</node>")] + second + b"</node></dv>"
    rebuilt = header[: start - 4] + struct.pack("<I", len(description)) + description + b"\0"
    rebuilt += b"\0" * (-len(rebuilt) % 4)
    path = tmp_path / "two.aedat4"
    path.write_bytes(one[:14] + struct.pack("<I", len(rebuilt)) + rebuilt + packets + struct.pack("<I", 1) + packets[4:])
    table = read_events_table(path)
    assert table.num_rows == 50
    assert events.source_notes(table.schema) == ["two.aedat4: events stream(s) events_undistorted not read (the first, events, is)"]
    from neurotac_cli.io import live

    stream = live.open_stream(str(path), follow=True, idle_timeout=0.1)  # followed, the same note
    assert sum(batch.num_rows for batch in stream.batches) == 50
    assert events.source_notes(stream.schema) == ["two.aedat4: events stream(s) events_undistorted not read (the first, events, is)"]


def test_a_time_origin_in_a_prophesee_header_is_added_as_faery_adds_it(tmp_path):
    """faery writes `% t0 N` (`% T0 N` in DAT) into the files it converts, their times counted from N."""
    import struct

    from neurotac_cli.io import live

    header = b"% evt 2.0\n% format EVT2;width=1280;height=720\n% geometry 1280x720\n% t0 913716224\n% end\n"
    words = struct.pack("<2I", 0x8 << 28, (1 << 28) | (5 << 22) | (100 << 11) | 200)
    (tmp_path / "t0.raw").write_bytes(header + words)
    assert read_events_table(tmp_path / "t0.raw").column("t").to_pylist() == [913716229]
    assert live._decoder("evt2", header, None).decode(words)[0].tolist() == [913716229]
    dat_header = b"% Data file containing CD events.\n% Version 2\n% Width 304\n% Height 240\n% T0 1000\n"
    (tmp_path / "t0.dat").write_bytes(dat_header + bytes([0, 8]) + struct.pack("<2I", 5, 10 | (20 << 14)))
    assert read_events_table(tmp_path / "t0.dat").column("t").to_pylist() == [1005]


def test_an_aedat4_file_whose_packets_end_before_its_index_table_is_refused_not_read_in_part(tmp_path):
    """A damaged packet header read as the index table dropped the rest of the file without a word."""
    import struct

    from neurotac_cli.errors import FormatError
    from neurotac_cli.export import aedat4_bytes
    from neurotac_cli.io import live

    data = bytearray(real_file("davis346_aestream.aedat4").read_bytes())
    offset = 18 + struct.unpack_from("<I", data, 14)[0]
    for _ in range(20):  # the 21st packet's stream id damaged
        offset += 8 + struct.unpack_from("<I", data, offset + 4)[0]
    struct.pack_into("<i", data, offset, 77)
    damaged = tmp_path / "damaged.aedat4"
    damaged.write_bytes(bytes(data))
    with pytest.raises(FormatError, match=f"from byte {offset:,} are no packet of a declared stream, where the index table is not"):
        read_events_table(damaged)
    header_end = 18 + struct.unpack_from("<I", data, 14)[0]
    decoder = live._decoder("aedat4", bytes(data[:header_end]), None)  # piped: the same file as its bytes arrive
    try:
        with pytest.raises(FormatError, match=f"from byte {offset:,} are no packet of a declared stream"):
            decoder.complete(bytearray(data[header_end:]))
    finally:
        decoder.close()
    one = aedat4_bytes(np.arange(50), np.arange(50) % 64, np.arange(50) % 48, np.arange(50) % 2, 64, 48)
    (tmp_path / "two.aedat4").write_bytes(one + one)  # two files joined
    with pytest.raises(FormatError, match="a damaged file, or two joined"):
        read_events_table(tmp_path / "two.aedat4")
    assert read_events_table(real_file("davis346_aestream.aedat4")).num_rows == 117_667  # the index table itself: read whole
    from neurotac_cli.io import aedat4

    unstated = bytearray(real_file("davis346_aestream.aedat4").read_bytes())  # a writer that never updated its header
    struct.pack_into("<q", unstated, aedat4.table_offset(bytes(unstated)), -1)
    (tmp_path / "unstated.aedat4").write_bytes(bytes(unstated))
    assert read_events_table(tmp_path / "unstated.aedat4").num_rows == 117_667
