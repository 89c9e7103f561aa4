"""Slip bars that follow the stream's own presses, against the training's bars held fixed, detection alone.

A model carries the slip bars of the sensor it was trained on (`ops.contact.slip_for` of the training
contacts' presses and releases); at run time they follow the median press of the stream's last
contacts (`ops.contact.follow_gain`). Scored with the true force ending contacts, as
`examples/slip_hysteresis.py` does:

1. The sessions script's sessions (`examples/sessions.py`'s output folder) with the bars of its
   default-physics training sessions: the default test sessions (the same sensor), the randomised
   training sessions and the unseen-physics sessions (other sensors).
2. The rig-sessions script's rigs (`examples/rig_sessions.py`'s output folder), each with the bars of
   its own first two sessions, scored on its third (the same sensor, another day's grasps).

Prints one line per session and way, then the figures pooled per group. The figures of
docs/design.md ("The slip bars follow the stream's own presses") come from this script.

    python examples/slip_gain.py --sessions examples/out-sessions --rigs examples/out-rigs
"""

import argparse
import dataclasses
import os

from neurotac_cli import tables
from neurotac_cli.ops import contact as detector
from rig_sessions import detection_config, peaks_of, streams  # beside this script
from slip_hysteresis import figures, line  # beside this script

GROUPS = ("test", "train-randomised", "unseen")
WAYS = ("fixed", "follow")


def bars_of(training) -> detector.SlipConfig:
    """The bars `train --contacts` sets from these streams' true contacts."""
    return detector.slip_for(*peaks_of(training))


def score(stream, bars, config) -> dict:
    """The slip flags of one stream, the bars held fixed and followed: {way: flags}."""
    out = {}
    for way in WAYS:
        slip = bars if way == "follow" else dataclasses.replace(bars, follow_presses=0)
        _, _, out[way], _ = detector.detect(config, stream["off"], stream["on"], separation=stream["separation"], slip=slip,
                                            force=stream["force"], counts=stream["counts"])
    return out


def read(path):
    return streams(tables.read([path])) if os.path.exists(path) else None


def main(argv=None):
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", default=os.path.join(here, "out-sessions"), help="the sessions script's output folder")
    parser.add_argument("--bars-from", default="train", help="the sessions folder whose sessions set the model's bars")
    parser.add_argument("--rigs", default=os.path.join(here, "out-rigs"), help="the rig-sessions script's output folder")
    args = parser.parse_args(argv)
    training = read(os.path.join(args.sessions, args.bars_from, "frames.arrows"))
    rigs = sorted(name for name in os.listdir(args.rigs) if os.path.exists(os.path.join(args.rigs, name, "frames.arrows"))) \
        if os.path.isdir(args.rigs) else []
    if training is None and not rigs:
        raise SystemExit(f"no sessions under {args.sessions}/{args.bars_from} and no rigs under {args.rigs}: "
                         "run examples/sessions.py or examples/rig_sessions.py first")
    pooled = {}

    def add(group, name, stream, flags):
        for way in WAYS:
            truths, flagged = pooled.setdefault((group, way), ([], []))
            truths.append(stream["slip"])
            flagged.append(flags[way])
            print(line(f"{name:22s} {way:6s}", figures([stream["slip"]], [flags[way]])), flush=True)

    if training is not None:
        bars = bars_of(training)
        print(f"bars from {args.bars_from}: {bars.min_events:g} OFF, {bars.on_events:g} ON events (median press {bars.press_off:g})")
        for group in GROUPS:
            for index, stream in enumerate(read(os.path.join(args.sessions, group, "frames.arrows")) or []):
                add(group, f"{group}/{index}", stream, score(stream, bars, detection_config([stream])))
    for rig in rigs:
        sessions = read(os.path.join(args.rigs, rig, "frames.arrows"))
        add("rigs", rig, sessions[-1], score(sessions[-1], bars_of(sessions[:-1]), detection_config(sessions)))
    for (group, way), (truths, flagged) in pooled.items():
        print(line(f"pooled {group}, {way}", figures(truths, flagged)))


if __name__ == "__main__":
    main()
