"""Time one task of a cross-validation study: the first fold's training of one model spec.

    python examples/time_one_task.py FRAMES MODEL [--cv loo] [--fold 0] [--set layers=4 ...] [--epochs N]

Runs `neurotac_cli.model.cv.run_fold` for one fold exactly as `neurotac eval --cv` (and `neurotac
study`) would, on one thread like every study task, and prints one JSON line: wall and CPU seconds,
epochs trained, seconds per epoch, and the fold's validation MSE. With `--epochs N` the training is
capped at N epochs, to measure seconds per epoch of a model whose full training is too long to wait
for here; a full task then costs about seconds per epoch x the epochs early stopping runs.
"""

import argparse
import json
import resource
import time

from neurotac_cli import model as models
from neurotac_cli import tables
from neurotac_cli.model.cv import fold_tasks, run_fold
from neurotac_cli.model.data import sequences
from neurotac_cli.study import _one_thread, parse_grid


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("frames")
    parser.add_argument("model")
    parser.add_argument("--cv", default="loo")
    parser.add_argument("--fold", type=int, default=0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--val-per", default=None)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="hyperparameters (as --grid, one value each)")
    parser.add_argument("--epochs", type=int, default=None, help="cap the epochs (seconds per epoch of a long training)")
    args = parser.parse_args(argv)
    options = parse_grid(args.set)[0]  # the grid's grammar; a name with several values takes its first
    if args.epochs:
        options["epochs"] = args.epochs
    spec = models.make_spec(args.model, **options)
    frames = tables.read([args.frames], kind="frames")
    groups, tasks = fold_tasks(sequences(frames), spec, args.cv, 1, args.seed, 0.1, args.val_per)
    task = tasks[args.fold]
    with _one_thread():
        started, cpu = time.monotonic(), resource.getrusage(resource.RUSAGE_SELF)
        _, validation = run_fold(frames, **task)
        wall = time.monotonic() - started
        after = resource.getrusage(resource.RUSAGE_SELF)
    cpu_s = (after.ru_utime - cpu.ru_utime) + (after.ru_stime - cpu.ru_stime)
    epochs = validation.get("epochs", float("nan"))
    print(json.dumps({"model": args.model, "spec": spec, "cv": args.cv, "folds": len(groups), "wall_s": round(wall, 2),
                      "cpu_s": round(cpu_s, 2), "epochs": epochs, "best_epoch": validation.get("best_epoch"),
                      "s_per_epoch": round(wall / epochs, 3) if epochs == epochs and epochs else None,
                      "val": {k: v for k, v in validation.items() if k.startswith("val_")}}))


if __name__ == "__main__":
    main()
