"""Sync accuracy against the simulator's truth: each trial's error, and the figures of docs/commands/sync.md.

    neurotac simulate --preset ch3 --seed 3 --out sim3
    python examples/sync_accuracy.py sim3                    # xcorr, as sync runs it by default
    python examples/sync_accuracy.py sim3 --method led -v    # one line per trial as well
    python examples/sync_accuracy.py sim3 --sensor-lag 25,75  # xcorr told the sensor's time constants (ms)

For every simulated folder (its manifest.csv has each trial's true LED-off instant, `true_t0_us`),
syncs every trial as `neurotac sync --manifest` does and prints, per folder: the number of trials,
the largest and mean |error|, how many are within 2 ms, which signal xcorr used, the range of its
uncertainty, how many errors lie inside it, and how many trials sync's warning (uncertainty over
±5 ms) names, among all and among those more than 2 ms off.
"""

import argparse
import csv
import pathlib

import numpy as np

from neurotac_cli import schema as sch
from neurotac_cli.io.manifest import ForceOptions, manifest_sources
from neurotac_cli.ops import sync as sy
from neurotac_cli.ops.xcorr import XCORR_UNCERTAIN_US


def measure(folder: pathlib.Path, method: str, verbose: bool, sensor_lag=None) -> str:
    manifest = folder / "manifest.csv"
    truth = {row["trial"]: int(row["true_t0_us"]) for row in csv.DictReader(open(manifest))}
    table = sy.sync_sources(manifest_sources(str(manifest), ForceOptions()), sy.SyncMethod(method=method, sensor_lag_us=sensor_lag))
    details = sch.get_meta(table.schema, sch.SYNC)["trials"]
    trials = table.column("trial").to_pylist()
    error = np.array([t0 - truth[trial] for trial, t0 in zip(trials, table.column("t0").to_pylist())]) / 1000
    if verbose:
        for trial, e in zip(trials, error):
            shown = {k: v for k, v in details[trial].items() if k in ("score", "uncertainty_us", "signal", "sensor_rise_us", "sensor_fall_us")}
            print(f"  {trial:24s} error {e:8.3f} ms  " + "  ".join(f"{k}={v}" for k, v in shown.items()))
    size = np.abs(error)
    line = f"{folder}: {len(size)} trials, max |error| {size.max():.3f} ms, mean {size.mean():.3f} ms, {(size <= 2).sum()} within 2 ms"
    if method == "xcorr" and all("uncertainty_us" in details[trial] for trial in trials):  # older builds lack it
        signals = [details[trial]["signal"] for trial in trials]
        spread = np.array([details[trial]["uncertainty_us"] for trial in trials]) / 1000
        warned = spread > XCORR_UNCERTAIN_US / 1000
        line += (f"; signal {', '.join(f'{s} {signals.count(s)}' for s in sorted(set(signals)))}"
                 f"; uncertainty ±{spread.min():.1f}-{spread.max():.1f} ms, holding {(size <= spread).sum()} errors"
                 f"; warned {warned.sum()}, of the {(size > 2).sum()} over 2 ms {(warned & (size > 2)).sum()}")
    return line


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=pathlib.Path, help="folders written by `neurotac simulate --out`")
    parser.add_argument("--method", default="xcorr", choices=["led", "xcorr"], help="sync method (default xcorr)")
    parser.add_argument("-v", "--verbose", action="store_true", help="one line per trial as well")
    parser.add_argument("--sensor-lag", metavar="RISE[,FALL]", help="xcorr: the force sensor's time constants in ms, as sync --sensor-lag (default: estimated)")
    args = parser.parse_args()
    lag = None
    if args.sensor_lag:
        rise, _, fall = args.sensor_lag.partition(",")
        lag = (int(float(rise) * 1000), int(float(fall or rise) * 1000))
    for folder in args.folders:
        print(measure(folder, args.method, args.verbose, lag), flush=True)


if __name__ == "__main__":
    main()
