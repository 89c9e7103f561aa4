"""Materials on an object size training never saw: `material-timing` with and without `--adapt-by object`.

Each data set is simulated `ch3` grasps with a force-controlled gripper (each grasp's peak force drawn
independently of its material): foam, rubber, silicone and steel on hexagons of 5, 7.5 and 10 mm,
--per grasps of each, 7 ms frames cropped 116x116 about the contact and pooled 4x4, as the models
section frames materials. `neurotac eval --cv group:object=hexN` trains on two sizes and scores the
third, without and with the features standardised within each size (`--adapt-by object`: the held-out
size's grasps standardised together, docs/design.md).

Writes the section between `<!-- results:material-sizes:start -->` and
`<!-- results:material-sizes:end -->` of docs/results.md and WORK/material_sizes.md (a quick or
resized run only the latter).

    make -C examples material-sizes                  # the published table (3 data sets, 2 seeds each; a few minutes)
    python examples/material_sizes.py --quick        # one small data set, 1 seed
"""

import argparse
import pathlib

from chapters import md_table, publish_section  # beside this script
from results import neurotac, sh

from neurotac_cli import tables

SECTION, TITLE = "material-sizes", "Materials on an object size training never saw"
SIZES = ("5", "7.5", "10")
MATERIALS = ("foam", "rubber", "silicone", "steel")
DATA_SEEDS, PER, REPEATS = (5, 6, 7), 4, 2  # the published table's
WAYS = (("as trained", ""), ("--adapt-by object", "--adapt-by object"))
PIPELINE = "{n} frame --window 7ms | {n} crop --size 116x116 --center auto --pool 4x4"


def data_set(work: pathlib.Path, seed: int, per: int) -> pathlib.Path:
    """The frames of one simulated data set (reused when present)."""
    path = work / f"hex-seed{seed}-per{per}.arrows"
    if not path.exists():
        objects = ",".join(f"{material}:hex{size}:{per}" for material in MATERIALS for size in SIZES)
        n = neurotac()
        sh(f"{n} simulate --preset ch3 --objects {objects} --gripper force --seed {seed} --synced | {PIPELINE.format(n=n)} > {path}.part")
        pathlib.Path(f"{path}.part").rename(path)
    return path


def accuracy(work: pathlib.Path, frames: pathlib.Path, size: str, options: str, repeats: int) -> float:
    """Out-of-fold accuracy (%) on the held-out size, from the metrics table `eval` writes."""
    metrics = work / f"{frames.stem}-hex{size}{'-adapt' if options else ''}-r{repeats}.parquet"
    if not metrics.exists():
        sh(f"{neurotac()} eval --cv group:object=hex{size} --model-spec material-timing {options} --repeats {repeats} "
           f"--seed 1 --metrics {metrics} < {frames} > /dev/null")
    table = tables.read([str(metrics)])
    rows = {(s, m): v for s, m, v in zip(*(table.column(c).to_pylist() for c in ("scope", "metric", "value")))}
    return 100 * rows[("all", "accuracy")]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default=str(pathlib.Path(__file__).resolve().parent / "out-material-sizes"))
    parser.add_argument("--seeds", default=",".join(map(str, DATA_SEEDS)), help="data set seeds, comma-separated")
    parser.add_argument("--per", type=int, default=PER, help="grasps of each material and size")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="training seeds per held-out size")
    parser.add_argument("--quick", action="store_true", help="one data set of 2 grasps per material and size, 1 training seed")
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    if args.quick:
        seeds, args.per, args.repeats = seeds[:1], 2, 1
    work = pathlib.Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    rows, means = [], {name: [] for name, _ in WAYS}
    for seed in seeds:
        frames = data_set(work, seed, args.per)
        for size in SIZES:
            cells = [accuracy(work, frames, size, options, args.repeats) for _, options in WAYS]
            for (name, _), value in zip(WAYS, cells):
                means[name].append(value)
            rows.append([str(seed), f"{size} mm", *(f"{value:.1f}" for value in cells)])
    rows.append(["mean", "", *(f"{sum(values) / len(values):.1f}" for values in means.values())])
    body = "\n".join([
        f"Made by `make -C examples material-sizes` (`examples/material_sizes.py`). Simulated `ch3` grasps with a "
        f"force-controlled gripper (peak force independent of material), {len(MATERIALS)} materials x hexagons of "
        f"{', '.join(SIZES)} mm x {args.per} grasps per data set; 7 ms frames, 116x116 about the contact pooled 4x4. "
        f"`neurotac eval --cv group:object=hexN --model-spec material-timing --repeats {args.repeats}`: trained on two "
        "sizes, scored on the third (accuracy in %, chance 25%), as trained and with the features standardised within "
        "each size (`--adapt-by object`).",
        "",
        md_table(["data set seed", "held-out size", *(name for name, _ in WAYS)], rows),
    ])
    print(body)
    (work / "material_sizes.md").write_text(body + "\n")
    if not args.quick and seeds == list(DATA_SEEDS) and args.per == PER and args.repeats == REPEATS:
        publish_section(SECTION, body, TITLE)


if __name__ == "__main__":
    main()
