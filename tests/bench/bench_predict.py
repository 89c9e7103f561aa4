"""Benchmarks of the force models (run on demand: `make bench` or `pytest -s tests/bench/bench_predict.py`).

1. Per-frame latency of streaming prediction (what `neurotac predict` does for each arriving frame:
   Arrow batch in, one recurrent step, Arrow batch out), one CPU thread, 115x115 frames: the thesis's
   ConvLSTM against our model. Goal: under 1 ms per 10 ms frame.
2. Training the ConvLSTM on the ch4 preset (115x115, 10 ms) to early stop on 2 threads. Goal: < 3 min.
   Set NEUROTAC_BENCH_FRAMES to a ch4 frames file to skip the simulation; NEUROTAC_BENCH_EPOCHS caps
   the epochs (the time per epoch is printed either way).
"""

import os
import subprocess
import sys
import time

import numpy as np
import pyarrow as pa
import torch

from neurotac_cli import model as models
from neurotac_cli import schema as sch
from neurotac_cli.model import convlstm, deform_gru
from neurotac_cli.model.core import Model

SIZE = 115


def _frames(n=400, seed=0):
    rng = np.random.default_rng(seed)
    counts = rng.poisson(0.05, (n, 2, SIZE, SIZE)).astype(np.uint16)
    schema = sch.frames_schema(SIZE, SIZE, window_us=10000)
    return pa.Table.from_arrays(
        [pa.array(["live"] * n), pa.array(np.arange(n, dtype=np.int32)), pa.array(np.arange(n, dtype=np.int64) * 10000),
         sch.counts_array(counts), pa.array(np.zeros(n, np.float32)), pa.array(["holding"] * n)], schema=schema)


def _model(module, name, config=None):
    config = config or module.Config()
    net = module.Net(config, (2, SIZE, SIZE))
    spec = {"window_us": 10000, "height": SIZE, "width": SIZE, "sensor": None, "channels": ["off", "on"],
            "accumulated": False, "normalisation": {"force_scale": 1.0}}
    return Model(name, config, net, spec)


def _latencies(model, frames):
    schema, batches = models.stream(model, frames.schema, iter(frames.to_batches(max_chunksize=1)))
    times = []
    iterator = iter(batches)
    while True:
        start = time.perf_counter()
        try:
            next(iterator)
        except StopIteration:
            break
        times.append(time.perf_counter() - start)
    return np.asarray(times[20:]) * 1000  # ms, after warm-up


def test_streaming_latency_per_frame_one_thread():
    torch.set_num_threads(1)
    frames = _frames()
    results = {}
    # deform-gru as trained by default (three members) and with one, whose steps the members add to
    for module, name, config in [(convlstm, "convlstm", None), (deform_gru, "deform-gru", None),
                                 (deform_gru, "deform-gru, one member", deform_gru.Config(members=1))]:
        latency = _latencies(_model(module, "deform-gru" if module is deform_gru else name, config), frames)
        results[name] = (np.percentile(latency, 50), np.percentile(latency, 99))
        print(f"\n{name:22s} per-frame latency at {SIZE}x{SIZE}, 1 thread: p50 {results[name][0]:.3f} ms, p99 {results[name][1]:.3f} ms")
    print(f"convlstm / ours: p50 x{results['convlstm'][0] / results['deform-gru'][0]:.1f}, p99 x{results['convlstm'][1] / results['deform-gru'][1]:.1f}")
    print(f"three members / one: p50 x{results['deform-gru'][0] / results['deform-gru, one member'][0]:.2f}")
    assert results["deform-gru"][0] < results["convlstm"][0]


def _ch4_frames(tmp_path):
    given = os.environ.get("NEUROTAC_BENCH_FRAMES")
    if given:
        return given
    path = tmp_path / "ch4.arrows"
    pipeline = (f"neurotac simulate --preset ch4 --seed 1 --synced | neurotac frame --window 10ms --pad-to longest "
                f"| neurotac crop --size {SIZE}x{SIZE} --center auto > {path}")
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    subprocess.run(["bash", "-o", "pipefail", "-c", pipeline], check=True, env=env)
    return str(path)


def test_convlstm_training_to_early_stop_two_threads(tmp_path):
    frames = _ch4_frames(tmp_path)
    epochs = os.environ.get("NEUROTAC_BENCH_EPOCHS", "500")
    command = [sys.executable, "-c", "from neurotac_cli.cli import main; main()", "train", "--model", "convlstm",
               "--threads", "2", "--epochs", epochs, "--seed", "1", "-o", str(tmp_path / "c.model"), frames]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True)
    elapsed = time.perf_counter() - start
    assert done.returncode == 0, done.stderr.decode()[-2000:]
    curve = models.load(str(tmp_path / "c.model")).training["curve"]
    print(f"\nconvlstm on ch4 ({SIZE}x{SIZE}), 2 threads: {len(curve)} epochs in {elapsed:.0f} s "
          f"({elapsed / len(curve):.1f} s per epoch; goal: early stop within 180 s)")
