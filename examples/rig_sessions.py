"""Sessions on rigs of other physics, each trained on its own sessions: detection, and deform-gru's force.

Each rig is one draw of every physics family of the simulator over its whole range (thresholds,
membrane, optics, noise, force sensor, objects: `results.py`'s `rig`), kept for three sessions of 20
grasps (`simulate --session --set ...`), as a lab with its own sensor would record them. The first two
sessions are the rig's training sessions, the third is scored; a rig of the default physics is the
reference.

1. Detection alone: the median press and release peaks of the training sessions' contacts set the slip bars
   (`ops.contact.slip_for`, what `train --contacts` does) until the scored session's own presses take
   over (`ops.contact.follow_gain`), against one fixed bar for every rig; the
   detector runs with the true force standing in for a force model's estimate (`ops.contact.detect`
   with `force`), so what is measured is the detection, whatever a model would read. Rigs 201-210 chose the bar's share of the press and
   its noise floor; rigs 211-216 took no part in that choice.
2. With --model: the model trained on the rig's training sessions (`train --contacts`) and scored on
   the third as `predict` runs it: RMSE in contact against the same grasps cut into trials and
   against the default physics, error at rest, drift, contact and slip detection.

Prints markdown tables and writes them to OUT/rig_sessions.md; a run of every rig with the model also
writes them into docs/results.md (between the `results:rig-sessions` markers). A run resumes:
sessions framed and models trained in OUT are reused.

    python examples/rig_sessions.py --quick                 # two small rigs, about a minute
    python examples/rig_sessions.py --model deform-gru      # 16 rigs and the default, about 40 minutes on 2 cores
"""

import argparse
import os

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from chapters import RESULTS_PAGE, publish_section  # beside this script
from results import add_jobs_option, each_rig, rig
from sessions import cut_into_trials, detection_cells, rest_cells, score, simulate, span
from neurotac_cli import metrics
from neurotac_cli import model as models
from neurotac_cli.model import data as shaping
from neurotac_cli.model import session
from neurotac_cli.ops import contact as detector

DEFAULT_RIG = 200  # the simulator's default physics, for reference
CHOICE_RIGS, CHECK_RIGS = tuple(range(201, 211)), tuple(range(211, 217))
FIXED = detector.SlipConfig(min_events=50.0, noise_sigma=0.0, follow_presses=0)  # one bar for every rig, no noise floor
WINDOW_MS = 10
EPOCHS, PATIENCE = 200, 15


def streams(table):
    """Per session: its frames, OFF, ON, centroid separation, true force (0 where unknown), touching and slip truth."""
    data = shaping.sequences(table)
    trial = np.asarray(table.column("trial").to_pylist(), dtype=object)
    slip = table.column("slip").to_numpy(zero_copy_only=False)
    out = []
    for name, counts, force, phase in zip(data.trials, data.counts, data.force, data.phase):
        off, on, separation = detector.frame_stats(counts)
        out.append(dict(counts=counts, off=off, on=on, separation=separation, force=np.nan_to_num(force),
                        touching=np.asarray([p not in (None, "none") for p in phase]), slip=slip[trial == name]))
    return out


def peaks_of(training) -> tuple:
    """(median press OFF peak, median release ON peak) of the streams' true contacts: what `train --contacts` sets the slip bars from."""
    return detector.rig_peaks([(s["off"], s["on"], metrics.runs(s["touching"])) for s in training])


def detection_config(streams) -> detector.ContactConfig:
    """The detector's settings as a model trained on these streams' force range ends contacts with them."""
    return detector.ContactConfig(release_force_n=session.RELEASE_SHARE * max(float(s["force"].max()) for s in streams))


def detection(training, test):
    """Slip figures with the fixed and the scaled bar, and contact figures, on the test streams."""
    press, release = peaks_of(training)
    config = detection_config(training + test)
    scaled = detector.slip_for(press, release)
    figures = {"press": press, "bar": scaled.min_events, "on_bar": scaled.on_events}
    for name, slip in (("fixed", FIXED), ("scaled", scaled)):
        # the slip flags do not change where contacts end, so both bars find the same contacts
        phases, _, flags, _ = zip(*(detector.detect(config, s["off"], s["on"], separation=s["separation"], slip=slip,
                                                    force=s["force"], counts=s["counts"]) for s in test))
        figures[name] = metrics.detection_figures([s["slip"] for s in test], flags, "slip", unit=WINDOW_MS, **metrics.SLIP_TIMING)
    figures["contact"] = metrics.detection_figures([s["touching"] for s in test], [p != detector.NONE for p in phases], "contact")
    return figures


def trained(name, training, folder, epochs):
    """The model trained on the rig's training sessions, one saved in `folder` before reused."""
    import torch

    torch.set_num_threads(1)
    path = os.path.join(folder, f"{name}.model")
    if os.path.exists(path):
        return models.load(path)
    model = session.train(training, models.make_spec(name, epochs=epochs, patience=PATIENCE), val_fraction=0.15, seed=1)
    models.save(model, path)
    return model


def one_rig(seed, out, grasps, model_name, epochs):
    options, about = rig(seed) if seed != DEFAULT_RIG else ("", "the simulator's default physics")
    folder = os.path.join(out, f"rig{seed}")
    table = simulate(folder, seed, 3, grasps, None, tuple(options.split()))
    names = list(dict.fromkeys(table.column("trial").to_pylist()))
    sessions = streams(table)
    figures = {"about": about, "detection": detection(sessions[:2], sessions[2:])}
    if model_name:
        trial = pa.array(table.column("trial").to_pylist())
        is_test = pc.equal(trial, names[2])
        training, test = table.filter(pc.invert(is_test)), table.filter(is_test)
        model = trained(model_name, training, folder, epochs)
        figures.update(session=score(model, test), cut=score(model, cut_into_trials(test)), range=span(test))
    return seed, figures


def pooled(rows, name):
    hits = sum(f["detection"][name]["slip_hits"] for _, f in rows)
    true = sum(f["detection"][name]["slip_true"] for _, f in rows)
    found = sum(f["detection"][name]["slip_found"] for _, f in rows)
    return 2 * hits / (true + found) if true + found else float("nan"), int(hits), int(true), int(found)


def fmt(value, digits=2):
    return "" if value is None or not np.isfinite(value) else f"{value:.{digits}f}"


def detection_lines(rows) -> list:
    lines = ["| rig | physics | press peak (events) | slip bar, OFF / ON | slip F1, fixed 50 | within 20 ms | slip F1, scaled | within 20 ms "
             "| slips | contact F1 |", "|---|---|---|---|---|---|---|---|---|---|"]
    for seed, f in rows:
        d = f["detection"]
        lines.append(f"| {seed} | {f['about']} | {d['press']:.0f} | {d['bar']:g} / {d['on_bar']:g} | {fmt(d['fixed']['slip_f1'])} | "
                     f"{fmt(d['fixed'].get('slip_within_20'))} | {fmt(d['scaled']['slip_f1'])} | {fmt(d['scaled'].get('slip_within_20'))} "
                     f"| {int(d['scaled']['slip_true'])} | {fmt(d['contact']['contact_f1'])} |")
    lines.append("")
    for label, group in (("rigs that chose the bar", CHOICE_RIGS), ("rigs that took no part in the choice", CHECK_RIGS)):
        mine = [row for row in rows if row[0] in group]
        if mine:
            fixed, scaled = pooled(mine, "fixed"), pooled(mine, "scaled")
            lines.append(f"- {label} ({len(mine)}): slip F1 pooled over their test sessions, fixed {fixed[0]:.3f} "
                         f"({fixed[1]} of {fixed[2]} slips, {fixed[3]} flagged), scaled {scaled[0]:.3f} "
                         f"({scaled[1]} of {scaled[2]}, {scaled[3]} flagged)")
    return lines


def model_lines(rows, model_name) -> list:
    default = dict(rows).get(DEFAULT_RIG)
    base = 100 * default["session"]["contact_rmse"] / default["range"] if default else float("nan")
    lines = [f"| rig | {model_name}: RMSE in contact (% of range) | against cut trials (goal <= 1.25) | against the default physics "
             "(goal <= 1.5) | rest mean abs error (% of range; goal < 2) | drift (% of range per min; goal < 0.5) | contact F1 "
             "(goal >= 0.98) | onsets within 2 frames | slip F1 (goal >= 0.9) | slips within 20 ms |", "|" + "---|" * 10]
    for seed, f in rows:
        s, c, spread = f["session"], f["cut"], f["range"]
        share = 100 * s["contact_rmse"] / spread
        lines.append(f"| {'default' if seed == DEFAULT_RIG else seed} | {share:.1f} | {fmt(s['contact_rmse'] / c['contact_rmse'])} "
                     f"| {fmt(share / base)} {rest_cells(s, spread)}{detection_cells(s)}|")
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two rigs of 4-grasp sessions, few epochs (about a minute)")
    parser.add_argument("--model", default=None, help="a force model to train on each rig's sessions (e.g. deform-gru)")
    parser.add_argument("--out", default=None, help="folder for sessions, models and rig_sessions.md (default examples/out-rigs[-quick])")
    add_jobs_option(parser)
    args = parser.parse_args(argv)
    here = os.path.dirname(os.path.abspath(__file__))
    out = args.out or os.path.join(here, "out-rigs-quick" if args.quick else "out-rigs")
    os.makedirs(out, exist_ok=True)
    if args.quick:
        seeds, grasps, epochs = (CHOICE_RIGS[0], CHECK_RIGS[0]), 4, 3
    else:
        seeds, grasps, epochs = ((DEFAULT_RIG,) if args.model else ()) + CHOICE_RIGS + CHECK_RIGS, 20, EPOCHS
    rows = each_rig(args.jobs, one_rig, seeds, out, grasps, args.model, epochs)
    lines = [f"Each rig: three sessions of {grasps} grasps with one draw of every physics family. Detection alone: the slip bars "
             "from the first two sessions' presses and releases, the third scored, the true force ending contacts. Fixed: 50 events of each "
             f"polarity above the background; scaled: {detector.SLIP_SHARE:g} of the rig's median press peak, at least "
             f"{detector.SLIP_FLOOR_EVENTS:g} events and {detector.SlipConfig.noise_sigma:g} Poisson σ of the background, "
             "for the ON events times the ratio of the median release's ON peak to the median press's OFF peak (at most 1); "
             "from the scored session's first contact on, the same of the median of its own last presses.", ""]
    lines += detection_lines([row for row in rows if row[0] != DEFAULT_RIG])
    if args.model:
        lines += ["", f"{args.model} trained on each rig's first two sessions (`train --contacts`, at most {epochs} epochs, "
                  f"patience {PATIENCE}) and run over the third as `predict` runs it; the default rig (seed {DEFAULT_RIG}) is the "
                  "reference for the ratio to the default physics.", ""]
        lines += model_lines(rows, args.model)
    text = "\n".join(lines) + "\n"
    print(text)
    with open(os.path.join(out, "rig_sessions.md"), "w", encoding="utf-8") as sink:
        sink.write(text)
    if not args.quick and args.model:
        publish(f"Made by `make -C examples rig-sessions` (`examples/rig_sessions.py --model {args.model}`).\n\n{text}")


def publish(body: str, page=RESULTS_PAGE):
    """The tables into `page` (docs/results.md), between its `results:rig-sessions` markers."""
    publish_section("rig-sessions", body, "Sessions on rigs of other physics", page)


if __name__ == "__main__":
    main()
