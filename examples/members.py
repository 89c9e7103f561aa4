"""deform-gru with one member and with three, on the default physics and on rigs of other physics.

A deform-gru trained on a few dozen grasps reads an unseen object size well or badly by the draw of
its two validation grasps and where early stopping ends: single trainings on one rig spread by up
to 2 points of the force range. With `--members 3` (the default) three GRUs on the same features
are each trained with a validation draw of their own and their estimates averaged. This script
measures both on the `ch4` held-out-size study (train on the 8 and 16 mm bolts, score the 12 mm
one) of the default physics and of eight rigs, each with every physics family drawn once
(results.py's `rig`), as a lab with another sensor would train on its own grasps.

Writes the section between `<!-- results:members:start -->` and `<!-- results:members:end -->` of
docs/results.md, and WORK/members.md (a quick or resized run only the latter).

    make -C examples members                 # the published table (9 physics, 3 seeds; about 15 minutes on 2 cores)
    python examples/members.py --quick       # the default physics and one rig, 1 seed
"""

import argparse
import pathlib

from chapters import keep_section, md_table, publish_section  # beside this script
from results import FORCE_SCORING, HELD_OUT, evaluate, fmt, frames, neurotac, rig

SECTION, TITLE = "members", "deform-gru's members"
RIG_SEEDS = (101, 102, 103, 104, 105, 106, 107, 108)  # 101-103 are the models section's rigs
SEEDS = 3


def scores(work, data, tag: str, members: int, seeds: int) -> tuple:
    """(mean, σ) over the seeds of the RMSE (% of the range) on the held-out 12 mm bolt."""
    found = evaluate(work, data, f"{tag}-members{members}",
                     f"--cv group:object=bolt12 --model-spec deform-gru --members {members} --repeats {seeds} "
                     "--nonzero --no-per-trial --seed 1", {}, FORCE_SCORING)
    return found[("all", "rmse_pct_range_fold_mean")], found[("all", "rmse_pct_range_fold_sd")]


def work_folder(work: str | None, quick: bool) -> pathlib.Path:
    """WORK, or examples/out-members (-quick): frames and metrics, shared with rig_families.py."""
    folder = pathlib.Path(work or pathlib.Path(__file__).resolve().parent / ("out-members-quick" if quick else "out-members"))
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def ch4_pipeline() -> str:
    """The models section's `ch4` frames: 10 ms, padded to the longest trial, cropped and pooled to 29x29."""
    return f"{neurotac()} frame --window 10ms --pad-to longest | {neurotac()} crop {HELD_OUT['ch4'][0]}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the default physics and one rig, one seed (about a minute)")
    parser.add_argument("--seeds", type=int, default=SEEDS, help=f"trainings per physics and member count (default {SEEDS})")
    parser.add_argument("--work", default=None, help="folder for frames and metrics (default examples/out-members[-quick])")
    args = parser.parse_args(argv)
    work = work_folder(args.work, args.quick)
    seeds, rigs = (1, RIG_SEEDS[:1]) if args.quick else (args.seeds, RIG_SEEDS)
    pipeline = ch4_pipeline()
    physics = [("default physics", "ch4", "--seed 1", "")]
    for seed in rigs:
        options, about = rig(seed)
        physics.append((f"rig {seed}", f"ch4-rig{seed}", f"--seed 1 {options}", about))
    rows, gains = [], []
    for name, tag, simulate, about in physics:
        data = frames(work, tag, pipeline, simulate)
        one, three = scores(work, data, tag, 1, seeds), scores(work, data, tag, 3, seeds)
        gains.append(three[0] / one[0])
        rows.append([name, f"{fmt(one[0], 2)} ± {fmt(one[1], 2)}", f"{fmt(three[0], 2)} ± {fmt(three[1], 2)}",
                     f"{fmt(three[0] / one[0], 2)}", about])
    better = sum(gain < 1 for gain in gains)
    body = "\n".join([
        f"Made by `{'python examples/members.py --quick' if args.quick else 'make -C examples members'}`.",
        "",
        "The `ch4` held-out-size study (35 grasps, seed 1; trained on the 8 and 16 mm bolts, 10% of them drawn for "
        "validation, scored on the 12 mm bolt), frames as in the models section; `neurotac eval --cv group:object=bolt12 "
        f"--model-spec deform-gru --members N --repeats {seeds}`. RMSE as % of the force range, non-zero force only, "
        "mean ± σ over the trainings.",
        "",
        md_table(["physics", "one member", "three members", "three / one", "rig"], rows),
        "",
        f"Three members read lower than one on {better} of {len(gains)} physics; on average "
        f"{fmt(sum(gains) / len(gains), 2)} times one member's error.",
    ])
    keep_section(work / "members.md", TITLE, body, publish, not args.quick and seeds == SEEDS)
    print(body)


def publish(body: str):
    """The full run's table into docs/results.md; a quick or resized run's stays in its folder."""
    publish_section(SECTION, body, TITLE)


if __name__ == "__main__":
    main()
