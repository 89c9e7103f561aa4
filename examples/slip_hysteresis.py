"""The slip flag's hysteresis measured on the sessions script's sessions, detection alone.

Every session of `examples/sessions.py`'s output folder (default physics for training and test,
randomised training, unseen physics) is scored with the slip bars of its own presses and releases
(`ops.contact.rig_peaks`, `slip_for`), the true force ending contacts, once per share of the bars a
slip under way must keep passing (`SlipConfig.keep_share`; 1: the starting bars to the end). Prints
one line per session and share, then the figures pooled over all sessions. The figures of
docs/design.md ("Slip") come from this script.

    python examples/slip_hysteresis.py --sessions examples/out-sessions --keep-share 1,0.5
"""

import argparse
import dataclasses
import os

from neurotac_cli import metrics, tables
from neurotac_cli.ops import contact as detector
from rig_sessions import WINDOW_MS, detection_config, peaks_of, streams  # beside this script

FOLDERS = ("train", "test", "train-randomised", "unseen")


def score_folder(folder: str, shares) -> list:
    """(session, share, true slips, flags) for every session of one folder's frames."""
    out = []
    for index, stream in enumerate(streams(tables.read([os.path.join(folder, "frames.arrows")]))):
        config, bars = detection_config([stream]), detector.slip_for(*peaks_of([stream]))
        for share in shares:
            _, _, flags, _ = detector.detect(config, stream["off"], stream["on"], separation=stream["separation"],
                                             slip=dataclasses.replace(bars, keep_share=share), force=stream["force"],
                                             counts=stream["counts"])
            out.append((f"{os.path.basename(folder)}/{index}", share, stream["slip"], flags))
    return out


def figures(truths, flags) -> dict:
    """Slip figures over the streams together (`metrics.detection_figures` pools them)."""
    return metrics.detection_figures(truths, flags, "slip", unit=WINDOW_MS, **metrics.SLIP_TIMING)


def line(label: str, f: dict) -> str:
    within = f.get("slip_within_20", 0.0) * f["slip_hits"]
    return (f"{label}: slip F1 {f['slip_f1']:.3f}, {f['slip_hits']:.0f} of {f['slip_true']:.0f} found, "
            f"{f['slip_found']:.0f} flagged, {within:.0f} within 20 ms")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "out-sessions"),
                        help="the sessions script's output folder (default examples/out-sessions)")
    parser.add_argument("--keep-share", default="1,0.5", help="comma-separated shares of the bars to compare")
    args = parser.parse_args(argv)
    shares = [float(value) for value in args.keep_share.split(",")]
    folders = [os.path.join(args.sessions, name) for name in FOLDERS if os.path.exists(os.path.join(args.sessions, name, "frames.arrows"))]
    if not folders:
        raise SystemExit(f"no sessions under {args.sessions}: run examples/sessions.py first")
    pooled = {share: ([], []) for share in shares}
    for folder in folders:
        for name, share, truth, flags in score_folder(folder, shares):
            pooled[share][0].append(truth)
            pooled[share][1].append(flags)
            print(line(f"{name:20s} keep {share:g}", figures([truth], [flags])))
    for share, (truths, flags) in pooled.items():
        print(line(f"pooled, keep {share:g}", figures(truths, flags)))


if __name__ == "__main__":
    main()
