"""Fuzzing and fault injection at the command level: what a user sees, not what a reader raises.

tests/test_io_fuzz.py fuzzes the camera readers in-process; here the same damage goes through the
commands (`import`, and every command that reads a table), and the tables themselves are damaged:
a column dropped, retyped, renamed or emptied, metadata forged. The only outcomes allowed are exit 0,
or exit 1 with one `neurotac CMD: error:` line; never a traceback. Last, memory limits: a command
under `ulimit -v` that runs out of memory says so in one line. Deterministic (derandomized).
"""

import io
import os
import subprocess
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.io.writers import aedat2_bytes
from tests.conftest import REAL_DATA
from tests.test_exits import frames_table
from tests.io.test_fuzz import REAL

FUZZ = settings(max_examples=12, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def run(args, stdin=None):
    """Run a command in-process; fail on anything but exit 0 or one error line with exit 1."""
    result = CliRunner().invoke(cli, args, input=stdin)
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        f"{args}: {type(result.exception).__name__}: {result.exception}"
    )
    assert "Traceback" not in result.stderr
    assert result.exit_code in (0, 1), (args, result.exit_code, result.stderr)
    if result.exit_code == 1:
        errors = [line for line in result.stderr.splitlines() if ": error: " in line]
        assert len(errors) == 1 and errors[0].startswith(f"neurotac {args[0]}: error: "), result.stderr
    return result


# ---------------------------------------------------------------- camera files through `import`


def simulated_files() -> dict:
    """Small camera files of the formats neurotac writes or that are plain text."""
    rng = np.random.default_rng(0)
    n = 400
    t = np.sort(rng.integers(0, 50_000, n))
    x, y, p = rng.integers(0, 240, n), rng.integers(0, 180, n), rng.integers(0, 2, n)
    rows = list(zip(t, x, y, p))
    return {
        "sim.aedat": aedat2_bytes(t, x, y, p),
        "sim.csv": ("t,x,y,p\n" + "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in rows)).encode(),
        "sim.txt": "".join(f"{a / 1e6:.6f} {b} {c} {d}\n" for a, b, c, d in rows).encode(),
    }


SIMULATED = simulated_files()


def camera_bytes(name: str) -> bytes:
    if name in SIMULATED:
        return SIMULATED[name]
    path = REAL_DATA / name
    if not path.is_file():
        pytest.skip(f"real recording {name} not found in {REAL_DATA} (set NEUROTAC_REAL_DATA)")
    data = path.read_bytes()
    return data if name.endswith(".aedat4") else data[: 1 << 15]  # AEDAT 4.0 keeps its packet table at the end


def import_bytes(tmp_path: Path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    result = run(["import", str(path)])
    if result.exit_code == 0:
        table = pa.ipc.open_stream(result.stdout_bytes).read_all()
        assert sch.kind_of(table.schema) == "events" and table.schema.names == ["t", "x", "y", "p"]


@pytest.mark.parametrize("name", sorted(SIMULATED) + REAL)
@FUZZ
@given(cut=st.floats(0, 1), flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 7)), max_size=6))
def test_import_of_a_truncated_or_bit_flipped_camera_file(tmp_path, name, cut, flips):
    whole = camera_bytes(name)
    data = bytearray(whole[: max(1, int(len(whole) * cut))])
    for where, bit in flips:
        data[int(where * len(data))] ^= 1 << bit
    import_bytes(tmp_path, name, bytes(data))


# ---------------------------------------------------------------- damaged tables through every reader


def stream_bytes(table: pa.Table) -> bytes:
    sink = io.BytesIO()
    with pa.ipc.new_stream(sink, table.schema) as writer:
        writer.write_table(table)
    return sink.getvalue()


@pytest.fixture(scope="module")
def kinds(tmp_path_factory) -> dict:
    """A valid table of every kind, and the model files the commands need."""
    folder = tmp_path_factory.mktemp("fuzz")
    frames = frames_table()
    tables.write(str(folder / "f.arrows"), frames)
    for model, name in (("tdnn", "m.model"), ("material-dnn", "c.model")):
        assert CliRunner().invoke(cli, ["train", "--model", model, "--epochs", "1", "-o", str(folder / name), str(folder / "f.arrows")]).exit_code == 0
    done = CliRunner().invoke(cli, ["eval", "--model", str(folder / "m.model"), "--metrics", str(folder / "metrics.arrows"),
                                    "-o", str(folder / "p.arrows"), str(folder / "f.arrows")])
    assert done.exit_code == 0, done.stderr
    rng = np.random.default_rng(1)
    t = np.sort(rng.integers(0, 40_000, 300))
    events = sch.events_table(t, rng.integers(0, 16, 300), rng.integers(0, 16, 300), rng.integers(0, 2, 300), 16, 16)
    recordings = sch.recordings_table(
        [{"trial": f"r{i}", "t0": 0, "events": (t, *(events.column(c).to_numpy() for c in "xyp")),
          "force": (np.arange(0, 40_000, 2000), np.linspace(0, 2, 20)), "labels": {"material": "foam"}} for i in range(2)],
        16, 16,
    )
    return {
        "folder": folder,
        "events": events,
        "recordings": recordings,
        "frames": frames,
        "predictions": tables.read([str(folder / "p.arrows")], kind="predictions"),
        "metrics": tables.read([str(folder / "metrics.arrows")], kind="metrics"),
    }


TYPES = [pa.string(), pa.float64(), pa.int8(), pa.bool_(), pa.large_string(), pa.list_(pa.int64())]
META_KEYS = [sch.KIND, sch.SENSOR, sch.WINDOW, sch.HISTORY, sch.SYNC, sch.SOURCE]
META_VALUES = [b'"frames"', b'"events"', b'"recordings"', b'"bogus"', b"{", b"null", b"[]", b'{"width": -1, "height": 2}',
               b'{"width": "x"}', b'{"width": 4, "height": 4}', b"0", b"-5", b"1e30", b'"abc"', b'[{"command": 1}]']
NAMES = ["t", "x", "trial", "frame", "counts", "force", "events", "zz", ""]
MUTATION = st.one_of(
    st.tuples(st.just("drop"), st.integers(0, 20)),
    st.tuples(st.just("rename"), st.integers(0, 20), st.sampled_from(NAMES)),
    st.tuples(st.just("retype"), st.integers(0, 20), st.sampled_from(TYPES)),
    st.tuples(st.just("nulls"), st.integers(0, 20)),
    st.tuples(st.just("meta"), st.sampled_from(META_KEYS), st.sampled_from(META_VALUES)),
    st.tuples(st.just("no metadata")),
    st.tuples(st.just("empty")),
)


def mutate(table: pa.Table, mutation) -> pa.Table:
    what, *args = mutation
    index = args[0] % table.num_columns if args and isinstance(args[0], int) else None
    if what == "drop":
        return table.remove_column(index)
    if what == "rename":
        return table.rename_columns([args[1] if i == index else name for i, name in enumerate(table.column_names)])
    if what in ("retype", "nulls"):
        typ = args[1] if what == "retype" else table.schema.field(index).type
        try:
            column = table.column(index).cast(typ, safe=False)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError):
            column = pa.nulls(table.num_rows, typ)
        if what == "nulls":
            column = pa.nulls(table.num_rows, typ)
        return table.set_column(index, pa.field(table.column_names[index], typ), column)
    if what == "meta":
        return table.replace_schema_metadata({**(table.schema.metadata or {}), args[0].encode(): args[1]})
    if what == "no metadata":
        return table.replace_schema_metadata(None)
    return table.slice(0, 0)


COMMANDS = {  # how each command reads a table from stdin; {d} = the fixture's folder
    "info": ["info", "-"],
    "frame": ["frame", "--window", "5ms", "--sensor", "16x16"],
    "crop": ["crop", "--pool", "2x2"],
    "augment": ["augment", "--fs", "1"],
    "train": ["train", "--model", "tdnn", "--epochs", "1", "-o", "{d}/fuzz.model"],
    "eval": ["eval", "--model", "{d}/m.model"],
    "classify": ["classify", "--model", "{d}/c.model"],
    "predict": ["predict", "--model", "{d}/m.model"],
    "sync": ["sync", "-", "--method", "offset", "--offset", "0us", "--force", "{d}/force.csv"],
}


@pytest.mark.parametrize("kind", ["events", "recordings", "frames", "predictions", "metrics"])
@settings(FUZZ, max_examples=int(os.environ.get("NEUROTAC_FUZZ_TABLES", "25")))
@given(mutations=st.lists(MUTATION, min_size=1, max_size=2), command=st.sampled_from(sorted(COMMANDS)))
def test_a_damaged_table_of_every_kind_is_refused_in_one_line_or_read(kinds, kind, mutations, command):
    folder = kinds["folder"]
    (folder / "force.csv").write_text("t_ms,force_N\n" + "".join(f"{t},1\n" for t in range(0, 40, 2)))
    table = kinds[kind]
    try:
        for mutation in mutations:
            table = mutate(table, mutation)
        data = stream_bytes(table)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError, ValueError, KeyError):
        assume(False)  # pyarrow itself will not build this table: nothing a user could pipe in
    run([arg.format(d=folder) for arg in COMMANDS[command]], stdin=data)


def test_forged_metadata_that_is_not_json_names_the_key(kinds):
    table = kinds["frames"].replace_schema_metadata({**kinds["frames"].schema.metadata, sch.WINDOW.encode(): b"{"})
    result = run(COMMANDS["crop"], stdin=stream_bytes(table))
    assert result.exit_code == 1 and "neurotac:window_us is not valid JSON" in result.stderr


# ---------------------------------------------------------------- resource limits

LIMIT_KB = 1_500_000  # `ulimit -v`: 1.5 GB of address space, room for torch's libraries but not for much more


def under_ulimit(command: str, cwd: Path):
    return subprocess.run(["bash", "-c", f"ulimit -v {LIMIT_KB}; {command}"], capture_output=True, text=True, cwd=cwd, timeout=300)


def _one_trial(tmp_path, span_us: int, width: int, height: int):
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, span_us, 5_000))
    recordings = sch.recordings_table(
        [{"trial": "a", "t0": 0, "events": (t, rng.integers(0, width, 5_000), rng.integers(0, height, 5_000), rng.integers(0, 2, 5_000)),
          "force": (np.arange(0, span_us, 2000), np.ones(span_us // 2000))}], width, height)
    tables.write(str(tmp_path / "r.arrows"), recordings)


def test_a_window_too_small_for_the_recording_is_one_line_and_leaves_no_output(tmp_path):
    """Windows of 1 µs over 2 s of a 240x180 sensor: 2,000,000 frames of 170 kB, past the frame limit."""
    _one_trial(tmp_path, 2_000_000, 240, 180)
    done = under_ulimit("neurotac frame --window 1us -o f.arrows r.arrows", tmp_path)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert [": error: " in line for line in done.stderr.splitlines()].count(True) == 1 and "--max-frames" in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.arrows"]


def test_framing_a_recording_into_many_frames_stays_within_a_small_memory_limit(tmp_path):
    """400,000 frames of 1 µs (32x32) stream to the output under the memory limit: none is held."""
    _one_trial(tmp_path, 400_000, 32, 32)
    done = under_ulimit("neurotac frame --window 1us r.arrows | wc -c", tmp_path)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert int(done.stdout) > 400_000 * 2 * 32 * 32 * 2


def test_torch_running_out_of_memory_is_one_line(tmp_path):
    """torch's allocator raises RuntimeError, not MemoryError: 64 layers of 4096 units need ~4 GB, Adam three times that."""
    tables.write(str(tmp_path / "f.arrows"), frames_table())
    done = under_ulimit("neurotac train --model tdnn --units 4096 --layers 64 --epochs 1 -o m.model f.arrows", tmp_path)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert "neurotac train: error: out of memory" in done.stderr
    assert not (tmp_path / "m.model").exists()
