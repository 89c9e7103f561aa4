"""A reduced run of the thesis's augmentation study (5.5): train on the small and large bolts, validate
on the medium one; no augmentation against each method; mean and σ of the validation MSE over seeds.

The thesis: ConvLSTM, 48 training and 12 validation grasps, 10 seeds, training set doubled by each
method. Here: 6 simulated grasps, a one-layer LSTM with 4 units, 2 epochs, 2 seeds, so it checks that
the pieces fit together (augment -> train -> eval, copies never split from their originals), not
the thesis's numbers. `examples/` runs the full study.
"""

import importlib.util
import math
import subprocess

import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from neurotac_cli.cli import cli

pytestmark = pytest.mark.slow

CONDITIONS = {
    "none": [],
    "resize": [["--where", "object=bolt12", "--resize", "1.25"], ["--where", "object=bolt18", "--resize", "0.83"]],
    "fs(-1)": [["--fs", "-1"]],
    "tes(-2,0.5)": [["--tes", "-2", "0.5"]],
}
SEEDS = (0, 1)
TRAIN = ["--model", "lstm", "--layers", "1", "--units", "4", "--epochs", "2", "--patience", "2", "--threads", "1"]


def needs(*commands):
    missing = [c for c in commands if importlib.util.find_spec(f"neurotac_cli.commands.{c}") is None]
    if missing:
        pytest.skip(f"neurotac {', '.join(missing)} not built yet")


def invoke(*args):
    done = CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)
    assert done.exit_code == 0, done.output
    return done


@pytest.fixture(scope="module")
def ch5(tmp_path_factory):
    needs("simulate", "frame", "crop", "train", "eval")
    folder = tmp_path_factory.mktemp("study")
    frames = folder / "frames.parquet"
    command = (
        "neurotac simulate --preset ch5 --trials 6 --seed 1 --synced | neurotac frame --window 10ms "
        f"| neurotac crop --size 140x150 --center auto --pool 2x2 -o {frames}"
    )
    subprocess.run(["bash", "-o", "pipefail", "-c", command], check=True, capture_output=True)
    table = pq.read_table(frames)
    pq.write_table(table.filter(pc.equal(table["object"], "bolt15")), folder / "validation.parquet")
    return folder


def augmented(folder, name, stages):
    """All trials, with copies of the training ones (small and large bolts) made by the condition's stages."""
    current = folder / "frames.parquet"
    for index, stage in enumerate(stages):
        following = folder / f"{name}-{index}.parquet"
        where = [] if "--where" in stage else ["--where", "object=bolt12", "--where", "object=bolt18"]
        invoke("augment", *where, *stage, "--seed", 7, "-o", following, current)
        current = following
    table = pq.read_table(current)
    training = {t for t, o in zip(table["trial"].to_pylist(), table["object"].to_pylist()) if o != "bolt15"}
    return current, len(training)


def validation_mse(folder, data, seed):
    model = folder / f"{data.stem}-{seed}.model"
    metrics = folder / f"{data.stem}-{seed}-metrics.parquet"
    invoke("train", *TRAIN, "--val-where", "object=bolt15", "--seed", seed, "-o", model, data)
    invoke("eval", "--model", model, "--metrics", metrics, "--no-per-trial", "-o", folder / "pred.arrows",
           folder / "validation.parquet")
    table = pq.read_table(metrics).to_pylist()
    return next(row["value"] for row in table if row["scope"] == "all" and row["metric"] == "mse")


def test_reduced_augmentation_study(ch5):
    # a 2-epoch, 4-unit LSTM: its MSE says nothing of the methods, so it is checked, not printed
    results = {}
    for name, stages in CONDITIONS.items():
        data, training_trials = augmented(ch5, name.replace("(", "_").replace(")", "").replace(",", "_"), stages)
        assert training_trials == (4 if name == "none" else 8)  # the thesis doubles the training set
        results[name] = [validation_mse(ch5, data, seed) for seed in SEEDS]
    assert all(math.isfinite(v) and v >= 0 for values in results.values() for v in values)
