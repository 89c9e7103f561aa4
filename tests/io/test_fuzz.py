"""Every reader, fuzzed: random bytes behind each format's magic, and real files truncated, bit-flipped
and with their headers mangled. The only outcomes allowed are a valid events table or one
NeurotacError: never another exception (a traceback for a user), never a hang."""

import os
import signal
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError
from neurotac_cli.io import read_events_table
from tests.conftest import REAL_DATA

SECONDS = 20
MAGICS = [
    b"#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.DAVIS240C\r\n",
    b"#!AER-DAT2.0\r\n",
    b"#!AER-DAT2.0\r\n# AEChip: ch.unizh.ini.jaer.chip.retina.DVS128\r\n",
    b"#!AER-DAT3.1\r\n#Source 1: DAVIS240C\r\n#!END-HEADER\r\n",
    b"#!AER-DAT4.0\r\n",
    b"% evt 2.0\n",
    b"% evt 3.0\n",
    b"% evt 2.1\n",
    b"% evt 2.1\n% format EVT21;endianness=legacy;height=720;width=1280\n% end\n",
    b"\x89HDF\r\n\x1a\n",
    b"% Data file containing events.\n% Version 2\n",
    b"Event Stream\x02\x00\x00\x01\xf0\x00\xb4\x00",
    b"Event Stream\x02\x00\x00\x02\x30\x01\xf0\x00",
    b"t,x,y,p\n",
    b"",
]
REAL = [
    "davis240c_rotdisk.aedat",
    "header_only_tonic.aedat",
    "davis346_aestream.aedat4",
    "dvxplorer_tonic.aedat4",
    "prophesee_vga_faery.evt2.raw",
    "prophesee_hd_expelliarmus.evt3.raw",
    "atis_ncars_loris.dat",
    "atis_ncars_loris.es",
]
FUZZ = settings(max_examples=int(os.environ.get("NEUROTAC_FUZZ_EXAMPLES", "40")), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


class Hang(Exception):
    pass


@contextmanager
def time_limit(seconds):
    def alarm(signum, frame):
        raise Hang(f"reader ran over {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def outcome(data: bytes, suffix: str = ".bin"):
    """Read `data` as a camera file: the table, or the NeurotacError. Anything else fails the test."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"fuzz{suffix}"
        path.write_bytes(data)
        with time_limit(SECONDS):
            try:
                table = read_events_table(path)
            except NeurotacError as error:
                message = str(error)
                assert message and "\n" not in message and "Traceback" not in message
                return error
    assert sch.kind_of(table.schema) == "events"
    assert table.schema.names == ["t", "x", "y", "p"]
    width, height = sch.sensor_of(table.schema)
    if table.num_rows:
        assert table["x"].to_numpy().max() < width and table["y"].to_numpy().max() < height
        assert table["p"].to_numpy().max() <= 1
    return table


_cache = {}


def real_bytes(name: str, limit: int = 1 << 16) -> bytes:
    """The first `limit` bytes of a real recording (fuzzing the whole file would be slow, and the
    cut is one more truncation)."""
    path = REAL_DATA / name
    if not path.is_file():
        pytest.skip(f"real recording {name} not found in {REAL_DATA}")
    if name not in _cache:
        _cache[name] = path.read_bytes()
    data = _cache[name]
    if name.endswith(".aedat4"):
        return data  # AEDAT 4.0 keeps its packet table at the end of the file
    if name.endswith(".aedat"):
        from neurotac_cli.io.aedat2 import header_length

        limit += header_length(data)  # jAER headers hold long preferences
    return data[:limit]


@FUZZ
@given(magic=st.sampled_from(MAGICS), body=st.binary(max_size=4096))
def test_random_bytes_behind_a_format_magic(magic, body):
    outcome(magic + body)


@FUZZ
@given(body=st.binary(min_size=1, max_size=2048))
def test_random_bytes(body):
    outcome(body)


@FUZZ
@given(text=st.text(alphabet="0123456789.,-+ e\tnaxyptsu_\n#", max_size=400))
def test_random_text(text):
    outcome(("t,x,y,p\n" + text).encode(), ".csv")
    outcome(text.encode(), ".txt")


@pytest.mark.parametrize("name", REAL)
@FUZZ
@given(cut=st.floats(0, 1))
def test_real_file_truncated(name, cut):
    data = real_bytes(name)
    outcome(data[: int(len(data) * cut)], Path(name).suffix)


@pytest.mark.parametrize("name", REAL)
@FUZZ
@given(flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 7)), min_size=1, max_size=8))
def test_real_file_bit_flipped(name, flips):
    data = bytearray(real_bytes(name))
    for where, bit in flips:
        data[int(where * len(data))] ^= 1 << bit
    outcome(bytes(data), Path(name).suffix)


@pytest.mark.parametrize("name", REAL)
@FUZZ
@given(start=st.integers(0, 400), junk=st.binary(min_size=1, max_size=64))
def test_real_file_header_mangled(name, start, junk):
    data = real_bytes(name)
    outcome(data[:start] + junk + data[start + len(junk) :], Path(name).suffix)


def test_a_bit_flip_in_a_davis_address_is_a_clear_error_or_a_valid_event():
    data = bytearray(real_bytes("davis240c_rotdisk.aedat"))
    result = outcome(bytes(data))
    assert result.num_rows > 0
    rng = np.random.default_rng(0)
    for _ in range(20):
        damaged = bytearray(data)
        damaged[int(rng.integers(len(data) // 2, len(data)))] ^= 0x40
        outcome(bytes(damaged))


def written_bytes(kind: str) -> bytes:
    """A file of a format no shared recording is in, written here from a real recording's events:
    HDF5 in each layout, EVT 2.1 in both word orders."""
    if kind not in _cache:
        from neurotac_cli.io import read_events_table
        from tests.io.test_evt21 import HEADER, encode
        from tests.io.test_hdf5 import write

        if kind.startswith("hdf5"):
            table = read_events_table(REAL_DATA / "davis346_aestream.aedat4")
            t, x, y, p = (table.column(c).to_numpy()[:2000] for c in "txyp")
            with tempfile.TemporaryDirectory() as folder:
                path = Path(folder) / "f.h5"
                write(path, kind.split("-")[1], t, x, y, p, 346, 260)
                _cache[kind] = path.read_bytes()
        else:
            table = read_events_table(REAL_DATA / "prophesee_hd_expelliarmus.evt3.raw")
            t, x, y, p = (table.column(c).to_numpy()[:3000] for c in "txyp")
            order = np.lexsort((x, p, y, t))
            legacy = kind.endswith("legacy")
            header = HEADER % (b"endianness=legacy;" if legacy else b"") if "said" in kind else b"% evt 2.1\n% end\n"
            _cache[kind] = header + encode(t[order], x[order], y[order], p[order], legacy=legacy, start_high=int(t[order][0]) >> 6)
    return _cache[kind]


WRITTEN = ["hdf5-metavision", "hdf5-dsec", "hdf5-e2vid", "evt21-said-little", "evt21-said-legacy", "evt21-unsaid-legacy"]


@pytest.mark.parametrize("kind", WRITTEN)
@FUZZ
@given(cut=st.floats(0, 1), flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 7)), max_size=8))
def test_written_file_cut_and_bit_flipped(kind, cut, flips):
    if not REAL_DATA.is_dir():
        pytest.skip(f"real recordings not found at {REAL_DATA}")
    data = bytearray(written_bytes(kind))
    for where, bit in flips:
        data[int(where * len(data))] ^= 1 << bit
    outcome(bytes(data[: max(8, int(len(data) * cut))]), ".h5" if kind.startswith("hdf5") else ".raw")
