"""Benchmark of the sensor in use (run on demand: `make bench` or `pytest -s tests/bench/bench_live.py`).

A recording is replayed at its recorded speed into the live pipe

    neurotac import --follow cam.aedat | neurotac frame --window 10ms | neurotac crop --size 115x115 --center 120,90
      | neurotac predict --model m.model

with the benchmark as the camera: it writes the file (AEDAT 2.0, the thesis's camera) one millisecond
of camera time at a time, each when that millisecond has passed on the wall clock, from the moment
every process of the pipe has started (predict's schema has arrived). Measured:

1. Latency: from a window's close (the wall-clock instant the camera wrote the window's last
   millisecond) to its force row arriving on predict's stdout; p50 and p99 over the replay. Goal:
   p99 under 5 ms at 10 ms windows, predict on one thread.
2. Memory: the resident memory (VmRSS) of each process, sampled every half second; the peak against
   the memory after the first minute of camera time (after the first quarter in a replay shorter
   than two minutes). Goal: under 1.2 times (flat).

The recording is simulated ch4 grasps (`neurotac simulate`) repeated to the length asked for, each
followed by 200 ms of the membrane at rest (the simulator's still recording: background activity);
the model is a deform-gru trained for 2 epochs on them (what is measured is the pipe, not the
model's accuracy).

    NEUROTAC_BENCH_LIVE_SECONDS  camera seconds replayed (default 20; 1800 for the 30-minute check)
    NEUROTAC_BENCH_LIVE_SPEED    replay speed: 1 = real time (default); 6 replays 30 minutes in 5
    NEUROTAC_BENCH_LIVE_INPUT    `follow` (a file that grows, read with import --follow; default) or
                                 `stdin` (a pipe into `import -`: nothing grows on disk, for long replays)
    NEUROTAC_BENCH_LIVE_UNTIL    `import`, `frame`, `crop` or `predict` (default): the last stage of the
                                 pipe, whose output is timed (to see where a delay comes from); for
                                 `import`, a window is out with the first batch holding its last millisecond
    NEUROTAC_BENCH_LIVE_PIPE     `pipe` (the four processes above; default) or `sense` (the same stages in one
                                 process: `neurotac sense`, reading the followed file or stdin)
    NEUROTAC_BENCH_LIVE_DUMP     a path: write each window's latency there (window, ms), one a line
    NEUROTAC_BENCH_LIVE_MEMDUMP  a path: write the memory samples there (camera seconds, then each
                                 process's RSS in kB), one a line, to see whether memory grows or spikes
"""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pyarrow as pa
import pytest

from neurotac_cli.io import read_events_table
from neurotac_cli.io.writers import DAVIS240C, HEADER

WINDOW_US = 10_000
SLICE_US = 1_000  # the camera writes a millisecond of events at a time
SECONDS = float(os.environ.get("NEUROTAC_BENCH_LIVE_SECONDS", "20"))
SPEED = float(os.environ.get("NEUROTAC_BENCH_LIVE_SPEED", "1"))
INPUT = os.environ.get("NEUROTAC_BENCH_LIVE_INPUT", "follow")
STAGES = ["import", "frame", "crop", "predict"]
UNTIL = os.environ.get("NEUROTAC_BENCH_LIVE_UNTIL", "predict")
PIPE = os.environ.get("NEUROTAC_BENCH_LIVE_PIPE", "pipe")
STARTUP_S = 20.0
ENV = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))


def _sh(command: str):
    subprocess.run(["bash", "-o", "pipefail", "-c", command], check=True, env=ENV, capture_output=True)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """Simulated grasps (the camera's material) and a deform-gru model trained briefly on them."""
    folder = tmp_path_factory.mktemp("live")
    _sh(f"neurotac simulate --preset ch4 --trials 4 --seed 1 --out {folder}/rig")
    _sh(f"neurotac sync --manifest {folder}/rig/manifest.csv | neurotac frame --window 10ms "
        f"| neurotac crop --size 115x115 --center 120,90 -o {folder}/frames.arrows")
    _sh(f"neurotac train --model deform-gru --epochs 2 --seed 1 -o {folder}/m.model < {folder}/frames.arrows")
    grasps, still = [], None
    for path in sorted((folder / "rig").glob("*.aedat")):
        table = read_events_table(path)
        events = [table[c].to_numpy() for c in ("t", "x", "y", "p")]
        if path.name == "still.aedat":
            still = events
        else:
            grasps.append(events)
    return folder, (grasps, still)


def _records(t, x, y, p, height=180) -> bytes:
    """AEDAT 2.0 records (jAER's DAVIS address, y pointing up) of events with t in µs."""
    words = np.empty((len(t), 2), dtype=">u4")
    words[:, 0] = ((height - 1 - y.astype(np.int64)) << 22) | (x.astype(np.int64) << 12) | (p.astype(np.int64) << 11)
    words[:, 1] = t
    return words.tobytes()


GAP_US = 200_000


def _recording(rig_events, seconds: float):
    """The grasps over and over, each followed by 200 ms of the membrane at rest (the simulator's
    still recording: a camera's background activity never stops, so no window waits long to close),
    until `seconds` of camera time: (t, x, y, p) per piece, t from 0."""
    grasps, still = rig_events
    offset, span_us = 0, int(seconds * 1e6)
    keep_rest = still[0] - still[0][0] < GAP_US  # the still recording lasts 2 s: the gap is its first 200 ms
    rest = (still[0][keep_rest] - still[0][0] + 1, *(c[keep_rest] for c in still[1:]))
    while offset < span_us:
        for t, x, y, p in grasps:
            for piece_t, piece_x, piece_y, piece_p in ((t - t[0], x, y, p), rest):
                shifted = piece_t + offset
                keep = shifted < span_us
                if keep.any():
                    yield shifted[keep], piece_x[keep], piece_y[keep], piece_p[keep]
                offset = int(shifted[-1]) + 1
                if offset >= span_us:
                    return
            offset += GAP_US - int(rest[0][-1])


class Camera(threading.Thread):
    """Writes the recording to `sink` a millisecond of camera time at a time, at `speed` times the
    recorded pace; `closed[k]` = the wall-clock instant window k's last millisecond was written."""

    def __init__(self, sink, rig_events, seconds, speed):
        super().__init__(daemon=True)
        self.sink, self.rig_events, self.seconds, self.speed = sink, rig_events, seconds, speed
        self.closed = np.full(int(seconds * 1e6) // WINDOW_US + 1, np.nan)
        self.start_wall = None

    def run(self):
        self.start_wall = time.monotonic()
        per_window = WINDOW_US // SLICE_US
        for i, (t, x, y, p) in enumerate(_recording(self.rig_events, self.seconds)):
            if i == 0:  # its first event went out with the header
                t, x, y, p = t[1:], x[1:], y[1:], p[1:]
            edges = np.searchsorted(t, np.arange((int(t[0]) // SLICE_US + 1) * SLICE_US, int(t[-1]) + SLICE_US + 1, SLICE_US))
            begin = 0
            for end in edges:
                if end == begin:
                    continue
                k = int(t[end - 1]) // SLICE_US  # the slice these events belong to
                due = self.start_wall + (k + 1) * SLICE_US / 1e6 / self.speed
                while (wait := due - time.monotonic()) > 0:
                    time.sleep(wait)
                self.sink.write(_records(t[begin:end], x[begin:end], y[begin:end], p[begin:end]))
                self.sink.flush()
                if (k + 1) % per_window == 0:
                    self.closed[(k + 1) // per_window - 1] = time.monotonic()
                begin = end
        self.sink.close()


def _end_after(camera: Camera, first: subprocess.Popen):
    """Once the camera has written everything, end the pipe: Ctrl-C to a followed file (stdin ends
    with the camera's pipe closing)."""
    camera.join()
    if INPUT == "follow":
        time.sleep(0.5)
        first.send_signal(signal.SIGINT)


def _rss_kb(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:"))
    except (OSError, StopIteration):
        return 0


def _pipe(folder, camera_path):
    """The live pipe as four processes, each one's stdout the next one's stdin (or `sense`, one process)."""
    if PIPE == "sense":
        source = ["--follow", "--idle-timeout", "3600s", str(camera_path)] if INPUT == "follow" else ["-"]
        command = ["neurotac", "sense", *source, "--model", str(folder / "m.model"), "--threads", "1",
                   "--window", "10ms", "--size", "115x115", "--center", "120,90"]
        stdin = subprocess.PIPE if INPUT == "stdin" else subprocess.DEVNULL
        return [subprocess.Popen(command, stdin=stdin, stdout=subprocess.PIPE, env=ENV)]
    first = ["neurotac", "import", "--follow", "--idle-timeout", "3600s", str(camera_path)] if INPUT == "follow" else ["neurotac", "import", "-"]
    commands = [first, ["neurotac", "frame", "--window", "10ms"], ["neurotac", "crop", "--size", "115x115", "--center", "120,90"],
                ["neurotac", "predict", "--model", str(folder / "m.model"), "--threads", "1"]]
    commands = commands[: 1 + STAGES.index(UNTIL)]
    processes, stdin = [], subprocess.PIPE if INPUT == "stdin" else subprocess.DEVNULL
    for command in commands:
        process = subprocess.Popen(command, stdin=stdin, stdout=subprocess.PIPE, env=ENV)
        if processes:
            processes[-1].stdout.close()  # the next process holds it now
        processes.append(process)
        stdin = process.stdout
    return processes


def test_live_pipe_latency_and_memory(rig):
    folder, rig_events = rig
    camera_path = folder / "cam.aedat"
    camera_path.write_bytes(b"")
    processes = _pipe(folder, camera_path)
    sink = processes[0].stdin if INPUT == "stdin" else open(camera_path, "wb")
    camera = Camera(sink, rig_events, SECONDS, SPEED)
    arrived, memory = {}, []
    done = threading.Event()

    def sample():
        while not done.wait(0.5):
            if camera.start_wall is not None:
                memory.append(((time.monotonic() - camera.start_wall) * SPEED, [_rss_kb(p.pid) for p in processes]))

    sampler = threading.Thread(target=sample, daemon=True)
    # the header and the first event (a header is known to be complete once a record follows it)
    t, x, y, p = rig_events[0][0]
    sink.write((HEADER + DAVIS240C).encode("ascii") + _records(t[:1] - t[0], x[:1], y[:1], p[:1]))
    sink.flush()
    # the rows are timed by a process of their own: a thread here would wait for the camera thread's
    # turn at the interpreter lock before it could read the clock
    reader = subprocess.Popen([sys.executable, __file__, "--read"], stdin=processes[-1].stdout, stdout=subprocess.PIPE, env=ENV)
    processes[-1].stdout.close()
    ready = threading.Event()
    reading = threading.Thread(target=_collect, args=(reader.stdout, ready, arrived), daemon=True)
    reading.start()
    # the camera starts once predict's schema has arrived (every process has started), or after
    # STARTUP_S: Arrow's stream writer sends a schema with its first batch, so where a stage waits
    # for its input's first batch (crop, predict) no schema comes through before the first frame
    started_early = not ready.wait(STARTUP_S)
    camera.start()
    sampler.start()
    threading.Thread(target=_end_after, args=(camera, processes[0]), daemon=True).start()
    reading.join()
    done.set()
    for process in processes + [reader]:
        process.wait(timeout=60)
    assert all(p.returncode == 0 for p in processes + [reader]), [p.returncode for p in processes + [reader]]
    if started_early:
        print(f"\nthe camera started after {STARTUP_S:g} s without predict's schema (a stage sends its schema with its first frame)")
    _report(camera, arrived, memory)


def _collect(stdout, ready, arrived):
    """The timing process's lines: `ready` once the pipe's schema has arrived, then `frame instant` per row."""
    for line in stdout:
        if line.strip() == b"ready":
            ready.set()
        else:
            frame, instant = line.split()
            arrived.setdefault(int(frame), float(instant))


def _read_forces(stdin, stdout):
    """The last stage's rows as they arrive (`--read`): `ready` once its schema has arrived, then at the
    end, one line per window: its frame and the monotonic-clock instant its row arrived."""
    arrived = {}
    reader = pa.ipc.open_stream(stdin)
    stdout.write(b"ready\n")
    stdout.flush()
    for batch in reader:
        now = time.monotonic()
        if "frame" in batch.schema.names:
            frames = batch.column("frame").to_pylist()
        else:  # import's events: a window has gone out with the events of its last millisecond
            t = batch.column("t").to_numpy()
            frames = np.unique(t[t % WINDOW_US >= WINDOW_US - SLICE_US] // WINDOW_US).tolist()
        for frame in frames:
            arrived.setdefault(frame, now)
    stdout.write("".join(f"{frame} {instant!r}\n" for frame, instant in arrived.items()).encode())
    stdout.flush()


def _report(camera: Camera, arrived: dict, memory: list):
    frames = np.array(sorted(k for k in arrived if k < len(camera.closed) and np.isfinite(camera.closed[k])))
    latency = (np.array([arrived[k] for k in frames]) - camera.closed[frames]) * 1000
    if os.environ.get("NEUROTAC_BENCH_LIVE_DUMP"):  # window, latency (ms) per row, to see when the slow ones come
        np.savetxt(os.environ["NEUROTAC_BENCH_LIVE_DUMP"], np.c_[frames, latency], fmt="%.3f")
    latency = latency[frames >= 20]  # after the processes have warmed up
    print(f"\nlive {'sense, one process' if PIPE == 'sense' else 'pipe to ' + UNTIL}, {INPUT}, {SECONDS:g} s of camera time at x{SPEED:g}: {len(arrived)} rows out, "
          f"{int(np.isfinite(camera.closed).sum())} windows written")
    print(f"window close -> its row on stdout: p50 {np.percentile(latency, 50):.2f} ms, p99 {np.percentile(latency, 99):.2f} ms, "
          f"max {latency.max():.2f} ms (goal: p99 < 5 ms)")
    names = ["sense"] if PIPE == "sense" else STAGES[: 1 + STAGES.index(UNTIL)]
    if os.environ.get("NEUROTAC_BENCH_LIVE_MEMDUMP"):
        np.savetxt(os.environ["NEUROTAC_BENCH_LIVE_MEMDUMP"], [[seconds, *rss] for seconds, rss in memory], fmt="%.1f")
    settled_at = 60.0 if SECONDS >= 120 else SECONDS / 4
    settled = next((rss for seconds, rss in memory if seconds >= settled_at), memory[-1][1])
    peak = np.max([rss for _, rss in memory], axis=0)
    for name, first, top in zip(names, settled, peak):
        print(f"  {name:8s} RSS after {settled_at:g} s {first / 1024:7.1f} MB, peak {top / 1024:7.1f} MB, x{top / max(first, 1):.2f} (goal < 1.2)")
    assert len(latency) > 0


if __name__ == "__main__" and sys.argv[1:] == ["--read"]:
    _read_forces(sys.stdin.buffer, sys.stdout.buffer)
