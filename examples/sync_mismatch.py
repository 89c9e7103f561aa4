"""How well xcorr's correlation tells a camera file and a force log that belong together from a pair
that does not: every simulated grasp synced with its own force log (matched) and with each other
grasp's (mismatched), per preset. Prints the correlations and the threshold `sync` uses.

    python examples/sync_mismatch.py --trials 8 --seed 11
"""

import argparse
import os
import subprocess
import tempfile

import numpy as np

from neurotac_cli import schema as sch
from neurotac_cli.io.events import read_events_table
from neurotac_cli.io.force import read_force_log
from neurotac_cli.ops import sync as sy


def correlation(events, force) -> tuple[float, float]:
    """(best correlation, its margin over the best offset 20 ms or more away)."""
    table = sy.sync_sources([sy.Source(trial="t", events=events, force=force, labels={})], sy.SyncMethod(method="xcorr"))
    found = sch.get_meta(table.schema, sch.SYNC)["trials"]["t"]
    return float(found["correlation"]), float(found["margin"])


def measure(preset: str, trials: int, seed: int, folder: str) -> tuple[list, list]:
    out = os.path.join(folder, preset)
    subprocess.run(["neurotac", "simulate", "--preset", preset, "--trials", str(trials), "--seed", str(seed), "--out", out], check=True)
    names = sorted(name[: -len(".aedat")] for name in os.listdir(out) if name.endswith(".aedat") and name != "still.aedat")
    events = {name: read_events_table(os.path.join(out, f"{name}.aedat")) for name in names}
    forces = {name: read_force_log(os.path.join(out, f"{name}_force.csv")) for name in names}
    matched, mismatched = [], []
    for camera in names:
        for log in names:
            try:
                r = correlation(events[camera], forces[log])
            except sy.SyncError:
                r = (float("nan"), float("nan"))
            (matched if camera == log else mismatched).append(r)
    return matched, mismatched


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=8)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--presets", default="ch3,ch4,ch5")
    args = parser.parse_args()
    everything = {"matched": [], "mismatched": []}
    with tempfile.TemporaryDirectory() as folder:
        for preset in args.presets.split(","):
            matched, mismatched = measure(preset, args.trials, args.seed, folder)
            everything["matched"] += matched
            everything["mismatched"] += mismatched
            for name, pairs in (("matched", matched), ("mismatched", mismatched)):
                for column, what in enumerate(("r", "margin")):
                    values = np.asarray(pairs)[:, column]
                    print(f"{preset} {name:10s} {what:6s} n={len(values):3d} min {np.nanmin(values):.3f} "
                          f"median {np.nanmedian(values):.3f} max {np.nanmax(values):.3f} failed {int(np.isnan(values).sum())}")
    matched, mismatched = (np.asarray(everything[k])[:, 0] for k in ("matched", "mismatched"))
    threshold = sy.XCORR_MIN_CORRELATION
    print(f"all matched: min {np.nanmin(matched):.3f}; all mismatched: max {np.nanmax(mismatched):.3f}, "
          f"99th percentile {np.nanpercentile(mismatched, 99):.3f}")
    print(f"threshold {threshold}: refuses {np.mean(matched < threshold):.1%} of matched pairs, "
          f"lets through {np.mean(mismatched >= threshold):.1%} of mismatched pairs")


if __name__ == "__main__":
    main()
