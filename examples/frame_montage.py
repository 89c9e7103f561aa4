"""A montage of one trial's frames with its force trace and phases underneath.

    neurotac simulate --preset ch4 --out sim
    neurotac sync --manifest sim/manifest.csv | neurotac frame --window 10ms \
      | neurotac crop --size 115x115 --center auto > frames.arrows
    python examples/frame_montage.py frames.arrows --trial steel-bolt12-01 --columns 11 -o docs/img/frame_montage.png

Each tile is one frame: ON counts in red, OFF counts in blue (both on a square-root scale, clipped
at the 99.5th percentile of the trial's counts), titled with its frame number and phase. Below, the
force per frame (the value `frame` attached to it) over the frame clock, with the phases shaded.
"""

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow.compute as pc  # noqa: E402

from neurotac_cli import schema as sch, tables  # noqa: E402

PHASE_COLOURS = {"grasping": "#f4c27a", "holding": "#9fd3a0", "releasing": "#a8c3e8", "none": "#ffffff"}


def montage(frames_path: str, trial: str | None, columns: int, every: int, output: str):
    frames = tables.read([frames_path], kind="frames")
    trials = frames.column("trial").unique().to_pylist()
    trial = trial or trials[0]
    if trial not in trials:
        raise SystemExit(f"no trial {trial!r} in {frames_path} (trials: {', '.join(trials[:8])}...)")
    rows = frames.filter(pc.equal(frames.column("trial"), trial))
    counts = sch.counts_numpy(rows.column("counts")).astype(np.float64)
    force = np.asarray(rows.column("force").to_pylist(), dtype=float)
    phase = rows.column("phase").to_pylist()
    window_ms = sch.get_meta(frames.schema, sch.WINDOW) / 1000
    shown = list(range(0, len(counts), every))[: columns * 4]
    top = np.percentile(np.sqrt(counts[counts > 0]), 99.5) if (counts > 0).any() else 1.0
    n_rows = int(np.ceil(len(shown) / columns))
    has_force = bool(np.isfinite(force).any())  # plain events framed without a force log: tiles only
    figure = plt.figure(figsize=(1.45 * columns, 1.55 * n_rows + (2.2 if has_force else 0.4)), dpi=110)
    grid = figure.add_gridspec(n_rows + has_force, columns, height_ratios=[1] * n_rows + [1.5] * has_force, hspace=0.35, wspace=0.05)
    for i, k in enumerate(shown):
        axis = figure.add_subplot(grid[i // columns, i % columns])
        on = np.clip(np.sqrt(counts[k, 1]) / top, 0, 1)
        off = np.clip(np.sqrt(counts[k, 0]) / top, 0, 1)
        image = np.stack([1 - off, 1 - off - on, 1 - on], axis=-1).clip(0, 1)  # white background, ON red, OFF blue
        axis.imshow(image, interpolation="nearest")
        axis.set_title(f"{k}: {phase[k]}" if phase[k] else f"{k}", fontsize=7, pad=2)
        axis.set_xticks([])
        axis.set_yticks([])
    if not has_force:
        figure.suptitle(f"{trial}: {window_ms:g} ms frames (ON red, OFF blue)", fontsize=9)
        figure.savefig(output, bbox_inches="tight")
        print(f"wrote {output}: trial {trial}, {len(shown)} of {len(counts)} frames")
        return
    axis = figure.add_subplot(grid[n_rows, :])
    t_ms = (np.arange(len(force)) + 1) * window_ms  # force read at each window's end
    start = 0
    for k in range(1, len(phase) + 1):
        if k == len(phase) or phase[k] != phase[start]:
            axis.axvspan(start * window_ms, k * window_ms, color=PHASE_COLOURS.get(phase[start] or "none", "#ffffff"), lw=0)
            start = k
    axis.plot(t_ms, force, "k.-", lw=1, ms=3)
    for k in shown:
        axis.axvline((k + 0.5) * window_ms, color="#999999", lw=0.5, ls=":")
    axis.set_xlim(0, len(force) * window_ms)
    axis.set_xlabel("time from the LED switch-off t0 (ms)")
    axis.set_ylabel("force (N)")
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for name, c in PHASE_COLOURS.items() if name != "none"]
    axis.legend(handles, [n for n in PHASE_COLOURS if n != "none"], loc="upper right", fontsize=7, ncol=3)
    figure.suptitle(f"{trial}: {window_ms:g} ms frames (ON red, OFF blue) and force per frame", fontsize=9)
    figure.savefig(output, bbox_inches="tight")
    print(f"wrote {output}: trial {trial}, {len(shown)} of {len(counts)} frames")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("frames", help="a frames table (Arrow or Parquet)")
    parser.add_argument("--trial", help="the trial to show (default: the first)")
    parser.add_argument("--columns", type=int, default=10, help="tiles per row")
    parser.add_argument("--every", type=int, default=1, help="show every n-th frame")
    parser.add_argument("-o", "--output", default="frame_montage.png")
    args = parser.parse_args()
    montage(args.frames, args.trial, args.columns, args.every, args.output)


if __name__ == "__main__":
    main()
