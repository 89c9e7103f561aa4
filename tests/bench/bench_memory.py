"""Benchmark: peak memory of `neurotac import FILE | neurotac frame --window W > /dev/null`, measured
per process with /usr/bin/time -v (maximum resident set size), on 10^7 to 10^8 events and on tiny
windows. The goal (issue "nothing unbounded"): under 1 GB for any window and any recording up to
10^8 events. Run on demand (not part of `make test`; 10^8 events take minutes and an 800 MB file):

    .venv/bin/python tests/bench/bench_memory.py                       # 1e7 and 1e8 events, tiny windows
    BENCH_MEMORY_EVENTS=1e7 .venv/bin/python tests/bench/bench_memory.py
    .venv/bin/python -m pytest -q -s tests/bench/bench_memory.py -o addopts=""

The camera file is AEDAT 2.0 (DAVIS240C, 240x180) at 10^6 events/s, written chunk by chunk into a
temporary folder (BENCH_MEMORY_DIR, default the system's). Each pipeline runs under `ulimit -v`
(BENCH_MEMORY_LIMIT_GB, default 6) and a time limit (BENCH_MEMORY_TIMEOUT_S, default 600), so a
step that does not stream ends in one out-of-memory line instead of taking the machine; such a
row says what the command printed. /usr/bin/time comes from the `time` package (apt-get install time).
"""

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

RATE_PER_S = 1_000_000
CHUNK = 2_000_000
WIDTH, HEIGHT = 240, 180
EVENTS = [int(float(n)) for n in os.environ.get("BENCH_MEMORY_EVENTS", "1e7,1e8").split(",")]
TINY = [(1_000_000, window) for window in ("100us", "10us", "1us")]  # 1 s of events: 10^4..10^6 windows
LIMIT_GB = float(os.environ.get("BENCH_MEMORY_LIMIT_GB", "6"))
TIMEOUT_S = int(os.environ.get("BENCH_MEMORY_TIMEOUT_S", "600"))


def write_camera_file(path: Path, n: int, seed: int = 0) -> None:
    """n events at RATE_PER_S, uniform over the sensor, written CHUNK events at a time."""
    from neurotac_cli.io.writers import aedat2_bytes

    rng = np.random.default_rng(seed)
    header = len(aedat2_bytes([], [], [], []))
    with open(path, "wb") as sink:
        for start in range(0, n, CHUNK):
            m = min(CHUNK, n - start)
            t0 = start * 1_000_000 // RATE_PER_S
            t = np.sort(rng.integers(t0, t0 + m * 1_000_000 // RATE_PER_S, m))
            data = aedat2_bytes(t, rng.integers(0, WIDTH, m), rng.integers(0, HEIGHT, m), rng.integers(0, 2, m))
            sink.write(data if start == 0 else data[header:])


def measure(camera: Path, window: str, folder: Path) -> dict:
    """Peak RSS (MB) of import and of frame, wall time, exit status and the last stderr line."""
    time_bin = shutil.which("time", path="/usr/bin:/bin") or "/usr/bin/time"
    neurotac = str(Path(sys.executable).parent / "neurotac")
    script = (
        f"ulimit -v {int(LIMIT_GB * 1024 * 1024)}; "
        f"{time_bin} -v -o {folder}/import.txt {neurotac} import {camera} "
        f"| {time_bin} -v -o {folder}/frame.txt {neurotac} frame --window {window} > /dev/null"
    )
    try:
        done = subprocess.run(["bash", "-o", "pipefail", "-c", script], capture_output=True, text=True, timeout=TIMEOUT_S)
        status, said = done.returncode, (done.stderr.strip().splitlines() or [""])[-1]
    except subprocess.TimeoutExpired:
        status, said = "timeout", f"over {TIMEOUT_S} s"
    row = {"status": status, "said": said[:160]}
    for step in ("import", "frame"):
        text = (folder / f"{step}.txt").read_text() if (folder / f"{step}.txt").exists() else ""
        peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
        wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", text)
        row[f"{step}_mb"] = int(peak.group(1)) // 1024 if peak else None
        row[f"{step}_s"] = _seconds(wall.group(1)) if wall else None
        (folder / f"{step}.txt").unlink(missing_ok=True)
    return row


def _seconds(text: str) -> float:
    seconds = 0.0
    for part in text.split(":"):
        seconds = seconds * 60 + float(part)
    return seconds


def main() -> list:
    if not Path("/usr/bin/time").exists():
        raise SystemExit("needs /usr/bin/time (apt-get install time)")
    folder = Path(tempfile.mkdtemp(prefix="bench-memory-", dir=os.environ.get("BENCH_MEMORY_DIR")))
    rows = []
    try:
        cases = [(n, "10ms") for n in EVENTS] + TINY
        for n in sorted({n for n, _ in cases}):
            camera = folder / f"{n}.aedat"
            write_camera_file(camera, n)
            for events, window in cases:
                if events == n:
                    row = {"events": n, "window": window, **measure(camera, window, folder)}
                    rows.append(row)
                    print(_line(row), flush=True)
            camera.unlink()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return rows


def _line(row: dict) -> str:
    return (f"{row['events']:>11,} events  window {row['window']:>5}  import {row['import_mb']} MB {row['import_s']} s  "
            f"frame {row['frame_mb']} MB {row['frame_s']} s  exit {row['status']}  {row['said']}")


def test_peak_memory_of_import_and_frame():
    for row in main():
        assert row["import_mb"] is not None, row


if __name__ == "__main__":
    main()
