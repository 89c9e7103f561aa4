"""Force models on physics training never saw, trained on more grasps of randomised physics.

The models section's "Physics training never saw" trains every force model on one set of 35 `ch4`
grasps whose physics is drawn per grasp (`simulate --vary all --hold-out membrane`, seed 11): every
grasp a sensor of its own, and 35 of them teach no model a reading that holds across sensors. Here
every force model trains on --sets such sets (seeds 11, 14, 15, ...: 35 grasps each, joined by
`concat --rename`) and is scored on the same grasps as there: seen physics (seed 12) and a
membrane from the upper third of its ranges (seed 13, `--unseen membrane`), so the two tables
compare row for row.

Writes the section between `<!-- results:physics-grasps:start -->` and
`<!-- results:physics-grasps:end -->` of docs/results.md, and WORK/physics_grasps.md (a quick or
resized run only the latter).

    make -C examples physics-grasps                # the published table (4 sets, 3 seeds; about 13 minutes on 2 cores)
    python examples/physics_grasps.py --quick      # 2 sets, deform-gru and tdnn, 1 seed
"""

import argparse
import concurrent.futures
import pathlib

from chapters import keep_section, md_table, publish_section  # beside this script
from results import FORCE_MODELS, HELD_OUT, PHYSICS, constant_pct, frames, mean_sd, neurotac, sh, unseen_scores

SECTION, TITLE = "physics-grasps", "Physics training never saw, with more grasps"
SETS, SEEDS = 4, 3  # the published table's
TRAIN_SEEDS = (11, 14, 15, 16, 17, 18, 19, 20)  # 11 is the models section's one set


def training_data(work: pathlib.Path, pipeline: str, sets: int) -> pathlib.Path:
    parts = [frames(work, f"ch4-physics-s{seed}", pipeline, f"--seed {seed} {PHYSICS} --hold-out membrane")
             for seed in TRAIN_SEEDS[:sets]]
    joined = work / f"ch4-physics-{sets}sets.arrows"
    if not joined.exists():
        sh(f"{neurotac()} concat --rename {' '.join(map(str, parts))} -o {joined}.part.arrows")
        pathlib.Path(f"{joined}.part.arrows").rename(joined)
    return joined


def one_model(name: str, work: pathlib.Path, train, tests: dict, seeds: int, sets: int) -> tuple:
    return name, unseen_scores(work, train, tests, f"physics-{sets}sets-{name}", name, seeds, "rmse_pct_range", {})


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 sets, deform-gru and tdnn, one seed (a few minutes)")
    parser.add_argument("--sets", type=int, default=SETS, help=f"sets of 35 training grasps (default {SETS}, at most {len(TRAIN_SEEDS)})")
    parser.add_argument("--seeds", type=int, default=SEEDS, help=f"trainings per model (default {SEEDS})")
    parser.add_argument("--jobs", type=int, default=2, help="models trained at once, each in a process of its own (default 2; 1: in this process)")
    parser.add_argument("--work", default=None, help="folder for frames, models and metrics (default examples/out-physics-grasps[-quick])")
    args = parser.parse_args(argv)
    here = pathlib.Path(__file__).resolve().parent
    work = pathlib.Path(args.work or here / ("out-physics-grasps-quick" if args.quick else "out-physics-grasps"))
    work.mkdir(parents=True, exist_ok=True)
    sets, seeds = (2, 1) if args.quick else (min(args.sets, len(TRAIN_SEEDS)), args.seeds)
    names = ["tdnn", "deform-gru"] if args.quick else FORCE_MODELS
    pipeline = f"{neurotac()} frame --window 10ms --pad-to longest | {neurotac()} crop {HELD_OUT['ch4'][0]}"
    train = training_data(work, pipeline, sets)
    tests = {"seen": frames(work, "ch4-physics-seen", pipeline, f"--seed 12 {PHYSICS} --hold-out membrane"),
             "unseen": frames(work, "ch4-physics-unseen", pipeline, f"--seed 13 {PHYSICS} --unseen membrane")}
    if args.jobs > 1:
        with concurrent.futures.ProcessPoolExecutor(args.jobs) as pool:
            scores = dict(pool.map(one_model, names, *zip(*[(work, train, tests, seeds, sets)] * len(names))))
    else:
        scores = dict(one_model(name, work, train, tests, seeds, sets) for name in names)
    constant = constant_pct(train, tests["unseen"])
    rows = [["constant (training mean)", f"{constant_pct(train, tests['seen']):.1f}", f"{constant:.1f}", ""]]
    for name in names:
        seen, unseen = scores[name]["seen"], scores[name]["unseen"]
        rows.append([name, mean_sd(seen), mean_sd(unseen), f"{sum(unseen) / sum(seen):.2f}"])
    best = min(names, key=lambda name: sum(scores[name]["unseen"]))
    body = "\n".join([
        f"Made by `{'python examples/physics_grasps.py --quick' if args.quick else 'make -C examples physics-grasps'}`.",
        "",
        f"The design of the models section's \"Physics training never saw\" with {sets} training sets of 35 `ch4` grasps "
        f"({35 * sets} grasps, physics drawn per grasp, membrane from the lower two thirds of its ranges; seeds "
        f"{', '.join(map(str, TRAIN_SEEDS[:sets]))}) instead of one, tested on the same seen (seed 12) and unseen-membrane "
        f"(seed 13) grasps. RMSE as % of the test set's force range, non-zero force only; {seeds} seed(s), `± σ` over seeds.",
        "",
        md_table(["Network", "seen physics RMSE %", "unseen physics RMSE %", "unseen / seen"], rows),
        "",
        f"Lowest error on the unseen physics: {best}, {mean_sd(scores[best]['unseen'])}% against the constant's {constant:.1f}%.",
    ])
    keep_section(work / "physics_grasps.md", TITLE, body, publish, not args.quick and (sets, seeds) == (SETS, SEEDS))
    print(body)


def publish(body: str):
    """The full run's table into docs/results.md; a quick or resized run's stays in its folder."""
    publish_section(SECTION, body, TITLE)


if __name__ == "__main__":
    main()
