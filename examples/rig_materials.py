"""Materials on rigs of other physics, each classifier trained on its own rig's grasps.

A lab records its own grasps with its own sensor: what has to carry from our simulator to that
sensor is the way the classifier learns, not its weights. Each rig is one draw of every physics
family of the simulator (thresholds, membrane, optics, noise, force sensor, objects; `results.rig`),
kept for the rig's 48 `ch3` grasps with a force-controlled gripper (each grasp's peak force drawn
independently of its material, as a lab's gripper would hold it). Every classifier is scored by
8-fold cross-validation over the rig's grasps, as on the default physics in the materials table.
The rigs are those of the force tables (101-103) and of the session tables (201-216).

Writes the section between `<!-- results:rig-materials:start -->` and `<!-- results:rig-materials:end -->`
of docs/results.md, and WORK/rig_materials.md (a quick or resized run only the latter).

    make -C examples rig-materials                 # about 15 minutes on 2 cores
    python examples/rig_materials.py --quick       # two rigs, one seed (about a minute)
"""

import argparse
import pathlib
import statistics

from chapters import keep_section, md_table, publish_section  # beside this script
from results import MATERIAL_PIPELINE, add_jobs_option, each_rig, fmt, frames, material_rows, neurotac, recalls, rig

SECTION, TITLE = "rig-materials", "Materials on rigs of other physics"
RIGS = (101, 102, 103, *range(201, 217))
GOAL = 0.90
REPEATS = 3  # seeds of each rig's cross-validation in the published table


def rig_data(work: pathlib.Path, seed: int, simulate: str = "") -> tuple:
    """(the frames of the rig's 48 grasps, a line on its physics); `simulate`: more simulate options."""
    options, about = rig(seed)
    folder = work / f"rig{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    return frames(folder, "ch3-force-gripper", MATERIAL_PIPELINE.format(n=neurotac()), f"--gripper force --seed 1 {simulate} {options}"), about


def one_rig(seed: int, work: pathlib.Path, repeats: int) -> tuple:
    data, about = rig_data(work, seed)
    return seed, about, material_rows(data.parent, data, "ch3", "kfold:8", repeats, {})


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two rigs, one seed (about a minute)")
    parser.add_argument("--repeats", type=int, default=REPEATS, help=f"seeds of each cross-validation (default {REPEATS}; another number is not published)")
    add_jobs_option(parser)
    parser.add_argument("--work", default=None, help="folder for frames and metrics (default examples/out-rig-materials[-quick])")
    args = parser.parse_args(argv)
    here = pathlib.Path(__file__).resolve().parent
    work = pathlib.Path(args.work or here / ("out-rig-materials-quick" if args.quick else "out-rig-materials"))
    rigs, repeats = (RIGS[:2], 1) if args.quick else (RIGS, args.repeats)
    results = each_rig(args.jobs, one_rig, rigs, work, repeats)
    names = list(results[0][2])
    rows, ours = [], []
    for seed, about, scores in results:
        timing = scores[names[0]]
        ours.append(timing[("all", "accuracy")])
        rows.append([str(seed), about, *(fmt(100 * scores[name][("all", "accuracy")], 1) for name in names), recalls(timing)])
    met = sum(value >= GOAL for value in ours)
    body = "\n".join([
        f"Made by `{'python examples/rig_materials.py --quick' if args.quick else 'make -C examples rig-materials'}`.",
        "",
        f"Each rig: 48 `ch3` grasps (foam, rubber, silicone, steel) with a force-controlled gripper and one draw of every "
        f"physics family; every classifier trained and scored by 8-fold cross-validation over the rig's own grasps, "
        f"{repeats} seed(s). Accuracy %:",
        "",
        md_table(["rig", "physics", *names, f"recall per class, {names[0]}"], rows),
        "",
        f"{names[0]}: mean {100 * statistics.mean(ours):.1f}% over {len(ours)} rigs, lowest {100 * min(ours):.1f}%, "
        f"at least {100 * GOAL:.0f}% on {met} of {len(ours)}.",
    ])
    work.mkdir(parents=True, exist_ok=True)
    keep_section(work / "rig_materials.md", TITLE, body, publish, not args.quick and repeats == REPEATS)


def publish(body: str):
    """The full run's table into docs/results.md; a quick run's stays in its folder."""
    publish_section(SECTION, body, TITLE)


if __name__ == "__main__":
    main()
