"""Speed of `augment` on chapter-5-sized data: 60 trials x 36 frames x 2 x 75 x 70 (H x W; the thesis says 70x75).

Rotation (0-45 degrees), resize (1.25), FS (-1) and TES (-2, 0.5), two copies each, must take under
10 s on 2 cores. Peers measured in the same run: scipy.ndimage.affine_transform for the warps (one
call per trial over all its frames) and numpy's multivariate_hypergeometric called per frame and
channel for TES.

    .venv/bin/python -m pytest -q -s tests/bench/bench_augment.py -o addopts=""
    .venv/bin/python tests/bench/bench_augment.py
"""

import time

import numpy as np

from neurotac_cli import schema as sch
from neurotac_cli.ops import augment as aug

TRIALS, FRAMES, HEIGHT, WIDTH = 60, 36, 75, 70  # crop --size 140x150 (W x H), pooled 2x2
BUDGET_S = 10.0


def ch5_frames(seed=0, events_per_frame=4000):
    """Grasp-like counts: a contact blob per trial whose event rate rises, holds and falls."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH]
    profile = np.concatenate([np.linspace(0.3, 1.5, 5), np.full(FRAMES - 10, 0.6), np.linspace(1.2, 0.2, 5)])
    counts, rows = [], {"trial": [], "frame": [], "t": [], "force": [], "phase": [], "object": []}
    for trial in range(TRIALS):
        radius = (10, 13, 16)[trial % 3]
        cy, cx = rng.uniform(30, 40), rng.uniform(32, 43)
        blob = np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / (2 * radius**2))
        blob *= events_per_frame / 2 / blob.sum()
        rates = profile[:, None, None, None] * blob[None, None] * np.ones((1, 2, 1, 1))
        counts.append(rng.poisson(rates).astype(np.uint16))
        for frame in range(FRAMES):
            rows["trial"].append(f"t{trial:02d}")
            rows["frame"].append(frame)
            rows["t"].append(frame * 10_000)
            rows["force"].append(float(profile[frame] * 10))
            rows["phase"].append("holding")
            rows["object"].append(("bolt12", "bolt15", "bolt18")[trial % 3])
    schema = sch.frames_schema(HEIGHT, WIDTH, labels=("object",), window_us=10_000)
    import pyarrow as pa

    columns = dict(rows, counts=sch.counts_array(np.concatenate(counts)))
    return pa.Table.from_pydict({name: columns[name] for name in schema.names}, schema=schema)


def time_it(function):
    """(CPU seconds of this process, result). The code is single-threaded; CPU time is what the run
    costs on an otherwise idle machine, where wall time on a shared one also counts other users."""
    start = time.process_time()
    result = function()
    return time.process_time() - start, result


def peer_warps(counts_per_trial, rng):
    """scipy.ndimage.affine_transform, one 3-D call per trial (frames x channels stacked), order 1."""
    from scipy import ndimage

    for counts in counts_per_trial:
        stack = counts.reshape(-1, HEIGHT, WIDTH).astype(np.float64)
        centre = np.array(aug.contact_centre(counts))
        for matrix in (aug.rotation_matrix(rng.uniform(0, 45)), np.eye(2) / 1.25):
            full = np.eye(3)
            full[1:, 1:] = matrix
            offset = np.concatenate([[0.0], centre - matrix @ centre])
            ndimage.affine_transform(stack, full, offset=offset, order=1, mode="grid-constant", cval=0.0)


def peer_tes(counts_per_trial, rng):
    """numpy's multivariate_hypergeometric, one call per frame and channel."""
    for counts in counts_per_trial:
        flat = counts.reshape(-1, HEIGHT * WIDTH).astype(np.int64)
        for row in flat:
            n = int(row.sum())
            if n:
                rng.multivariate_hypergeometric(row, int(round(0.5 * n)))


def test_augment_ch5_under_budget():
    table = ch5_frames()
    counts = sch.counts_numpy(table["counts"])
    events = int(counts.sum(dtype=np.int64))
    methods = [aug.Rotate(0.0, 45.0), aug.Resize(1.25), aug.FrameShift(-1), aug.EventShift(-2, 0.5)]
    wall = time.perf_counter()
    seconds, (out, counted) = time_it(lambda: aug.augment_frames(table, methods, copies=2, seed=1))
    wall = time.perf_counter() - wall
    assert out.num_rows == table.num_rows * 9
    print(f"\naugment ch5 ({TRIALS}x{FRAMES}x2x{HEIGHT}x{WIDTH}, {events / 1e6:.1f} M events): "
          f"rotate+resize+fs+tes, 2 copies each: {seconds:.2f} s CPU, {wall:.2f} s wall (budget {BUDGET_S:.0f} s)")
    per_method = {}
    trials = [counts[i * FRAMES:(i + 1) * FRAMES] for i in range(TRIALS)]
    for method in methods:
        rng = np.random.default_rng(0)
        per_method[method.name], _ = time_it(lambda: [method(trial, rng) for trial in trials for _ in range(2)])
        print(f"  {method.name:7s} {per_method[method.name]:.2f} s CPU for {2 * TRIALS} trial copies")
    rng = np.random.default_rng(0)
    peer_warp_s, _ = time_it(lambda: [peer_warps(trials, rng) for _ in range(2)])
    peer_tes_s, _ = time_it(lambda: [peer_tes(trials, rng) for _ in range(2)])
    ours_warp = per_method["rotate"] + per_method["resize"]
    print(f"  warps: ours {ours_warp:.2f} s vs scipy.ndimage.affine_transform {peer_warp_s:.2f} s "
          f"(ratio ours/peer {ours_warp / peer_warp_s:.2f})")
    print(f"  TES draw: ours {per_method['tes']:.2f} s vs per-frame multivariate_hypergeometric {peer_tes_s:.2f} s "
          f"(ratio ours/peer {per_method['tes'] / peer_tes_s:.2f})")
    assert seconds < BUDGET_S


if __name__ == "__main__":
    test_augment_ch5_under_budget()
