"""Force models on sessions of many grasps: error in contact against the same grasps cut into trials,
at rest, drift, contact and slip detection, in one table.

Simulates training and test sessions (`neurotac simulate --session`, test seeds that training never
saw), frames them through the CLI (`sync | crop --pool 6x6 | frame --window 10ms --phases session
--slips grasps.csv`: each frame's slip truth from the grasps' manifest), trains deform-gru, the
thesis's LSTM and ConvLSTM on the contacts the event detector finds (`train --contacts`), and scores
each on the test sessions and on the same grasps cut into trials; then on sessions whose physics
training never saw (`simulate --vary all --unseen membrane`: pixels, optics, noise, force sensor and
objects drawn from wide ranges, the membrane from the upper third of its ranges), beside deform-gru
and the LSTM trained on randomised sessions (`--vary all --hold-out membrane`). Prints markdown
tables and writes them to OUT/sessions.md; the full run also writes them into docs/results.md
(section "Sessions of many grasps"), the quick run never.
The run resumes: framed sessions and trained models found in OUT are reused (a model's training time
is kept beside it in NAME.seconds), so a run cut off, or one adding a model, trains only what is missing.

    python examples/sessions.py --quick            # seconds to a minute: tiny sessions, few epochs
    python examples/sessions.py --out out/sessions # the goals' size: 50-grasp sessions of >= 5 min
    python examples/sessions.py --models deform-gru --randomised-models deform-gru --replace-rows
                                                   # deform-gru's rows re-made, the other models' kept

The full mode took about 40 minutes on the 2-core machine (25 Nov 2026, its models split over two
processes; the ConvLSTM's 10 epochs over 200 contacts were 21 minutes of it); on a machine shared
with other work its parts summed to 1 h 50 min of one core. With the data and models in OUT, a run
only scores (minutes).
The LSTM has 2 layers of 32 units (the thesis: 6).

The frames are the whole 240x180 sensor sum-pooled 6x6 (40x30): slips carry the object far from
the centre, and on a CPU the ConvLSTM trains on sessions only at that size.
"""

import argparse
import os
import subprocess
import sys
import time

import numpy as np
import pyarrow as pa

from neurotac_cli import tables
from chapters import RESULTS_PAGE, publish_section, section_body  # beside this script
from neurotac_cli import model as models
from neurotac_cli.model import evaluate, session

FULL = dict(train_sessions=4, train_grasps=50, test_sessions=2, test_grasps=50, duration="5min", empty="2min",
            unseen_sessions=3, unseen_grasps=20,
            epochs={"deform-gru": 200, "lstm": 60, "convlstm": 10}, patience=15)
QUICK = dict(train_sessions=1, train_grasps=4, test_sessions=1, test_grasps=2, duration=None, empty="10s",
             unseen_sessions=1, unseen_grasps=2,
             epochs={"deform-gru": 15, "lstm": 3, "convlstm": 1}, patience=5)
MODELS = {"deform-gru": {}, "lstm": {"layers": 2}, "convlstm": {}}
TRAIN_SEED, TEST_SEED, UNSEEN_SEED, RANDOMISED_SEED = 1501, 3501, 4501, 5501  # not 2501: that session chose the detector's settings
# Domain randomisation: every physics family drawn per session from wide ranges, the membrane's from the
# lower two thirds of its ranges for training and from the upper third for the unseen test sessions.
RANDOMISED, UNSEEN = ("--vary", "all", "--hold-out", "membrane"), ("--vary", "all", "--unseen", "membrane")
RANDOMISED_MODELS = "deform-gru,lstm"  # the ConvLSTM trains for about 45 min a set on 2 cores: default physics only
CUT_MARGIN = 20  # frames kept before a grasp's first contact and after its release when cut into a trial
WINDOW_MS = 10


def simulate(folder, seed, sessions, grasps, duration, physics=()):
    """Session recordings into `folder` (`physics`: more simulate options), framed into
    folder/frames.arrows (with a slip truth column)."""
    frames = os.path.join(folder, "frames.arrows")
    if os.path.exists(frames):
        return tables.read([frames])
    args = ["simulate", "--session", "--grasps", str(grasps), "--sessions", str(sessions), "--seed", str(seed), "--out", folder]
    run_cli(args + (["--duration", duration] if duration else []) + list(physics))
    pipe = (f"neurotac sync --manifest {folder}/manifest.csv | neurotac crop --pool 6x6 "
            f"| neurotac frame --window {WINDOW_MS}ms --phases session --slips {folder}/grasps.csv")
    done = subprocess.run(pipe, shell=True, capture_output=True, check=False)
    if done.returncode:
        sys.exit(f"sessions.py: framing failed: {done.stderr.decode(errors='replace').strip()}")
    table = _read_stream(done.stdout)
    tables.write(frames, table)
    return table


def _read_stream(data: bytes) -> pa.Table:
    import pyarrow.ipc as ipc

    return ipc.open_stream(data).read_all()


def run_cli(args):
    done = subprocess.run(["neurotac", *args], capture_output=True, check=False)
    if done.returncode:
        sys.exit(f"sessions.py: neurotac {' '.join(args)} failed: {done.stderr.decode(errors='replace').strip()}")


def cut_into_trials(table: pa.Table) -> pa.Table:
    """Each grasp of each session as a trial of its own: its frames with CUT_MARGIN frames either side."""
    trial = np.asarray(table.column("trial").to_pylist(), dtype=object)
    grasp = table.column("grasp").to_numpy(zero_copy_only=False)
    rows, names = [], []
    for name in dict.fromkeys(trial):
        mine = np.flatnonzero(trial == name)
        for index in sorted(set(grasp[mine][grasp[mine] >= 0].tolist())):
            inside = mine[grasp[mine] == index]
            lo, hi = max(inside[0] - CUT_MARGIN, mine[0]), min(inside[-1] + CUT_MARGIN + 1, mine[-1] + 1)
            rows += range(lo, hi)
            names += [f"{name}/grasp{index:02d}"] * (hi - lo)
    cut = table.take(pa.array(rows, pa.int64()))
    return cut.set_column(cut.schema.get_field_index("trial"), "trial", pa.array(names, pa.string()))


def score(model, table: pa.Table) -> dict:
    _, rows = evaluate.evaluate_model(model, table, per_trial=False)
    return {metric: value for scope, metric, value in rows if scope == "all"}


def train_one(name, train, size, out, seed=1, tag=""):
    """The model trained on `train`, and its training's wall seconds; one saved in `out` (as NAME`tag`.model)
    before is reused."""
    path, seconds_path = os.path.join(out, f"{name}{tag}.model"), os.path.join(out, f"{name}{tag}.seconds")
    if os.path.exists(path) and os.path.exists(seconds_path):
        with open(seconds_path, encoding="utf-8") as source:
            return models.load(path), float(source.read())
    spec = models.make_spec(name, **MODELS[name], epochs=size["epochs"][name], patience=size["patience"])
    started = time.monotonic()
    model = session.train(train, spec, val_fraction=0.15, seed=seed)
    seconds = time.monotonic() - started
    models.save(model, path)
    with open(seconds_path, "w", encoding="utf-8") as sink:
        sink.write(f"{seconds:.1f}\n")
    return model, seconds


def table_rows(results: dict, force_range: float) -> list[str]:
    pct = lambda v: 100 * v / force_range  # noqa: E731
    lines = ["| model | RMSE in contact, sessions (N) | same grasps cut into trials (N) | ratio (goal <= 1.25) "
             "| rest mean abs error (% of range; goal < 2) | rest max (N) | drift (% of range per min; goal < 0.5) "
             "| contact F1 (goal >= 0.98) | onsets within 2 frames | slip F1 (goal >= 0.9) | slips within 20 ms | R² "
             "| no-grasp session: max abs (N), contacts | train (s) |",
             "|" + "---|" * 14]
    for name, (s, c, seconds, empty) in results.items():
        lines.append(
            f"| {name} | {s['contact_rmse']:.3f} | {c['contact_rmse']:.3f} | {s['contact_rmse'] / c['contact_rmse']:.2f} "
            f"| {pct(s['rest_mean_abs']):.2f} | {s['rest_max_abs']:.3f} | {pct(abs(s['drift_n_per_min'])):.3f} "
            f"{detection_cells(s)}| {s['r2']:.3f} | {empty['rest_max_abs']:.3f}, {int(empty.get('contact_found', 0))} | {seconds:.0f} |")
    return lines


def detection_cells(figures: dict) -> str:
    """Contact F1, onsets within 2 frames, slip F1, slips within 20 ms: the detection cells of every session table."""
    nan = float("nan")
    return (f"| {figures['contact_f1']:.3f} | {figures.get('contact_within_2', nan):.3f} | {figures.get('slip_f1', nan):.3f} "
            f"| {figures.get('slip_within_20', nan):.3f} ")


def rest_cells(figures: dict, force_range: float) -> str:
    """Mean |estimate| at rest and its drift, as % of the force range (drift per minute)."""
    return f"| {100 * figures['rest_mean_abs'] / force_range:.2f} | {100 * abs(figures['drift_n_per_min']) / force_range:.3f} "


def span(table: pa.Table) -> float:
    force = table.column("force").to_numpy(zero_copy_only=False)
    return float(np.nanmax(force) - np.nanmin(force))


def unseen_rows(results: dict, unseen_range: float, force_range: float) -> list[str]:
    """Each model on unseen physics against itself on the default-physics test sessions (errors as shares of
    each set's force range, so a wider range of forces does not pass for a larger error)."""
    lines = ["| model | RMSE in contact (N) | % of range | default-physics test sessions (% of range) | ratio (goal <= 1.5) "
             "| rest mean abs error (% of range) | drift (% of range per min) | contact F1 | onsets within 2 frames | slip F1 "
             "| slips within 20 ms | R² | train (s) |",
             "|" + "---|" * 13]
    for name, (v, seen, seconds) in results.items():
        share, seen_share = 100 * v["contact_rmse"] / unseen_range, 100 * seen["contact_rmse"] / force_range
        lines.append(f"| {name} | {v['contact_rmse']:.3f} | {share:.1f} | {seen_share:.1f} | {share / seen_share:.2f} "
                     f"{rest_cells(v, unseen_range)}{detection_cells(v)}| {v['r2']:.3f} | {seconds:.0f} |")
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny sessions and few epochs (seconds to a minute)")
    parser.add_argument("--out", default=None, help="folder for data, models and sessions.md (default examples/out-sessions[-quick])")
    parser.add_argument("--models", default=",".join(MODELS), help="comma-separated models to train (default all three)")
    parser.add_argument("--train-sessions", type=int, default=None, help="override the mode's number of training sessions")
    parser.add_argument("--train-grasps", type=int, default=None, help="override the grasps per training session")
    parser.add_argument("--test-sessions", type=int, default=None, help="override the number of test sessions")
    parser.add_argument("--randomised-models", default=RANDOMISED_MODELS,
                        help=f"comma-separated models also trained on domain-randomised sessions (default {RANDOMISED_MODELS}; '' for none)")
    parser.add_argument("--epochs", default=None, metavar="MODEL=N,...", help="override the most epochs per model, e.g. convlstm=2")
    parser.add_argument("--replace-rows", action="store_true",
                        help="publish a run of fewer models by replacing their rows in the published tables, keeping the other "
                             "models' rows (the same sessions and seeds: for re-making one model's rows after it changed)")
    args = parser.parse_args(argv)
    size = dict(QUICK if args.quick else FULL)
    for key in ("train_sessions", "train_grasps", "test_sessions"):
        if getattr(args, key) is not None:
            size[key] = getattr(args, key)
    if args.epochs:
        size["epochs"] = dict(size["epochs"], **{k: int(v) for k, v in (item.split("=") for item in args.epochs.split(","))})
    here = os.path.dirname(os.path.abspath(__file__))
    out = args.out or os.path.join(here, "out-sessions-quick" if args.quick else "out-sessions")
    os.makedirs(out, exist_ok=True)
    import torch

    torch.set_num_threads(1)
    train = simulate(os.path.join(out, "train"), TRAIN_SEED, size["train_sessions"], size["train_grasps"], None)
    test = simulate(os.path.join(out, "test"), TEST_SEED, size["test_sessions"], size["test_grasps"], size["duration"])
    cut = cut_into_trials(test)
    empty = simulate(os.path.join(out, "empty"), TEST_SEED + 1, 1, 0, size["empty"])
    unseen = simulate(os.path.join(out, "unseen"), UNSEEN_SEED, size["unseen_sessions"], size["unseen_grasps"], None, UNSEEN)
    force_range = span(test)
    results, on_unseen = {}, {}
    for name in args.models.split(","):
        model, seconds = train_one(name, train, size, out)
        results[name] = (score(model, test), score(model, cut), seconds, score(model, empty))
        on_unseen[name] = (score(model, unseen), results[name][0], seconds)
        print(f"{name}: trained in {seconds:.0f} s", file=sys.stderr)
    randomised = [name for name in args.randomised_models.split(",") if name]
    if randomised:
        train_randomised = simulate(os.path.join(out, "train-randomised"), RANDOMISED_SEED, size["train_sessions"],
                                    size["train_grasps"], None, RANDOMISED)
        for name in randomised:
            model, seconds = train_one(name, train_randomised, size, out, tag="-randomised")
            on_unseen[f"{name}, randomised"] = (score(model, unseen), score(model, test), seconds)
    text = report(size, test, cut, unseen, force_range, results, on_unseen, constant_rmse(train, unseen))
    print(text)
    with open(os.path.join(out, "sessions.md"), "w", encoding="utf-8") as sink:
        sink.write(text)
    if publishes(args):
        publish(text)
    elif args.replace_rows and publishes(args, fewer_allowed=True):
        publish(merged_rows(published(), text))


def constant_rmse(train: pa.Table, table: pa.Table) -> tuple[float, float]:
    """(the training contacts' mean force, the RMSE in `table`'s contacts of a constant at it): the error of a
    sensor that reads every contact as the typical training grasp, which a model must beat to read force at all."""
    def in_contact(t):
        force = np.nan_to_num(t.column("force").to_numpy(zero_copy_only=False))
        return force[np.asarray([p not in (None, "none") for p in t.column("phase").to_pylist()])]

    mean = float(in_contact(train).mean())
    return mean, float(np.sqrt(np.mean((in_contact(table) - mean) ** 2)))


def report(size, test, cut, unseen, force_range, results, on_unseen, constant) -> str:
    """The run's two tables in markdown, each under a line saying what it measured, and what a constant
    reading (`constant_rmse`) scores on the unseen sessions."""
    minutes = test.num_rows * WINDOW_MS / 60000
    grasps = len(set(cut.column("trial").to_pylist()))
    lines = [f"Test: {size['test_sessions']} session(s), {grasps} grasps, {minutes:.1f} min (seed {TEST_SEED}); "
             f"training: {size['train_sessions']} session(s) of {size['train_grasps']} grasps (seed {TRAIN_SEED}); "
             f"force range {force_range:.2f} N; frames 40x30 (240x180 pooled 6x6), 10 ms; "
             f"epochs at most {', '.join(f'{k} {v}' for k, v in size['epochs'].items())}.", ""] + table_rows(results, force_range)
    lines += ["", f"On physics training never saw: {size['unseen_sessions']} session(s) of {size['unseen_grasps']} grasps "
              f"(seed {UNSEEN_SEED}), each with its pixels, optics, noise, force sensor and objects drawn from the simulator's "
              f"wide ranges and its membrane from the upper third of its ranges (`{' '.join(UNSEEN)}`); force range "
              f"{span(unseen):.2f} N. Each model trained on the default physics above, and (randomised) on "
              f"{size['train_sessions']} session(s) of {size['train_grasps']} grasps with every family drawn from its ranges "
              f"and the membrane from their lower two thirds (`{' '.join(RANDOMISED)}`, seed {RANDOMISED_SEED}).", ""]
    lines += unseen_rows(on_unseen, span(unseen), force_range)
    lines += ["", f"A constant at the training contacts' mean force ({constant[0]:.2f} N) reads these sessions' contacts at "
              f"RMSE {constant[1]:.3f} N ({100 * constant[1] / span(unseen):.1f}% of the range): a model at or above it "
              "tells these grasps' forces apart no better than that constant does, whatever its rank."]
    return "\n".join(lines) + "\n"


def publishes(args, fewer_allowed=False) -> bool:
    """Only a run at the goals' size goes on the published page; a quick or resized run stays in OUT.
    A run of fewer models only with `fewer_allowed` (its rows merged into the published tables)."""
    resized = args.epochs or any(getattr(args, key) is not None for key in ("train_sessions", "train_grasps", "test_sessions"))
    fewer = args.models != ",".join(MODELS) or args.randomised_models != RANDOMISED_MODELS  # a table without some rows
    return not args.quick and not resized and (fewer_allowed or not fewer)


PUBLISHED_HEAD = "Made by `make -C examples sessions` (`examples/sessions.py`)."


def publish(text: str, page=RESULTS_PAGE):
    """The table into `page` (docs/results.md), between its `results:sessions` markers."""
    publish_section("sessions", f"{PUBLISHED_HEAD}\n\n{text}", "Sessions of many grasps", page)


def published(page=RESULTS_PAGE) -> str:
    """The tables now between the page's `results:sessions` markers, without the line naming the script."""
    body = section_body(open(page, encoding="utf-8").read(), "sessions")
    if body is None:
        raise SystemExit(f"{page} has no published sessions tables whose rows could be replaced")
    return body.removeprefix(PUBLISHED_HEAD).strip() + "\n"


def merged_rows(old: str, new: str) -> str:
    """`old` tables with the rows `new` holds (a run of fewer models on the same sessions) in place of
    those models' rows. Every line that is not a model's row must read the same in both, or the
    sessions differ and nothing is merged."""
    def rows(text):  # each line with (its table's number, its model) for a model's row, None for any other line
        lines, table, out = text.splitlines(), 0, []
        for i, line in enumerate(lines):
            header = line.startswith("|") and i + 1 < len(lines) and lines[i + 1].startswith("|---")
            table += header
            is_row = line.startswith("|") and not header and not line.startswith("|---")
            out.append((line, (table, line.split("|")[1].strip()) if is_row else None))
        keys = [key for _, key in out if key is not None]
        if len(keys) != len(set(keys)):
            raise SystemExit("a sessions table names one model in two rows: run every model (no --replace-rows)")
        return out

    old_rows, new_rows = rows(old), rows(new)
    if [line for line, key in old_rows if key is None] != [line for line, key in new_rows if key is None]:
        raise SystemExit("the published sessions tables were made on other sessions or sizes: run every model (no --replace-rows)")
    fresh = {key: line for line, key in new_rows if key is not None}
    missing = {name for _, name in fresh} - {key[1] for _, key in old_rows if key is not None}
    if missing or not fresh:
        raise SystemExit(f"the published sessions tables have no row for {', '.join(sorted(missing)) or 'this run'}: run every model")
    return "\n".join(fresh.get(key, line) for line, key in old_rows) + "\n"


if __name__ == "__main__":
    main()
