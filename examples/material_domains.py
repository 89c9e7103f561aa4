"""Materials on an object size or a sensor training never saw: `material-timing` with and without `--adapt-by`.

1. Sizes. Each data set is simulated `ch3` grasps with a force-controlled gripper (each grasp's peak
   force drawn independently of its material): foam, rubber, silicone and steel on hexagons of 5,
   7.5 and 10 mm, --per grasps of each, 7 ms frames cropped 116x116 about the contact and pooled
   4x4, as the models section frames materials. `neurotac eval --cv group:object=hexN` trains on
   two sizes and scores the third, without and with the features standardised within each size
   (`--adapt-by object`: the held-out size's grasps standardised together, docs/design.md), with
   `material-timing` and with `material-rises` (its rise times alone).
2. Sensors. `material-timing`, `material-curves` and the thesis's DNN (`material-dnn`), trained on
   the models section's default-physics grasps with a force-controlled gripper
   (`ch3 --gripper force --seed 2`, 48 grasps), scored on each rig's 48 grasps (the rigs of
   `examples/rig_materials.py`: one draw of every physics family each) with `neurotac classify`,
   as trained and with `--adapt-by object` (each rig's grasps standardised together: one object,
   one sensor); beside them `material-timing` trained on many simulated sensors instead
   (`simulate --vary all --rigs 16`, 32 grasps on each, `train --adapt-by rig`).
3. Physics families training never saw. The same many-sensor training with one family drawn from
   the lower two thirds of its ranges only (`--hold-out FAMILY`), scored on other sensors of those
   ranges and on sensors whose FAMILY comes from the upper third (`--unseen FAMILY`), 16 grasps on
   each sensor, standardised per sensor.

Writes the section between `<!-- results:material-domains:start -->` and
`<!-- results:material-domains:end -->` of docs/results.md and WORK/material_domains.md (a quick or
resized run only the latter).

    make -C examples material-domains                # the published tables (about 30 minutes on 2 cores)
    python examples/material_domains.py --quick      # one small data set (middle size held out) and one small rig, 1 seed
"""

import argparse
import concurrent.futures
import pathlib

from chapters import md_table, publish_section  # beside this script
from results import MATERIAL_PIPELINE, frames, metrics, neurotac, sh
from rig_materials import RIGS, rig_data

SECTION, TITLE = "material-domains", "Materials on an object size or a sensor training never saw"
SIZES = ("5", "7.5", "10")
MATERIALS = ("foam", "rubber", "silicone", "steel")
DATA_SEEDS, PER, REPEATS = (5, 6, 7), 4, 2  # the published table's
WAYS = (("as trained", ""), ("--adapt-by object", "--adapt-by object"))
MANY_RIGS, MANY_PER = 16, 8  # training sensors of the many-sensor models, and grasps of each material on each
HELD_OUT_FAMILIES = ("membrane", "pixels")
TEST_RIGS, TEST_PER = 8, 4  # sensors of each held-out family's test sets, and grasps of each material on each
SENSOR_MODELS = ("material-timing", "material-curves", "material-dnn")  # ours, and the thesis's DNN
SIZE_MODELS = ("material-timing", "material-rises")  # ours, with and without the event amounts


def data_set(work: pathlib.Path, seed: int, per: int) -> pathlib.Path:
    """The frames of one simulated data set (reused when present)."""
    objects = ",".join(f"{material}:hex{size}:{per}" for material in MATERIALS for size in SIZES)
    return frames(work, f"ch3-hex-seed{seed}-per{per}", MATERIAL_PIPELINE.format(n=neurotac()),
                  f"--objects {objects} --gripper force --seed {seed}")


def accuracy(work: pathlib.Path, frames: pathlib.Path, size: str, options: str, repeats: int, spec: str = "material-timing") -> float:
    """Out-of-fold accuracy (%) on the held-out size, from the metrics table `eval` writes."""
    named = "" if spec == "material-timing" else f"-{spec}"
    path = work / f"{frames.stem}-hex{size}{named}{'-adapt' if options else ''}-r{repeats}.parquet"
    if not path.exists():
        sh(f"{neurotac()} eval --cv group:object=hex{size} --model-spec {spec} {options} --repeats {repeats} "
           f"--seed 1 --metrics {path} < {frames} > /dev/null")
    return 100 * metrics(path)[("all", "accuracy")]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", default=str(pathlib.Path(__file__).resolve().parent / "out-material-domains"))
    parser.add_argument("--seeds", default=",".join(map(str, DATA_SEEDS)), help="data set seeds, comma-separated")
    parser.add_argument("--per", type=int, default=PER, help="grasps of each material and size")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="training seeds per held-out size")
    parser.add_argument("--jobs", type=int, default=2, help="rigs simulated at once (default 2)")
    parser.add_argument("--quick", action="store_true", help="one data set of 2 grasps per material and size, the middle size "
                        "held out, 1 training seed; one rig of 12 grasps against 12 default ones")
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    if args.quick:
        seeds, args.per, args.repeats = seeds[:1], 2, 1
    work = pathlib.Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    columns = [(spec, name, options) for spec in SIZE_MODELS for name, options in WAYS]
    rows, means = [], [[] for _ in columns]
    for seed in seeds:
        frames = data_set(work, seed, args.per)
        for size in SIZES[1:2] if args.quick else SIZES:  # a quick run holds out the middle size only
            cells = [accuracy(work, frames, size, options, args.repeats, spec) for spec, _, options in columns]
            for values, value in zip(means, cells):
                values.append(value)
            rows.append([str(seed), f"{size} mm", *(f"{value:.1f}" for value in cells)])
    rows.append(["mean", "", *(f"{sum(values) / len(values):.1f}" for values in means)])
    grasps = 12 if args.quick else 48  # ch3's 48, or a quick run's few
    specs = SENSOR_MODELS[:1] if args.quick else SENSOR_MODELS
    many_rigs, many_per = (2, 2) if args.quick else (MANY_RIGS, MANY_PER)
    # a quick run trains one many-sensor model, the first held-out family's, for both tables
    many_tag, many_vary = (f"{HELD_OUT_FAMILIES[0]}-seen", f"--vary all --hold-out {HELD_OUT_FAMILIES[0]}") if args.quick else ("all", "--vary all")
    many = many_sensor_model(work, many_tag, many_vary, many_rigs, many_per, 31)
    sensors = sensor_rows(work, RIGS[:1] if args.quick else RIGS, f"--trials {grasps}" if args.quick else "", args.jobs, specs, [many])
    families = HELD_OUT_FAMILIES[:1] if args.quick else HELD_OUT_FAMILIES
    test_rigs, test_per = (1, 2) if args.quick else (TEST_RIGS, TEST_PER)
    held = [family_row(work, family, many_rigs, many_per, test_rigs, test_per) for family in families]
    body = "\n".join([
        f"Made by `make -C examples material-domains` (`examples/material_domains.py`). Simulated `ch3` grasps with a "
        f"force-controlled gripper (peak force independent of material), {len(MATERIALS)} materials x hexagons of "
        f"{', '.join(SIZES)} mm x {args.per} grasps per data set; 7 ms frames, 116x116 about the contact pooled 4x4. "
        f"`neurotac eval --cv group:object=hexN --model-spec MODEL --repeats {args.repeats}`: trained on two "
        "sizes, scored on the third (accuracy in %, chance 25%), as trained and with the features standardised within "
        "each size (`--adapt-by object`); `material-rises` is `material-timing` on its rise times alone.",
        "",
        md_table(["data set seed", "held-out size", *(f"{spec}, {name}" for spec, name, _ in columns)], rows),
        "",
        f"Trained on the default physics (`ch3 --gripper force --seed 2`, {grasps} grasps), scored on each rig's {grasps} grasps "
        "(`--gripper force --seed 1` and the rig's physics, as in \"Materials on rigs of other physics\"), accuracy in %; "
        f"in the last column `material-timing` trained instead on {many_rigs} simulated sensors of {4 * many_per} grasps each "
        f"(`simulate --preset ch3 --gripper force {many_vary} --rigs {many_rigs} --objects {sensor_objects(many_rigs, many_per)} "
        f"--seed 31`, {many_per} grasps of each material "
        "on each sensor; `train --adapt-by rig`), none of them a rig of the table:",
        "",
        md_table(["rig", "physics", *(f"{spec}, {name}" for spec in specs for name, _ in WAYS),
                  f"material-timing, {many_rigs} simulated sensors, --adapt-by rig"], sensors),
        "",
        f"Physics families training never saw: `material-timing` trained as in the last column, on {many_rigs} sensors "
        f"whose FAMILY is drawn from the lower two thirds of its ranges only (`--vary all --hold-out FAMILY --rigs "
        f"{many_rigs}`, seed 31), scored on {test_rigs} other sensors of those ranges (`--hold-out FAMILY`, seed 41: seen) and "
        f"on {test_rigs} sensors whose FAMILY comes from the upper third (`--unseen FAMILY`, seed 42: never seen), "
        f"{4 * test_per} grasps on each sensor ({test_per} of each material), each sensor's grasps standardised together. "
        "Accuracy in %:",
        "",
        md_table(["held-out family", "seen physics", "unseen physics", "unseen / seen", "recall per class, unseen"], held),
    ])
    print(body)
    (work / "material_domains.md").write_text(body + "\n")
    if not args.quick and seeds == list(DATA_SEEDS) and args.per == PER and args.repeats == REPEATS:
        publish_section(SECTION, body, TITLE)


def classified(model: pathlib.Path, data: pathlib.Path) -> tuple[float, dict]:
    """(accuracy %, {class: recall %}) of a classifier on a frames table, from the metrics table `eval --model` writes."""
    name = data.parent.name if data.parent.name.startswith("rig") else data.stem
    path = model.with_name(f"{model.stem}-{name}.parquet")
    if not path.exists():
        sh(f"{neurotac()} eval --model {model} --metrics {path} < {data} > /dev/null")
    scores = metrics(path)
    return 100 * scores[("all", "accuracy")], {scope.split(":", 1)[1]: 100 * value for (scope, metric), value in scores.items() if metric == "recall"}


def sensor_objects(rigs: int, per: int) -> str:
    """simulate's --objects for `per` hexagons of each material on each of `rigs` sensors."""
    return ",".join(f"{material}:hex:{rigs * per}" for material in MATERIALS)


def sensors_data(work: pathlib.Path, tag: str, vary: str, rigs: int, per: int, seed: int) -> pathlib.Path:
    """Frames of `rigs` simulated sensors of drawn physics, `per` grasps of each material on each, labelled `rig`."""
    return frames(work, f"ch3-sensors-{tag}-r{rigs}x{per}-s{seed}", MATERIAL_PIPELINE.format(n=neurotac()),
                  f"--objects {sensor_objects(rigs, per)} --gripper force --seed {seed} {vary} --rigs {rigs}")


def many_sensor_model(work: pathlib.Path, tag: str, vary: str, rigs: int, per: int, seed: int) -> pathlib.Path:
    """`material-timing` trained on many simulated sensors, its features standardised per sensor."""
    data = sensors_data(work, tag, vary, rigs, per, seed)
    model = work / f"{data.stem}-material-timing.model"
    if not model.exists():
        sh(f"{neurotac()} train --model material-timing --adapt-by rig --seed 1 -o {model} {data}")
    return model


def family_row(work: pathlib.Path, family: str, rigs: int, per: int, test_rigs: int, test_per: int) -> list:
    """One row of the held-out families' table: seen and unseen accuracy of the many-sensor model trained without FAMILY's upper third."""
    model = many_sensor_model(work, f"{family}-seen", f"--vary all --hold-out {family}", rigs, per, 31)
    seen, _ = classified(model, sensors_data(work, f"{family}-seen", f"--vary all --hold-out {family}", test_rigs, test_per, 41))
    unseen, recall = classified(model, sensors_data(work, f"{family}-unseen", f"--vary all --unseen {family}", test_rigs, test_per, 42))
    return [family, f"{seen:.1f}", f"{unseen:.1f}", f"{unseen / seen:.2f}" if seen else "",
            ", ".join(f"{name} {value:.0f}%" for name, value in sorted(recall.items()))]


def sensor_rows(work: pathlib.Path, rigs, extra: str, jobs: int, specs=SENSOR_MODELS, more=()) -> list:
    """One row per rig: each model of `specs` trained on the default physics, as trained and adapted,
    then each model of `more` (paths)."""
    training = frames(work, "ch3-force-gripper", MATERIAL_PIPELINE.format(n=neurotac()), f"--gripper force --seed 2 {extra}")
    models = []
    for spec in specs:
        for name, options in WAYS:
            model = work / f"default-{spec}{'-adapt' if options else ''}.model"
            if not model.exists():
                sh(f"{neurotac()} train --model {spec} {options} --seed 1 -o {model} {training}")
            models.append(model)
    models += list(more)
    with concurrent.futures.ThreadPoolExecutor(max(1, jobs)) as pool:  # each simulation is a process of its own
        made = list(pool.map(lambda seed: rig_data(work, seed, extra), rigs))
    rows, means = [], [[] for _ in models]
    for seed, (data, about) in zip(rigs, made):
        cells = [classified(model, data)[0] for model in models]
        for values, value in zip(means, cells):
            values.append(value)
        rows.append([str(seed), about, *(f"{value:.1f}" for value in cells)])
    rows.append(["mean", "", *(f"{sum(values) / len(values):.1f}" for values in means)])
    return rows


if __name__ == "__main__":
    main()
