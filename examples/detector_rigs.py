"""Contact and slip detection on rigs of other physics: the slip bar a fixed count, or scaled to the rig's presses.

Each rig is one draw of every physics family of the simulator over its whole range (thresholds,
membrane, optics, noise, force sensor, objects: `results.py`'s `rig`), kept for three sessions of 20
grasps (`simulate --session --set ...`). The first two sessions stand in for the rig's training
sessions: the median press peak of their contacts sets the slip bar (`ops.contact.slip_for`, what
`train --contacts` does); the third is scored. The detector runs with the true force standing in for a
force model's estimate, so what is measured is the detection, whatever a model would read. Rigs 201-210
chose the bar's share of the press and its noise floor; rigs 211-216 took no part in that choice.
Prints a markdown table and writes it to OUT/detector_rigs.md; without --quick, also into
docs/results.md (section "Sessions of many grasps", between the `results:detector-rigs` markers).
A run resumes: sessions already framed in OUT are reused.

    python examples/detector_rigs.py --quick   # two small rigs, about a minute
    python examples/detector_rigs.py           # 16 rigs, about 15 minutes on 2 cores
"""

import argparse
import concurrent.futures
import os
import sys

import numpy as np

from chapters import replace_section  # beside this script
from results import rig
from sessions import simulate
from neurotac_cli import metrics
from neurotac_cli.model import data as shaping
from neurotac_cli.model.session import RELEASE_SHARE
from neurotac_cli.ops import contact as detector

CHOICE_RIGS, CHECK_RIGS = tuple(range(201, 211)), tuple(range(211, 217))
FIXED = detector.SlipConfig(min_events=50.0, noise_sigma=0.0)  # one bar for every rig, no noise floor
WINDOW_MS = 10


def streams(table):
    """Per session: OFF, ON, centroid separation, true force (0 where unknown), touching and slip truth."""
    data = shaping.sequences(table)
    trial = np.asarray(table.column("trial").to_pylist(), dtype=object)
    slip = table.column("slip").to_numpy(zero_copy_only=False)
    out = []
    for name, counts, force, phase in zip(data.trials, data.counts, data.force, data.phase):
        off, on, separation = detector.frame_stats(counts)
        out.append(dict(off=off, on=on, separation=separation, force=np.nan_to_num(force),
                        touching=np.asarray([p not in (None, "none") for p in phase]), slip=slip[trial == name]))
    return out


def run(config, slip, stream):
    """Contact and slip flags per frame, as `model.session.Stream` makes them, the true force ending contacts."""
    state = detector.ContactState.start(config)
    contact, flags = np.zeros(len(stream["off"]), bool), np.zeros(len(stream["off"]), bool)
    for k, (off, on, force) in enumerate(zip(stream["off"], stream["on"], stream["force"])):
        phase = detector.step(config, state, off, on, by_force=True)
        if phase != detector.NONE:
            state.peak_force = max(state.peak_force, float(force))
            if state.released and detector.end_by_force(config, state, float(force)):
                phase = detector.NONE
        contact[k] = phase != detector.NONE
        flags[k] = detector.slip_step(slip, state, off, on, float(stream["separation"][k]))
    return contact, flags


def one_rig(seed, out, grasps):
    options, about = rig(seed)
    table = simulate(os.path.join(out, f"rig{seed}"), seed, 3, grasps, None, tuple(options.split()))
    sessions = streams(table)
    training, test = sessions[:2], sessions[2:]
    press = float(np.median([p for s in training for p in detector.press_peaks(s["off"], metrics.runs(s["touching"]))]))
    config = detector.ContactConfig(release_force_n=RELEASE_SHARE * max(float(s["force"].max()) for s in sessions))
    scaled = detector.slip_for(press)
    figures = {}
    for name, slip in (("fixed", FIXED), ("scaled", scaled)):
        contact, flags = zip(*(run(config, slip, s) for s in test))
        figures[name] = metrics.detection_figures([s["slip"] for s in test], flags, "slip", unit=WINDOW_MS,
                                                  suffix="latency_ms", tolerance=20.0)
        figures["contact"] = metrics.detection_figures([s["touching"] for s in test], contact, "contact", suffix="onset_frames")
    return seed, about, press, scaled.min_events, figures


def pooled(rows, name):
    hits = sum(f[name]["slip_hits"] for *_, f in rows)
    true = sum(f[name]["slip_true"] for *_, f in rows)
    found = sum(f[name]["slip_found"] for *_, f in rows)
    return 2 * hits / (true + found) if true + found else float("nan"), int(hits), int(true), int(found)


def table_lines(rows) -> list:
    fmt = lambda v, d=2: "" if v is None or not np.isfinite(v) else f"{v:.{d}f}"  # noqa: E731
    lines = ["| rig | physics | press peak (events) | slip bar | slip F1, fixed 50 | within 20 ms | slip F1, scaled | within 20 ms "
             "| slips | contact F1 |", "|---|---|---|---|---|---|---|---|---|---|"]
    for seed, about, press, bar, f in rows:
        lines.append(f"| {seed} | {about} | {press:.0f} | {bar:g} | {fmt(f['fixed']['slip_f1'])} | "
                     f"{fmt(f['fixed'].get('slip_within_20'))} | {fmt(f['scaled']['slip_f1'])} | {fmt(f['scaled'].get('slip_within_20'))} "
                     f"| {int(f['scaled']['slip_true'])} | {fmt(f['contact']['contact_f1'])} |")
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two rigs of 4-grasp sessions (about a minute)")
    parser.add_argument("--out", default=None, help="folder for the sessions and detector_rigs.md (default examples/out-detector[-quick])")
    parser.add_argument("--jobs", type=int, default=2, help="rigs simulated at once (default 2)")
    args = parser.parse_args(argv)
    here = os.path.dirname(os.path.abspath(__file__))
    out = args.out or os.path.join(here, "out-detector-quick" if args.quick else "out-detector")
    os.makedirs(out, exist_ok=True)
    seeds, grasps = ((CHOICE_RIGS[0], CHECK_RIGS[0]), 4) if args.quick else (CHOICE_RIGS + CHECK_RIGS, 20)
    with concurrent.futures.ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(one_rig, seeds, [out] * len(seeds), [grasps] * len(seeds)))
    lines = [f"Each rig: three sessions of {grasps} grasps with one draw of every physics family; the slip bar from the first "
             "two sessions' presses, the third scored, the true force ending contacts. Fixed: 50 events of each polarity "
             f"above the background; scaled: {detector.SLIP_SHARE:g} of the rig's median press peak, at least "
             f"{detector.SLIP_FLOOR_EVENTS:g} events and {detector.SlipConfig.noise_sigma:g} Poisson σ of the background.", ""]
    lines += table_lines(rows) + [""]
    for label, group in (("rigs that chose the bar", CHOICE_RIGS), ("rigs that took no part in the choice", CHECK_RIGS)):
        mine = [row for row in rows if row[0] in group]
        if mine:
            fixed, scaled = pooled(mine, "fixed"), pooled(mine, "scaled")
            lines.append(f"- {label} ({len(mine)}): slip F1 pooled over their test sessions, fixed {fixed[0]:.3f} "
                         f"({fixed[1]} of {fixed[2]} slips, {fixed[3]} flagged), scaled {scaled[0]:.3f} "
                         f"({scaled[1]} of {scaled[2]}, {scaled[3]} flagged)")
    text = "\n".join(lines) + "\n"
    print(text)
    with open(os.path.join(out, "detector_rigs.md"), "w", encoding="utf-8") as sink:
        sink.write(text)
    if not args.quick:
        page = os.path.join(here, "..", "docs", "results.md")
        with open(page, encoding="utf-8") as source:
            before = source.read()
        body = f"Made by `make -C examples detector-rigs` (`examples/detector_rigs.py`).\n\n{text}"
        with open(page, "w", encoding="utf-8") as sink:
            sink.write(replace_section(before, "detector-rigs", body, title="Contact and slip detection on rigs of other physics"))
        print(f"wrote {os.path.abspath(page)}", file=sys.stderr)


if __name__ == "__main__":
    main()
