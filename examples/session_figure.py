"""The figure of docs/simulator.md's session section: a simulated session's force, event rate and labels over time.

    .venv/bin/python examples/session_figure.py [OUT_PNG]      # default docs/img/sim_session.png

Simulates one session with `neurotac simulate --session`, syncs it with `neurotac sync --manifest`
(one LED blink: one trial), then plots the force log, the OFF and ON events per 10 ms frame, the true
grasp intervals and slips from grasps.csv, and the phases `frame --phases session` gives each frame
(computed here with the same functions, without the count frames, which would not fit in memory).
"""

import csv
import os
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pyarrow as pa

from neurotac_cli.ops.frame import frame_force
from neurotac_cli.ops.phases import session_columns

SIMULATE = ["neurotac", "simulate", "--session", "--grasps", "8", "--seed", "5", "--illumination-drift", "0.3",
            "--set", "illumination_period_us=20s", "--set", "slip_share=0.5"]
WINDOW_US = 10_000
PHASE_COLOURS = {"grasping": "tab:green", "holding": "tab:blue", "releasing": "tab:red"}


def session_table(folder):
    subprocess.run([*SIMULATE, "--out", folder], check=True)
    done = subprocess.run(["neurotac", "sync", "--manifest", os.path.join(folder, "manifest.csv")], check=True, capture_output=True)
    return pa.ipc.open_stream(done.stdout).read_all()


def main(out_png):
    with tempfile.TemporaryDirectory() as folder:
        table = session_table(folder)
        with open(os.path.join(folder, "grasps.csv")) as handle:
            grasps = list(csv.DictReader(handle))
    events = table["events"][0].values
    t = events.field("t").to_numpy()
    p = events.field("p").to_numpy()
    force = table["force"][0].values
    force_t, force_v = force.field("t").to_numpy(), force.field("value").to_numpy()
    frames = int(force_t[-1] // WINDOW_US) + 1
    kept = (t >= 0) & (t < frames * WINDOW_US)
    counts = np.zeros((frames, 2))
    np.add.at(counts, (t[kept] // WINDOW_US, p[kept].astype(int)), 1)
    per_frame = frame_force(force_t, force_v, WINDOW_US, frames)
    phase, grasp = session_columns(per_frame, frames, frames)
    seconds = np.arange(frames) * WINDOW_US / 1e6

    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(11, 6), sharex=True, height_ratios=[3, 3, 1])
    top.plot(force_t / 1e6, force_v, lw=0.7, color="k")
    for g in grasps:
        top.axvspan(float(g["contact_ms"]) / 1e3, float(g["released_ms"]) / 1e3, color="0.9", zorder=0)
        top.text(float(g["contact_ms"]) / 1e3, 1.04 * force_v.max(), f"{g['material']}\n{g['object']}", fontsize=7, va="bottom")
        if g["slip_start_ms"]:
            top.axvspan(float(g["slip_start_ms"]) / 1e3, float(g["slip_end_ms"]) / 1e3, color="tab:orange", alpha=0.6, zorder=1)
    top.set_ylim(-0.1, 1.3 * force_v.max())
    top.set_ylabel("force (N)")
    top.set_title("simulated session: true grasp intervals grey, slips orange")
    middle.plot(seconds, counts[:, 0], lw=0.6, color="tab:red", label="OFF")
    middle.plot(seconds, counts[:, 1], lw=0.6, color="tab:green", label="ON")
    middle.set_yscale("log")
    middle.set_ylabel("events / 10 ms")
    middle.legend(loc="upper right", fontsize=8)
    for name, colour in PHASE_COLOURS.items():
        mask = phase == name
        bottom.fill_between(seconds, 0, 1, where=mask, color=colour, step="post", label=name, lw=0)
    bottom.set_yticks([])
    bottom.set_ylabel("phase")
    bottom.set_xlabel("time from LED-off (s)")
    bottom.legend(loc="upper right", fontsize=7, ncol=3)
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)
    print(f"{out_png}: {len(grasps)} grasps, {len(set(grasp.tolist()) - {-1})} found by the labels, {t.size} events")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/img/sim_session.png")
