"""Draw docs/img/augment_methods.png: one simulated chapter-5 grasp, before and after each augmentation.

    .venv/bin/python examples/augment_figure.py [docs/img/augment_methods.png]

The grasp and a still-scene (noise) recording come from the simulator, framed at 10 ms and cropped to
140x150 pooled 2x2 (the thesis's chapter-5 frames) with the same commands a user runs; the
augmentations are the Python functions behind `neurotac augment`. Each row is one method, each
column one frame (OFF events red, ON events green, as the thesis draws them); the last column plots
the events per frame of the copy (colour) over the original's (grey).
"""

import pathlib
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from neurotac_cli import schema as sch, tables  # noqa: E402
from neurotac_cli.ops import augment as aug  # noqa: E402

SEED = 2
FRAMES_SHOWN = (1, 2, 3, 4, 29, 30, 31, 32)
CROP = "--size 140x150 --center auto --pool 2x2"


def neurotac_has(command: str) -> bool:
    return subprocess.run(["neurotac", command, "--help"], capture_output=True).returncode == 0


def pipeline(source: str, out: pathlib.Path):
    """Run `source | frame | crop` into `out` and read it back."""
    crop = f" | neurotac crop {CROP}" if neurotac_has("crop") else ""
    subprocess.run(["bash", "-o", "pipefail", "-c", f"{source} | neurotac frame --window 10ms{crop} -o {out}"],
                   check=True, stderr=subprocess.DEVNULL)
    table = tables.read([str(out)], kind="frames")
    return table if crop else crop_like_the_thesis(table)


def crop_like_the_thesis(table, centre=None):
    """Stand-in for `neurotac crop` where it is missing: 140x150 around the contact, pooled 2x2."""
    counts = sch.counts_numpy(table["counts"]).astype(np.uint16)
    if centre is None:
        cy, cx = aug.contact_centre(counts[1:])
        centre = int(np.clip(cy - 75, 0, counts.shape[2] - 150)), int(np.clip(cx - 70, 0, counts.shape[3] - 140))
    y0, x0 = centre
    window = counts[:, :, y0:y0 + 150, x0:x0 + 140]
    pooled = window.reshape(len(counts), 2, 75, 2, 70, 2).sum(axis=(3, 5)).astype(np.uint16)
    labels = [name for name in sch.label_columns(table.schema)]
    schema = sch.frames_schema(75, 70, labels=labels, window_us=sch.get_meta(table.schema, sch.WINDOW))
    columns = {name: table[name] for name in schema.names if name != "counts"}
    columns["counts"] = sch.counts_array(pooled)
    import pyarrow as pa

    return pa.Table.from_pydict({name: columns[name] for name in schema.names}, schema=schema)


def load_data(folder: pathlib.Path):
    frames = pipeline(f"neurotac simulate --preset ch5 --trials 1 --seed {SEED} --synced", folder / "grasp.parquet")
    subprocess.run(["neurotac", "simulate", "--preset", "ch5", "--trials", "1", "--seed", str(SEED),
                    "--out", str(folder / "sim")], check=True, capture_output=True)
    noise = pipeline(f"neurotac import {folder / 'sim' / 'still.aedat'}", folder / "still.parquet")
    return frames, noise


def rgb(frame: np.ndarray, scale: float) -> np.ndarray:
    """OFF (channel 0) red, ON (channel 1) green, as the thesis draws event frames."""
    image = np.zeros((*frame.shape[1:], 3))
    image[..., 0] = frame[0] / scale
    image[..., 1] = frame[1] / scale
    return np.clip(image, 0, 1)


def main(path="docs/img/augment_methods.png"):
    with tempfile.TemporaryDirectory() as folder:
        frames, noise = load_data(pathlib.Path(folder))
    trial = frames["trial"][0].as_py()
    rows = np.flatnonzero(np.array(frames["trial"].to_pylist()) == trial)
    original = sch.counts_numpy(frames["counts"])[rows]
    pool = aug.noise_pool(noise, frames.schema)
    methods = [
        ("rotate 20°", aug.Rotate(20.0)),
        ("resize β=1.25", aug.Resize(1.25)),
        ("resize β=0.83", aug.Resize(0.83)),
        ("noise (still scene)", aug.Noise(tuple(pool))),
        ("FS −1", aug.FrameShift(-1)),
        ("TES −2 (ζ=0.5)", aug.EventShift(-2, 0.5)),
    ]
    rng = np.random.default_rng(SEED)
    copies = [("original", original)] + [(name, method(original, rng)[0]) for name, method in methods]
    scale = max(1.0, np.percentile(original[list(FRAMES_SHOWN)], 99.9))
    totals = original.sum(axis=(1, 2, 3))

    figure, axes = plt.subplots(len(copies), len(FRAMES_SHOWN) + 1, figsize=(2.0 * (len(FRAMES_SHOWN) + 2), 2.1 * len(copies)),
                                gridspec_kw={"width_ratios": [1] * len(FRAMES_SHOWN) + [2.2]})
    for row, (name, counts) in enumerate(copies):
        for column, frame in enumerate(FRAMES_SHOWN):
            axis = axes[row, column]
            axis.imshow(rgb(counts[frame], scale), interpolation="nearest")
            axis.set_xticks([])
            axis.set_yticks([])
            if row == 0:
                axis.set_title(f"frame {frame}\n{int(frame * 10)}–{int(frame * 10 + 10)} ms", fontsize=9)
            if column == 0:
                axis.set_ylabel(name, fontsize=10)
        axis = axes[row, -1]
        axis.plot(totals, color="0.6", lw=1.5, label="original")
        if row:
            axis.plot(counts.sum(axis=(1, 2, 3)), color="C3", lw=1.2, label="copy")
        axis.set_yscale("symlog", linthresh=100)
        axis.set_xlabel("frame" if row == len(copies) - 1 else "")
        axis.tick_params(labelsize=7)
        if row <= 1:
            axis.legend(fontsize=7, loc="upper right")
        if row == 0:
            axis.set_title("events per frame", fontsize=9)
    figure.suptitle(f"neurotac augment on one simulated chapter-5 grasp ({trial}); OFF red, ON green", fontsize=11)
    figure.tight_layout()
    pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=80)
    print(f"wrote {path}", file=sys.stderr)


if __name__ == "__main__":
    main(*sys.argv[1:])
