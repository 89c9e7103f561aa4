"""Which physics makes a rig hard: each family of a rig's physics alone on the default physics.

deform-gru trained on a rig's own grasps reads some rigs at twice its default-physics error and more
(the members table). This script takes such rigs (results.py's `rig`: every family drawn once over
its whole range) and puts one family of the rig's draw at a time on the default physics (the rest
as by default), plus the ON threshold alone, then scores the `ch4` held-out-size study of the
members table on each: train on the 8 and 16 mm bolts, score the 12 mm one, three members, the
same seeds. It shares members.py's work folder, so the default physics and the whole rigs are the
members table's own runs.

Writes the section between `<!-- results:rig-families:start -->` and `<!-- results:rig-families:end -->`
of docs/results.md, and WORK/rig-families.md (a quick or resized run only the latter).

    make -C examples rig-families            # the published table (3 rigs, 3 seeds; about 30 minutes on 2 cores)
    python examples/rig_families.py --quick  # one rig, two families, 1 seed
"""

import argparse
import math

from chapters import keep_section, md_table, publish_section  # beside this script
from members import SEEDS, ch4_pipeline, scores, work_folder
from results import drawn, fmt, frames, set_options

SECTION, TITLE = "rig-families", "Which physics makes a rig hard"
RIG_SEEDS = (101, 105, 108)  # three of the members table's six rigs beyond 1.5 times the default physics
ON_ALONE = "ON threshold alone"  # a part of the pixels family: left out of the product and of the costliest family


def families() -> dict:
    """Family name -> its parameters, and the ON threshold alone."""
    from neurotac_cli.sim import physics

    return {**{name: tuple(params) for name, params in physics.FAMILIES.items()}, ON_ALONE: ("on_threshold",)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one rig, two families, one seed (a few minutes)")
    parser.add_argument("--seeds", type=int, default=SEEDS, help=f"trainings per physics (default {SEEDS})")
    parser.add_argument("--work", default=None, help="folder for frames and metrics (default examples/out-members[-quick], shared with members.py)")
    args = parser.parse_args(argv)
    work = work_folder(args.work, args.quick)
    seeds, rigs = (1, RIG_SEEDS[:1]) if args.quick else (args.seeds, RIG_SEEDS)
    groups = dict(list(families().items())[:2]) if args.quick else families()
    pipeline = ch4_pipeline()
    default = scores(work, frames(work, "ch4", pipeline, "--seed 1"), "ch4", 3, seeds)[0]
    columns, product, whole = {}, {}, {}
    for seed in rigs:
        values, column = drawn(seed), {}
        for name, params in groups.items():
            tag = f"ch4-rig{seed}-{name.split()[0].lower()}"
            data = frames(work, tag, pipeline, f"--seed 1 {set_options({k: v for k, v in values.items() if k in params})}")
            column[name] = scores(work, data, tag, 3, seeds)[0]
        whole[seed] = scores(work, frames(work, f"ch4-rig{seed}", pipeline, f"--seed 1 {set_options(values)}"), f"ch4-rig{seed}", 3, seeds)[0]
        product[seed] = math.prod(column[name] / default for name in groups if name != ON_ALONE)
        columns[seed] = column
    cell = lambda pct: f"{fmt(pct, 2)} ({fmt(pct / default, 2)}x)"  # noqa: E731
    rows = [[name, *(cell(columns[seed][name]) for seed in rigs)] for name in groups]
    rows.append(["every family (the rig)", *(cell(whole[seed]) for seed in rigs)])
    rows.append(["product of the families' ratios", *(f"{fmt(product[seed], 2)}x" for seed in rigs)])
    worst = {seed: max((name for name in groups if name != ON_ALONE), key=columns[seed].get) for seed in rigs}
    body = "\n".join([
        f"Made by `{'python examples/rig_families.py --quick' if args.quick else 'make -C examples rig-families'}`.",
        "",
        "The members table's study (`ch4`, 35 grasps, seed 1; deform-gru with three members trained on the 8 and 16 mm "
        f"bolts, scored on the 12 mm bolt; {seeds} seed(s)) on the default physics with one family of a rig's draw in "
        "place of the default's ([simulator.md](simulator.md) lists the families), and on the whole rig. RMSE as % of "
        f"the force range, non-zero force only, mean over the trainings; in brackets the ratio to the default physics' "
        f"{fmt(default, 2)}%.",
        "",
        md_table(["physics", *(f"rig {seed}" for seed in rigs)], rows),
        "",
        "The family that costs most alone: " + "; ".join(f"rig {seed}, {worst[seed]} ({fmt(columns[seed][worst[seed]] / default, 2)}x)"
                                                         for seed in rigs) + ".",
        reach(columns, whole),
    ])
    keep_section(work / "rig-families.md", TITLE, body, publish, not args.quick and seeds == SEEDS)
    print(body)


def reach(columns: dict, whole: dict) -> str:
    """Whether one family alone reaches a rig's whole error."""
    reached = [seed for seed in columns if max(columns[seed].values()) >= whole[seed]]
    if not reached:
        return f"No family alone reaches its rig's whole error on any of the {len(columns)} rigs: the rigs' costs are several families' together."
    return f"One family alone reaches its rig's whole error on {', '.join(f'rig {seed}' for seed in reached)}."


def publish(body: str):
    """The full run's table into docs/results.md; a quick or resized run's stays in its folder."""
    publish_section(SECTION, body, TITLE)


if __name__ == "__main__":
    main()
