"""Figures of docs/simulator.md, made from the simulator's own output (thesis Figs 3.2, 3.3 and 3.5).

    .venv/bin/python examples/simulator_figures.py [OUT_DIR]     # default docs/img

The framing here is a plain numpy binning of each trial's events in windows from the sync instant
(`neurotac frame` does the same job on tables).
"""

import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from neurotac_cli.sim.config import preset_config
from neurotac_cli.sim.run import simulate

MATERIAL_COLOURS = {"foam": "tab:orange", "rubber": "tab:purple", "silicone": "tab:cyan", "steel": "tab:gray"}


def counts_per_window(trial, window_us, frames):
    """(frames, 2) OFF/ON counts per window from the true LED-off instant."""
    rel = trial.t - trial.grasp.led_off_camera_us
    index = np.floor_divide(rel, window_us)
    ok = (index >= 0) & (index < frames)
    counts = np.zeros((frames, 2), np.int64)
    np.add.at(counts, (index[ok], trial.p[ok].astype(int)), 1)
    return counts


def force_per_window(trial, window_us, frames):
    """The logged force read at each window start after a 5-sample median filter (thesis 3.6.1)."""
    from scipy.signal import medfilt

    smooth = medfilt(trial.force_n.astype(float), 5)
    at = np.minimum(np.arange(frames) * window_us // 2000, smooth.size - 1)
    return smooth[at]


def figure_counts_vs_force(out):
    """Thesis Fig 3.3: normalised force, OFF and ON counts per 7 ms frame over one ch3 grasp."""
    config = preset_config("ch3", groups=("rubber:hex:1",), force_min_n=3.0, force_max_n=3.4)
    trial = simulate(config, seed=3).trials[0]
    counts = counts_per_window(trial, 7_000, 144)
    force = force_per_window(trial, 7_000, 144)
    frames = np.arange(1, 145)
    fig, ax = plt.subplots(figsize=(8, 3.4))
    ax.plot(frames, force / force.max(), color="tab:blue", label="force (FlexiForce model)")
    # the LED-off spike sits in frame 1: leave it out of the normalisation, as the thesis's trials start after it
    grasp = counts.copy()
    grasp[0] = 0
    ax.plot(frames, grasp[:, 0] / grasp[:, 0].max(), color="tab:red", label="OFF events")
    ax.plot(frames, grasp[:, 1] / grasp[:, 1].max(), color="tab:green", label="ON events")
    for edge in (22.5, 122.5):
        ax.axvline(edge, color="k", lw=0.8, ls=":")
    ax.set_xlabel("frame (7 ms)")
    ax.set_ylabel("normalised value")
    ax.set_title("One simulated grasp (ch3 preset, rubber hexagon): force and events per frame")
    ax.legend(loc="center right", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "sim_counts_vs_force.png"), dpi=110)
    plt.close(fig)


def figure_montage(out):
    """Thesis Fig 3.2: events of one ch4 grasp in 10 ms frames (red OFF, green ON), cropped to the contact."""
    config = preset_config("ch4", groups=("steel:bolt12:1",), force_min_n=2.8, force_max_n=3.1)
    trial = simulate(config, seed=2).trials[0]
    g = trial.grasp
    rel = trial.t - g.led_off_camera_us
    picks = [0, 1, 2, 3, 4, 6, 10, 20, int(g.release_us // 10_000), int(g.release_us // 10_000) + 1,
             int(g.release_us // 10_000) + 2, int(g.release_us // 10_000) + 4]
    cx, cy = (int(round(c)) for c in g.center_px)
    half = 57  # the thesis's 115 x 115 crop
    fig, axes = plt.subplots(2, 6, figsize=(12, 5.0))
    for ax, frame in zip(axes.ravel(), picks):
        sel = (rel >= frame * 10_000) & (rel < (frame + 1) * 10_000)
        image = np.ones((2 * half + 1, 2 * half + 1, 3))
        x = trial.x[sel].astype(int) - cx + half
        y = trial.y[sel].astype(int) - cy + half
        inside = (x >= 0) & (x <= 2 * half) & (y >= 0) & (y <= 2 * half)
        p = trial.p[sel][inside]
        counts = np.zeros((2, 2 * half + 1, 2 * half + 1))
        np.add.at(counts, (p.astype(int), y[inside], x[inside]), 1)
        scale = max(1.0, np.percentile(counts[counts > 0], 95) if (counts > 0).any() else 1.0)
        off, on = np.clip(counts[0] / scale, 0, 1), np.clip(counts[1] / scale, 0, 1)
        image[..., 1] -= off
        image[..., 2] -= off
        image[..., 0] -= on
        image[..., 2] -= on
        ax.imshow(np.clip(image, 0, 1), interpolation="nearest")
        ax.set_title(f"{frame * 10}-{frame * 10 + 10} ms\n{int((p == 0).sum())} OFF / {int((p == 1).sum())} ON", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"One simulated grasp (ch4 preset, 12 mm bolt head, peak {g.peak_force_n:.2f} N): "
                 f"10 ms frames from LED-off, 115x115 crop; red OFF, green ON", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "sim_frame_montage.png"), dpi=100)
    plt.close(fig)


def figure_accumulation(out):
    """Thesis Fig 3.5: accumulated ON and OFF events of one grasp per material at a similar force."""
    groups = tuple(f"{m}:hex:3" for m in MATERIAL_COLOURS)
    config = preset_config("ch3", groups=groups, force_min_n=2.9, force_max_n=3.1)
    simulation = simulate(config, seed=5)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    frames = np.arange(1, 145)
    for trial in simulation.trials:
        counts = counts_per_window(trial, 7_000, 144)
        counts[0] = 0  # the LED-off spike: before the grasp
        colour = MATERIAL_COLOURS[trial.grasp.material]
        first = trial.grasp.trial.endswith("01")
        for axis, channel in ((0, 1), (1, 0)):
            axes[axis].plot(frames, np.cumsum(counts[:, channel]), color=colour, lw=1.2,
                            label=trial.grasp.material if first else None)
    for axis, name in ((0, "ON"), (1, "OFF")):
        axes[axis].set_title(f"accumulated {name} events (3 grasps per material, 2.9-3.1 N)", fontsize=9)
        axes[axis].set_xlabel("frame (7 ms)")
        for edge in (22.5, 122.5):
            axes[axis].axvline(edge, color="k", lw=0.8, ls=":")
    axes[0].set_ylabel("events since LED-off")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "sim_accumulation.png"), dpi=110)
    plt.close(fig)


def main(out="docs/img"):
    os.makedirs(out, exist_ok=True)
    figure_counts_vs_force(out)
    figure_montage(out)
    figure_accumulation(out)


if __name__ == "__main__":
    main(*sys.argv[1:])
