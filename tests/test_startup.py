"""Each verb imports only what its work needs: on an empty input (it starts, reads the schema, and
refuses it, or describes it for `info`) no verb loads numba, scipy, sklearn, matplotlib or Parquet,
and none loads torch, not even the model verbs, which read the model file's header without it
(`predict` starts importing torch in the background while it waits for its first frame)."""

import json
import subprocess
import sys

import numpy as np
import pyarrow.ipc as ipc
import pytest

from neurotac_cli import schema as sch

HEAVY = ("torch", "numba", "scipy", "sklearn", "matplotlib", "pyarrow.parquet")

# Runs the CLI in this process, then prints which heavy modules it imported.
PROBE = """
import sys
from neurotac_cli.cli import cli
try:
    cli.main(sys.argv[1:], prog_name="neurotac")
except SystemExit as done:
    code = done.code
print(repr((code, sorted(m for m in %r if m in sys.modules))), file=sys.stderr)
""" % (HEAVY,)


def empty_table(path, schema):
    with open(path, "wb") as sink:
        ipc.new_stream(sink, schema).close()


def model_file(path):
    """A model file with a valid neurotac header (the verb refuses the empty input before its weights are read)."""
    from safetensors.numpy import save_file

    header = {"format": "neurotac-model", "model": "deform-gru", "task": "force", "architecture": {},
              "input": {"window_us": 10_000, "height": 4, "width": 4, "normalisation": {"force_scale": 1.0}}}
    save_file({"w": np.zeros(1, np.float32)}, str(path), metadata={"neurotac": json.dumps(header)})


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("startup")
    empty_table(folder / "events.arrows", sch.events_schema(24, 18))
    empty_table(folder / "frames.arrows", sch.frames_schema(4, 4, window_us=10_000))
    model_file(folder / "m.model")
    return folder


@pytest.mark.parametrize("args, table", [
    (["frame", "--window", "10ms"], "events"),
    (["info", "-"], "events"),  # an empty table described, exit 0
    (["crop", "--size", "2x2", "--center", "1,1"], "frames"),
    (["augment", "--tes", "-2", "0.5"], "frames"),
    (["predict", "--model", "{m}"], "frames"),
    (["eval", "--model", "{m}"], "frames"),
    (["train", "--model", "deform-gru", "-o", "{out}"], "frames"),
    (["classify", "--model", "{m}"], "frames"),
])
def test_a_verb_on_an_empty_input_imports_nothing_heavy(inputs, args, table):
    args = [a.format(m=inputs / "m.model", out=inputs / "out.model") for a in args]
    with open(inputs / f"{table}.arrows", "rb") as stdin:
        done = subprocess.run([sys.executable, "-c", PROBE, *args], stdin=stdin, capture_output=True, text=True)
    code, heavy = eval(done.stderr.strip().splitlines()[-1])
    if args[0] == "predict":  # it starts importing torch in a thread while it waits for the first frame, and does not wait for it
        heavy = [name for name in heavy if name != "torch"]
    assert (code == 0) if args[0] == "info" else (code == 1 and "has no rows" in done.stderr), done.stderr
    assert heavy == [], f"{args[0]} imported {heavy} before refusing an empty input"
