"""Prophesee EVT 2.1: files written here in OpenEB's word layout (its decoder's bit fields, both word
orders) from a real recording's events, read back event for event, and against evlib's reader."""

import numpy as np
import pytest

from neurotac_cli import schema as sch
from neurotac_cli.errors import FormatError
from neurotac_cli.io import read_events_table, reader
from tests.conftest import real_file

HEADER = b"%% evt 2.1\n%% format EVT21;%sheight=720;width=1280\n%% end\n"


def encode(t, x, y, p, legacy=False, triggers=(), start_high=0):
    """EVT 2.1 words for time-ordered events: a TIME_HIGH for every 64 µs step (from `start_high`),
    CD vectors of consecutive events with one (t, y, p) within one 32-pixel block, x rising."""
    words, high, i, pending = [], start_high - 1, 0, sorted(triggers)

    def walk(to):
        nonlocal high
        while high < to >> 6:
            high += 1
            words.append(((0x8 << 28) | (high & 0x0FFFFFFF), 0))

    while i < len(t) or pending:
        if pending and (i >= len(t) or pending[0][0] <= t[i]):
            when, value, channel = pending.pop(0)
            walk(when)
            words.append(((0xA << 28) | ((when & 63) << 22) | (channel << 8) | value, 0))
            continue
        walk(int(t[i]))
        base, mask, j = int(x[i]) & ~31, 0, i
        while (j < len(t) and t[j] == t[i] and y[j] == y[i] and p[j] == p[i] and int(x[j]) & ~31 == base
               and (j == i or x[j] > x[j - 1])):
            mask |= 1 << (int(x[j]) - base)
            j += 1
        words.append(((int(p[i]) << 28) | ((int(t[i]) & 63) << 22) | (base << 11) | int(y[i]), mask))
        i = j
    pairs = np.array(words, dtype=np.uint64).astype("<u4")  # (fields, mask) per word
    return np.ascontiguousarray(pairs if legacy else pairs[:, ::-1]).tobytes()


@pytest.fixture(scope="module")
def real():
    table = read_events_table(real_file("prophesee_hd_expelliarmus.evt3.raw"))
    t, x, y, p = (table.column(c).to_numpy() for c in "txyp")
    order = np.lexsort((x, p, y, t))  # EVT 2.1 needs time order; vectors group one row's pixels
    return t[order], x[order], y[order], p[order]


def same(table, t, x, y, p):
    return all(np.array_equal(table.column(c).to_numpy(), v) for c, v in zip("txyp", (t, x, y, p)))


@pytest.mark.parametrize("order", ["little", "legacy"])
def test_a_real_recording_reads_back_in_either_word_order_from_the_header_or_the_words(real, tmp_path, order):
    data = encode(*real, legacy=order == "legacy")
    for name, header in (("said.raw", HEADER % (b"endianness=legacy;" if order == "legacy" else b"")),
                         ("unsaid.raw", b"% evt 2.1\n% geometry 1280x720\n% end\n")):
        (tmp_path / name).write_bytes(header + data)
        table = read_events_table(tmp_path / name)
        assert same(table, *real), name
        assert sch.get_meta(table.schema, "neurotac:source")["evt21_order"] == order
        assert sch.sensor_of(table.schema) == (1280, 720)


def test_evlib_reads_the_same_events(real, tmp_path):
    evlib = pytest.importorskip("evlib")
    path = tmp_path / "e.raw"
    path.write_bytes(HEADER % b"" + encode(*real))
    theirs = evlib.load_events(str(path)).collect()
    t, x, y, p = real
    assert np.array_equal(theirs["t"].cast(int).to_numpy(), t)
    assert np.array_equal(theirs["x"].to_numpy(), x) and np.array_equal(theirs["y"].to_numpy(), y)
    assert np.array_equal(theirs["polarity"].to_numpy() > 0, p > 0)


def test_chunks_triggers_wraps_and_a_cut_last_word(real, tmp_path, monkeypatch):
    t, x, y, p = (v[:3000] for v in real)
    triggers = [(int(t[10]), 1, 2), (int(t[2000]), 0, 2)]
    path = tmp_path / "c.raw"
    path.write_bytes(HEADER % b"" + encode(t, x, y, p, triggers=triggers) + b"\x01\x02\x03")
    monkeypatch.setattr(reader, "CHUNK_BYTES", 4096)  # a few hundred words a chunk
    table = read_events_table(path)
    assert same(table, t, x, y, p)
    assert sch.get_meta(table.schema, "neurotac:triggers") == [
        {"t": triggers[0][0], "type": "rising", "id": 2}, {"t": triggers[1][0], "type": "falling", "id": 2}]
    assert sch.get_meta(table.schema, "neurotac:source")["cut_bytes"] == 3
    # the 28-bit time high wraps after 2^34 µs: a fall back to 0 is a loop
    late = np.array([(1 << 34) - 100, (1 << 34) - 10, (1 << 34) + 5, (1 << 34) + 70], dtype=np.int64)
    words = encode(late, np.array([1, 2, 3, 4]), np.array([5, 5, 5, 5]), np.array([1, 0, 1, 0]), start_high=int(late[0]) >> 6)
    (tmp_path / "w.raw").write_bytes(HEADER % b"" + words)
    assert np.array_equal(read_events_table(tmp_path / "w.raw").column("t").to_numpy(), late)


def test_words_that_fit_neither_order_are_refused(tmp_path):
    path = tmp_path / "bad.raw"
    path.write_bytes(b"% evt 2.1\n% end\n" + np.random.default_rng(0).integers(0, 2**32, 64, dtype=np.uint64).astype("<u4").tobytes())
    with pytest.raises(FormatError, match="fit neither word order"):
        read_events_table(path)
    path.write_bytes(b"% format EVT21;endianness=big\n% end\n" + bytes(16))
    with pytest.raises(FormatError, match="endianness 'big'"):
        read_events_table(path)


@pytest.mark.parametrize("header", [HEADER % b"endianness=legacy;", b"% evt 2.1\n% geometry 1280x720\n% end\n"])
def test_a_followed_file_written_mid_word_gives_the_files_events(real, tmp_path, header):
    from neurotac_cli.io import live
    from tests.io.test_live import collect, write_in_pieces

    t, x, y, p = (v[:20000] for v in real)
    data = header + encode(t, x, y, p, legacy=b"legacy" in header or b"format" not in header, start_high=int(t[0]) >> 6)
    path = tmp_path / "cam.raw"
    path.write_bytes(b"")
    writer = write_in_pieces(data, path)
    table, batches = collect(live.open_stream(str(path), follow=True, idle_timeout=0.5))
    writer.join()
    assert batches > 1 and same(table, t, x, y, p)
    # the order is in the stream's metadata, as a file's: from the header, or found in the words
    assert sch.get_meta(table.schema, "neurotac:source").get("evt21_order") == "legacy"


UNSAID = b"% evt 2.1\n% geometry 1280x720\n% end\n"


def joined_before_a_time_high(t, x, y, p, legacy: bool) -> bytes:
    """EVT 2.1 words of a stream joined mid-recording: CD words with no time base come first."""
    data = encode(t, x, y, p, legacy=legacy, start_high=int(t[0]) >> 6)
    words = np.frombuffer(data, dtype="<u4").reshape(-1, 2)
    kinds = words[:, 0 if legacy else 1] >> 28
    return np.ascontiguousarray(words[kinds != 0x8][:300]).tobytes() + data


@pytest.mark.parametrize("order", ["little", "legacy"])
def test_a_piped_stream_whose_order_is_told_from_its_words_writes_that_order_in_its_metadata(real, tmp_path, order):
    import subprocess

    import pyarrow as pa

    from tests.io.test_live import fifo_of

    t, x, y, p = (v[:20000] for v in real)
    data = UNSAID + joined_before_a_time_high(t, x, y, p, legacy=order == "legacy")
    (tmp_path / "cam.raw").write_bytes(data)
    whole = read_events_table(tmp_path / "cam.raw")
    done = subprocess.run(["neurotac", "import", fifo_of(tmp_path, data)], capture_output=True)
    assert done.returncode == 0, done.stderr
    piped = pa.ipc.open_stream(done.stdout).read_all()  # the Arrow IPC stream `import` writes on a pipe
    assert same(piped, t, x, y, p) and same(whole, t, x, y, p)
    for table in (piped, whole):
        assert sch.get_meta(table.schema, "neurotac:source")["evt21_order"] == order


def test_a_stream_that_ends_before_any_time_high_has_the_files_default_order(real, tmp_path):
    from neurotac_cli.io import live

    t, x, y, p = (v[:200] for v in real)
    data = UNSAID + joined_before_a_time_high(t, x, y, p, legacy=True)[: 8 * 5]
    (tmp_path / "cam.raw").write_bytes(data)
    whole = read_events_table(tmp_path / "cam.raw")
    stream = live.open_stream(str(tmp_path / "cam.raw"), follow=True, idle_timeout=0.2)
    assert not sum(batch.num_rows for batch in stream.batches)
    assert sch.get_meta(stream.schema, "neurotac:source")["evt21_order"] == "little"
    assert sch.get_meta(whole.schema, "neurotac:source")["evt21_order"] == "little"


def test_a_wrap_across_a_missing_time_high_is_still_a_wrap(tmp_path):
    """A TIME_HIGH that falls back by more than half its range is a wrap, even when the words of the
    top values were dropped (a camera under load, a recording cut and joined)."""
    late = np.array([(1 << 34) - 300, (1 << 34) + 150], dtype=np.int64)
    words = np.frombuffer(encode(late, np.array([1, 2]), np.array([5, 5]), np.array([1, 0]), start_high=int(late[0]) >> 6), dtype="<u4")
    pairs = words.reshape(-1, 2)
    highs = pairs[:, 1] >> 28 == 0x8
    top = highs & ((pairs[:, 1] & 0x0FFFFFFF) >= (1 << 28) - 2)  # drop the last two TIME_HIGHs before the wrap
    (tmp_path / "gap.raw").write_bytes(HEADER % b"" + np.ascontiguousarray(pairs[~top]).tobytes())
    assert np.array_equal(read_events_table(tmp_path / "gap.raw").column("t").to_numpy(), late)


def test_a_stream_whose_first_read_holds_no_time_high_waits_for_one(real):
    """Without an order in the header, the live decoder decides at the first words that tell it."""
    from neurotac_cli.io import live_decoders

    t, x, y, p = (v[:2000] for v in real)
    data = encode(t, x, y, p, legacy=True, start_high=int(t[0]) >> 6)
    words = np.frombuffer(data, dtype="<u4").reshape(-1, 2)
    no_high = words[words[:, 0] >> 28 != 0x8][:5]  # CD words of a stream joined before its first TIME_HIGH
    decoder = live_decoders.Evt21(b"% evt 2.1\n% end\n", None)
    assert not len(decoder.decode(np.ascontiguousarray(no_high).tobytes())[0])
    decoded = decoder.decode(data)
    assert decoder.legacy and np.array_equal(decoded[0], t)


def test_a_stream_whose_header_arrives_alone_waits_for_words_before_choosing_an_order():
    from neurotac_cli.io import live_decoders

    decoder = live_decoders.Evt21(b"% evt 2.1\n% end\n", None)
    assert decoder.settled(bytearray(), at_end=False) is False and decoder.legacy is None
    assert decoder.settled(bytearray(), at_end=True) is True and decoder.legacy is False  # OpenEB's default, as a file
