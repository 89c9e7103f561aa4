"""Decoding speed of `neurotac import` against the peer readers, measured in the same run.

Our reader (`read_events_table`: file -> Arrow table with t, x, y, p) against every peer among
evlib, faery, aedat and expelliarmus that reads the same file (full decode to arrays). Best of
REPEATS runs after one warm-up each (the page cache and the allocator warm up). Prints the time of each and the ratio peer/ours (> 1: ours is faster), and checks the
goals: ours at least as fast as the fastest peer on the DAVIS240C AEDAT 2.0 file and the EVT 3.0
file; the text reader at least 5x faster than numpy.loadtxt. Also checks that memory stays flat
while a large file streams through `read_events` in chunks.

    .venv/bin/python -m pytest -q -s tests/bench/bench_import.py -o addopts=""
    .venv/bin/python tests/bench/bench_import.py
"""

import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

warnings.filterwarnings("ignore")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
REAL = Path(os.environ.get("NEUROTAC_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))
REPEATS = 15

from neurotac_cli.io import read_events_table  # noqa: E402


def best_time(function, repeats=REPEATS) -> float:
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def _faery(path):
    import faery

    chunks = list(faery.events_stream_from_file(str(path)))
    return np.concatenate(chunks) if chunks else None


def _evlib(path):
    import evlib

    return evlib.load_events(str(path)).collect()


def _expelliarmus(encoding):
    def read(path):
        from expelliarmus import Wizard

        return Wizard(encoding=encoding).read(str(path))

    return read


def _aedat(path):
    import aedat

    return [packet for packet in aedat.Decoder(str(path)) if "events" in packet]


def _tonic_numpy(path):
    """tonic's AEDAT 2.0 reader (raw address and timestamp words) decoded with numpy, as a tonic user
    would: the only pipeline among the peers' that reads a DAVIS AEDAT 2.0 file right."""
    import tonic.io

    version, start = tonic.io.read_aedat_header_from_file(str(path))[:2]
    raw = tonic.io.get_aer_events_from_file(str(path), version, start)
    address = raw["address"]
    keep = (address & np.uint32(0x80000400)) == 0
    address = address[keep]
    return np.rec.fromarrays(
        [raw["timeStamp"][keep].astype(np.int64), (address >> 12) & 0x3FF, 179 - ((address >> 22) & 0x1FF), (address >> 11) & 1],
        names="t,x,y,p",
    )


PEERS = {
    "davis240c_rotdisk.aedat": {"evlib": _evlib, "faery": _faery, "aedat": _aedat, "tonic+numpy": _tonic_numpy},
    "prophesee_hd_expelliarmus.evt3.raw": {"evlib": _evlib, "faery": _faery, "expelliarmus": _expelliarmus("evt3")},
    "prophesee_vga_faery.evt2.raw": {"evlib": _evlib, "faery": _faery, "expelliarmus": _expelliarmus("evt2")},
    "davis346_aestream.aedat4": {"evlib": _evlib, "faery": _faery, "aedat": _aedat},
    "atis_ncars_loris.dat": {"evlib": _evlib, "faery": _faery, "expelliarmus": _expelliarmus("dat")},
    "atis_ncars_loris.es": {"evlib": _evlib, "faery": _faery},
}
GOALS = ("davis240c_rotdisk.aedat", "prophesee_hd_expelliarmus.evt3.raw")


def measure_file(name: str) -> dict:
    """Times (s) of ours and of each peer on one file; a peer that cannot read it (or reads a different
    number of events) gets the reason instead of a time."""
    path = REAL / name  # an absolute path stays as it is
    rows = read_events_table(path).num_rows
    result = {"ours": best_time(lambda: read_events_table(path)), "rows": rows, "peers": {}}
    for peer, read in PEERS[name].items():
        try:
            out = read(path)
            count = _count(out)
        except Exception as error:  # a peer that fails on this file is reported, not fatal
            result["peers"][peer] = f"cannot read it ({str(error).splitlines()[0][:70]})"
            continue
        if count != rows:
            result["peers"][peer] = f"reads {count} events, not {rows}"
            continue
        result["peers"][peer] = best_time(lambda: read(path))
    return result


def _count(out) -> int:
    if out is None:
        return 0
    if isinstance(out, list):
        return sum(len(packet["events"]) for packet in out)
    return len(out)


def report(name: str, result: dict) -> float | None:
    """Print one file's line; return the ratio fastest-peer / ours, or None when no peer reads it."""
    timed = {peer: t for peer, t in result["peers"].items() if isinstance(t, float)}
    parts = [f"ours {result['ours'] * 1e3:7.2f} ms"]
    for peer, value in result["peers"].items():
        parts.append(f"{peer} {value * 1e3:.2f} ms (x{value / result['ours']:.2f})" if isinstance(value, float) else f"{peer}: {value}")
    print(f"{name} ({result['rows']:,} events): " + "; ".join(parts))
    if not timed:
        return None
    return min(timed.values()) / result["ours"]


def measure_text(rows=300_000) -> dict:
    """Ours against numpy.loadtxt as it is usually called (default float64), and, for the CSV of
    integers, against loadtxt told the integer dtype (its fastest path)."""
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, 10**9, rows))
    x, y, p = rng.integers(0, 240, rows), rng.integers(0, 180, rows), rng.integers(0, 2, rows)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "events.csv"
        with open(path, "w") as handle:
            handle.write("t,x,y,p\n")
            np.savetxt(handle, np.column_stack([t, x, y, p]), fmt="%d", delimiter=",")
        spaced = Path(folder) / "events.txt"
        with open(spaced, "w") as handle:
            np.savetxt(handle, np.column_stack([t / 1e6, x, y, p]), fmt=["%.6f", "%d", "%d", "%d"], delimiter=" ")
        assert read_events_table(path).num_rows == rows and read_events_table(spaced).num_rows == rows
        times = {
            "csv ours": best_time(lambda: read_events_table(path, sensor=(240, 180)), repeats=5),
            "csv loadtxt": best_time(lambda: np.loadtxt(path, delimiter=",", skiprows=1), repeats=3),
            "csv loadtxt int64": best_time(lambda: np.loadtxt(path, delimiter=",", skiprows=1, dtype=np.int64), repeats=3),
            "txt ours": best_time(lambda: read_events_table(spaced, sensor=(240, 180)), repeats=5),
            "txt loadtxt": best_time(lambda: np.loadtxt(spaced), repeats=3),
        }
    ratios = {
        "csv": times["csv loadtxt"] / times["csv ours"],
        "csv_int64": times["csv loadtxt int64"] / times["csv ours"],
        "txt": times["txt loadtxt"] / times["txt ours"],
    }
    print(
        f"text {rows:,} rows: CSV t,x,y,p ours {times['csv ours'] * 1e3:.1f} ms, numpy.loadtxt {times['csv loadtxt'] * 1e3:.1f} ms "
        f"(x{ratios['csv']:.1f}), loadtxt dtype=int64 {times['csv loadtxt int64'] * 1e3:.1f} ms (x{ratios['csv_int64']:.1f}); "
        f"whitespace t x y p (s) ours {times['txt ours'] * 1e3:.1f} ms, numpy.loadtxt {times['txt loadtxt'] * 1e3:.1f} ms (x{ratios['txt']:.1f})"
    )
    return ratios


MEMORY_SCRIPT = """
import resource, sys
sys.path.insert(0, {root!r})
from neurotac_cli.io import read_events
schema, batches = read_events(sys.argv[1])
rows = sum(batch.num_rows for batch in batches)
print(rows, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def measure_memory(events=(1_000_000, 16_000_000)) -> list[tuple[int, int]]:
    """Peak resident memory (KiB) of streaming an AEDAT 2.0 file of each size through read_events."""
    from neurotac_cli.io.writers import aedat2_bytes

    peaks = []
    with tempfile.TemporaryDirectory() as folder:
        for n in events:
            rng = np.random.default_rng(1)
            path = Path(folder) / f"big{n}.aedat"
            block = 1_000_000
            with open(path, "wb") as handle:
                for start in range(0, n, block):
                    m = min(block, n - start)
                    data = aedat2_bytes(np.arange(start, start + m), rng.integers(0, 240, m), rng.integers(0, 180, m), rng.integers(0, 2, m))
                    handle.write(data if start == 0 else data[_header_length(data) :])
            done = subprocess.run([sys.executable, "-c", MEMORY_SCRIPT.format(root=str(ROOT)), str(path)], capture_output=True, text=True, check=True)
            rows, peak = map(int, done.stdout.split())
            assert rows == n
            peaks.append((n, peak))
    print("streaming memory: " + ", ".join(f"{n:,} events ({n * 8 / 2**20:.0f} MiB file) peak {peak / 1024:.0f} MiB" for n, peak in peaks))
    return peaks


def _header_length(data: bytes) -> int:
    from neurotac_cli.io.aedat2 import header_length

    return header_length(data)


def test_import_is_at_least_as_fast_as_the_fastest_peer():
    ratios = {}
    for name in PEERS:
        if (REAL / name).is_file():
            ratios[name] = report(name, measure_file(name))
    for name in GOALS:
        if name in ratios and ratios[name] is not None:
            assert ratios[name] >= 1.0, f"{name}: the fastest peer is {ratios[name]:.2f}x our time"


def test_evt21_against_the_peers():
    """No EVT 2.1 recording is among the shared ones: the EVT 3.0 recording's events are written as
    EVT 2.1 (little word order, which evlib reads; the tests' encoder) and timed like the others."""
    from tests.io.test_evt21 import encode

    source = REAL / "prophesee_hd_expelliarmus.evt3.raw"
    if not source.is_file():
        return
    table = read_events_table(source)
    words = encode(*(table.column(c).to_numpy() for c in "txyp"))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "hd.evt21.raw"
        path.write_bytes(b"% evt 2.1\n% format EVT21;endianness=little;height=720;width=1280\n% end\n" + bytes(words))
        PEERS[path] = {"evlib": _evlib, "faery": _faery, "expelliarmus": _expelliarmus("evt21")}
        try:
            ratio = report(path.name, measure_file(path))
        finally:
            del PEERS[path]
    assert ratio is None or ratio >= 1.0, f"EVT 2.1: the fastest peer is {ratio:.2f}x our time"


def test_text_reader_is_at_least_5x_faster_than_loadtxt():
    ratios = measure_text()
    assert ratios["csv"] >= 5 and ratios["txt"] >= 5


def test_memory_does_not_grow_with_the_file():
    (small, small_peak), (large, large_peak) = measure_memory()
    assert large_peak - small_peak < 64 * 1024, "streaming a 16x larger file should not need much more memory"


if __name__ == "__main__":
    test_import_is_at_least_as_fast_as_the_fastest_peer()
    test_evt21_against_the_peers()
    test_text_reader_is_at_least_5x_faster_than_loadtxt()
    test_memory_does_not_grow_with_the_file()
