"""Exit codes as the docs promise, for every command: 2 for a usage error, 1 for bad data, each one
line on stderr. Outputs that cannot be written (a full disk, a read-only or vanished folder) are one
line and exit 1, leave no part file, and keep the file that was there. The same trials given twice
are refused by every command that groups by trial."""

import errno
import os
import shutil
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import COMMANDS, cli
from neurotac_cli.errors import OutputError
from neurotac_cli.options import TablePath

GARBAGE = b"this is not a table\n"


def frames_table(trials=("a", "b"), frames=4, size=8, seed=0):
    rng = np.random.default_rng(seed)
    schema = sch.frames_schema(size, size, labels=("material",), window_us=10_000)
    rows = [(trial, k) for trial in trials for k in range(frames)]
    import pyarrow as pa

    counts = rng.integers(0, 3, (len(rows), 2, size, size)).astype(np.uint16)
    columns = [
        pa.array([r[0] for r in rows]), pa.array([r[1] for r in rows], pa.int32()),
        pa.array([r[1] * 10_000 for r in rows], pa.int64()), sch.counts_array(counts),
        pa.array(rng.random(len(rows)), pa.float32()), pa.array(["holding"] * len(rows)),
        pa.array(["foam" if r[0] == "a" else "steel" for r in rows]),
    ]
    return pa.Table.from_arrays(columns, schema=schema)


def recordings_table(names=("a", "b")):
    trials = [
        {"trial": name, "t0": 1_000, "events": ([0, 5, 9], [1, 2, 3], [1, 2, 3], [0, 1, 0]), "force": ([0, 2000], [0.0, 1.0])}
        for name in names
    ]
    return sch.recordings_table(trials, 8, 8)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("exits")
    tables.write(str(folder / "f.arrows"), frames_table())
    tables.write(str(folder / "r.arrows"), recordings_table())
    (folder / "force.csv").write_text("t_ms,force_N\n" + "".join(f"{t},0\n" for t in range(0, 40, 2)))
    (folder / "garbage.aedat").write_bytes(b"#!AER-DAT2.0\r\n" + os.urandom(37))
    for model, name in (("tdnn", "m.model"), ("material-dnn", "c.model")):
        code, stderr, _ = invoke(["train", "--model", model, "--epochs", "1", "-o", str(folder / name), str(folder / "f.arrows")])
        assert code == 0, stderr
    return folder


def invoke(args, stdin=GARBAGE):
    result = CliRunner().invoke(cli, args, input=stdin)
    return result.exit_code, result.stderr, result.output


# command -> (arguments of a usage error, arguments of a data error with GARBAGE on stdin); {d} = the files
CASES = {
    "simulate": (["simulate"], ["simulate", "--trials", "1", "--synced", "-o", "{d}/no-such-folder/s.arrows"]),
    "import": (["import", "{d}/garbage.aedat", "-o", "e.xyz"], ["import", "-"]),
    "info": (["info", "--no-such-option", "-"], ["info", "-"]),
    "sync": (["sync", "-"], ["sync", "-", "--force", "{d}/force.csv"]),
    "frame": (["frame", "--window", "10ms", "-o", "f.txt"], ["frame", "--window", "10ms"]),
    "crop": (["crop", "--size", "4x4", "-o", "c.txt"], ["crop", "--size", "4x4", "--center", "auto"]),
    "augment": (["augment", "--fs", "1", "-o", "a.arrowz"], ["augment", "--fs", "1"]),
    "train": (["train", "--model", "tdnn", "-o", "{d}/m.model", "--plot", "curve.xyz"], ["train", "--model", "tdnn", "-o", "{d}/m2.model"]),
    "eval": (["eval", "--model", "{d}/m.model", "--metrics", "m.jsn"], ["eval", "--model", "{d}/m.model"]),
    "classify": (["classify", "--model", "{d}/c.model", "-o", "p.txt"], ["classify", "--model", "{d}/c.model"]),
    "predict": (["predict", "--model", "{d}/m.model", "-o", "p.txt"], ["predict", "--model", "{d}/m.model"]),
    "sense": (["sense", "-", "--model", "{d}/m.model", "-o", "p.txt"], ["sense", "-", "--model", "{d}/m.model"]),
    "render": (["render", "-o", "r.txt"], ["render", "-o", "r.png"]),
    "select": (["select", "-o", "s.arrows"], ["select", "--where", "trial = 'a'"]),
    "concat": (["concat"], ["concat", "-", "{d}/f.arrows"]),
    "split": (["split", "--train", "a.arrows", "--test", "b.arrows", "--fraction", "2"], ["split", "--train", "a.arrows", "--test", "b.arrows", "--fraction", "0.5"]),
    "export": (["export", "-o", "e.txt"], ["export", "-o", "e.raw"]),
    "study": (["study", "--model-spec", "tdnn", "--grid", "layers", "{d}/f.arrows"], ["study", "--model-spec", "tdnn"]),
}


def test_every_command_has_its_cases():
    assert set(CASES) == set(COMMANDS)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_usage_error_exits_2_and_bad_data_exits_1_in_one_line(command, files):
    usage, data = ([arg.format(d=files) for arg in args] for args in CASES[command])
    code, stderr, _ = invoke(usage)
    assert code == 2, stderr
    assert "Traceback" not in stderr and "rror" in stderr
    code, stderr, _ = invoke(data)
    assert code == 1, stderr
    assert stderr.startswith(f"neurotac {command}: error: ") and stderr.count("\n") == 1, stderr


def test_the_table_suffixes_of_the_options_are_those_the_writer_knows():
    assert set(TablePath.SUFFIXES) == set(tables.SUFFIXES)


# ---------------------------------------------------------------- outputs that cannot be written


class FullDisk:
    """An IPC writer on a disk that fills after the first batch."""

    def __init__(self, sink, schema):
        self.batches = 0

    def write_batch(self, batch):
        self.batches += 1
        if self.batches > 1:
            raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")

    def close(self):
        pass


def write_frames(path, stream):
    return invoke(["crop", "--pool", "2x2", "-o", str(path), "-"], stdin=stream)


def _stream(table):
    import io

    import pyarrow as pa

    sink = io.BytesIO()
    with pa.ipc.new_stream(sink, table.schema) as writer:
        for batch in table.to_batches(max_chunksize=4):
            writer.write_batch(batch)
    return sink.getvalue()


def test_a_full_disk_is_one_line_keeps_the_old_file_and_leaves_no_part(tmp_path, monkeypatch):
    target = tmp_path / "out.arrows"
    target.write_bytes(b"the previous output")
    stream = _stream(frames_table(tuple("abcdef")))
    monkeypatch.setattr(tables.ipc, "new_stream", FullDisk)
    code, stderr, _ = write_frames(target, stream)
    assert code == 1 and stderr.count("\n") == 1
    assert "cannot write" in stderr and "no space left on the device" in stderr and "previous" in stderr
    assert target.read_bytes() == b"the previous output"
    assert sorted(os.listdir(tmp_path)) == ["out.arrows"]


def test_a_folder_that_vanishes_while_writing_is_one_line(tmp_path, monkeypatch):
    folder = tmp_path / "gone"
    folder.mkdir()
    real_replace = os.replace

    def vanish_then_replace(source, destination):
        shutil.rmtree(folder)
        return real_replace(source, destination)

    monkeypatch.setattr(tables.os, "replace", vanish_then_replace)
    code, stderr, _ = write_frames(folder / "out.arrows", _stream(frames_table()))
    assert code == 1 and stderr.count("\n") == 1 and "its folder vanished while writing" in stderr


@pytest.fixture
def tmpfs(tmp_path):
    """Mount a small tmpfs (needs root): yields a function mounting one with the given options."""
    mounted = []

    def mount(options):
        folder = tmp_path / f"fs{len(mounted)}"
        folder.mkdir()
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True)
        if done.returncode:
            pytest.skip(f"cannot mount a tmpfs here ({done.stderr.decode().strip()}; needs root)")
        mounted.append(folder)
        return folder

    if shutil.which("mount") is None or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    yield mount
    for folder in mounted:
        subprocess.run(["umount", str(folder)], capture_output=True)


def one_error(stderr: str) -> bool:
    """One error line, no traceback (warnings may come before it)."""
    return "Traceback" not in stderr and [": error: " in line for line in stderr.splitlines()].count(True) == 1


def test_a_real_full_disk_and_a_read_only_one(tmpfs, files):
    small = tmpfs("size=64k")
    (small / "f.arrows").write_bytes(b"old")
    done = subprocess.run(["neurotac", "augment", "--rotate", "10", "--copies", "40", "-o", str(small / "f.arrows"), str(files / "f.arrows")],
                          capture_output=True, text=True)
    assert done.returncode == 1 and one_error(done.stderr) and "no space left" in done.stderr, done.stderr
    assert (small / "f.arrows").read_bytes() == b"old" and os.listdir(small) == ["f.arrows"]
    done = subprocess.run(f"neurotac augment --rotate 10 --copies 40 {files / 'f.arrows'} > {small / 'g.arrows'}", shell=True, capture_output=True, text=True)
    assert done.returncode == 1 and one_error(done.stderr) and "no space left" in done.stderr, done.stderr
    read_only = tmpfs("ro,size=64k")
    done = subprocess.run(["neurotac", "crop", "--pool", "2x2", "-o", str(read_only / "f.arrows"), str(files / "f.arrows")], capture_output=True, text=True)
    assert done.returncode == 1 and "read-only file system" in done.stderr and done.stderr.count("\n") == 1


# ---------------------------------------------------------------- the same trials twice


@pytest.mark.parametrize("command", [
    ["crop", "--pool", "2x2"], ["augment", "--fs", "1"], ["train", "--model", "tdnn", "--epochs", "1", "-o", "{d}/x.model"],
    ["eval", "--model", "{d}/m.model"], ["classify", "--model", "{d}/c.model"], ["predict", "--model", "{d}/m.model"],
    ["study", "--model-spec", "tdnn"],
])
def test_the_same_frames_given_twice_are_refused_with_a_hint(command, files):
    args = [arg.format(d=files) for arg in command]
    code, stderr, _ = invoke([*args, str(files / "f.arrows"), str(files / "f.arrows")])
    assert code == 1 and "frame 0 of trial 'a' appears twice" in stderr and "--trial" in stderr, stderr
    twice = (files / "f.arrows").read_bytes() * 2  # `cat f.arrows f.arrows |`
    code, stderr, _ = invoke(args, stdin=twice)
    assert code == 1 and "appears twice" in stderr, stderr


def test_the_same_recordings_twice_are_refused_and_distinct_ones_pass(files, tmp_path):
    code, stderr, _ = invoke(["frame", "--window", "1ms", str(files / "r.arrows"), str(files / "r.arrows")])
    assert code == 1 and "trial 'a' appears twice" in stderr
    tables.write(str(tmp_path / "r2.arrows"), recordings_table(("c", "d")))
    code, stderr, _ = invoke(["frame", "--window", "1ms", "-o", str(tmp_path / "f.arrows"), str(files / "r.arrows"), str(tmp_path / "r2.arrows")])
    assert code == 0, stderr


def test_a_repeated_frame_within_one_batch_and_far_apart_frame_numbers():
    unique = sch.UniqueRows("frames")
    unique.check(frames_table(("a",)).to_batches()[0])
    unique.check(frames_table(("b",)).to_batches()[0])
    table = frames_table(("c",))
    import pyarrow as pa

    far = table.set_column(1, "frame", pa.array([0, 2**30, 5, 2**31 - 1], pa.int32()))
    unique.check(far.to_batches()[0])  # a set, not 2 GB of flags
    with pytest.raises(sch.SchemaError, match="frame 5 of trial 'c'"):
        unique.check(far.slice(2, 1).to_batches()[0])
    doubled = table.set_column(1, "frame", pa.array([7, 8, 7, 9], pa.int32())).set_column(0, "trial", pa.array(["d"] * 4))
    with pytest.raises(sch.SchemaError, match="frame 7 of trial 'd'"):
        sch.UniqueRows("frames").check(doubled.to_batches()[0])


@pytest.mark.parametrize("rows_per_batch", [1, 7, 200])
def test_row_by_row_and_batched_checks_find_the_same_repeat(rows_per_batch):
    """Small batches (a streamed frame at a time) are checked row by row, large ones with numpy."""
    import pyarrow as pa

    trials = np.repeat(np.array(["a", "b", "c"]), 300)
    frames = np.tile(np.arange(300), 3)
    frames[700] = 50  # trial c (rows 600-899) has frame 50 at row 650 already
    table = pa.table({"trial": trials, "frame": pa.array(frames, pa.int32())})
    unique = sch.UniqueRows("frames")
    with pytest.raises(sch.SchemaError, match="frame 50 of trial 'c'"):
        for batch in table.to_batches(max_chunksize=rows_per_batch):
            unique.check(batch)


@pytest.mark.parametrize("name", [".arrows", "out.ARROWS.bak", "out"])
def test_an_output_named_without_a_table_suffix_is_a_usage_error(name, files):
    code, stderr, _ = invoke(["crop", "--pool", "2x2", "-o", name, str(files / "f.arrows")])
    assert code == 2 and "cannot tell the table format" in stderr


@pytest.mark.parametrize("text, says", [
    (None, "cannot read the true slips"),
    ("trial,start,end\na,1,2\n", "no slip_start_ms, slip_end_ms column"),
    ("slip_start_ms,slip_end_ms\n1,2\n", "no trial (or session) column"),
    ("trial,slip_start_ms,slip_end_ms\na,ten,20\n", "line 2: slip_start_ms is 'ten'"),
    ("trial,slip_start_ms,slip_end_ms\na,5,nan\n", "line 2: slip_end_ms is 'nan'"),
    ("trial,slip_start_ms,slip_end_ms\na,,\nb,20,10\n", "line 3: the slip ends at 10 ms, not after its start at 20 ms"),
    (b"\xff\xfe\x00bad", "not a CSV of true slips"),
])
def test_a_bad_csv_of_true_slips_is_one_line(files, tmp_path, text, says):
    path = tmp_path / "slips.csv"
    if isinstance(text, bytes):
        path.write_bytes(text)
    elif text is not None:
        path.write_text(text)
    code, stderr, _ = invoke(["frame", "--window", "1ms", "--slips", str(path), str(files / "r.arrows")])
    assert code == 1 and stderr.count("\n") == 1 and says in stderr, stderr


def test_true_slips_for_a_plain_events_stream_are_refused(files, tmp_path):
    (tmp_path / "slips.csv").write_text("trial,slip_start_ms,slip_end_ms\na,1,2\n")
    events = tmp_path / "e.arrows"
    tables.write(str(events), sch.events_table(np.array([0, 5]), np.array([1, 2]), np.array([1, 2]), np.array([0, 1]), 8, 8))
    code, stderr, _ = invoke(["frame", "--window", "1ms", "--slips", str(tmp_path / "slips.csv"), str(events)])
    assert code == 1 and "synced recordings" in stderr and stderr.count("\n") == 1, stderr


@pytest.mark.parametrize("name, offered", [("big.arrows", True), ("big.parquet", False), ("big.png", False)])
def test_parquet_is_offered_for_a_file_too_large_only_where_the_output_is_an_uncompressed_table(name, offered):
    # a Parquet table, a picture or a model has no smaller form that the advice could name
    why, what_to_do = OutputError.why(OSError(errno.EFBIG, "File too large"), name)
    assert why == "file too large for its file system"
    assert ("as .parquet" in what_to_do) == offered
    assert ("as .parquet" in str(OutputError.from_os(name, OSError(errno.EFBIG, "File too large")))) == offered


def test_the_uncompressed_tables_are_every_table_format_but_parquet():
    # errors.py cannot import tables.py (tables imports errors): the two lists are kept in step here
    assert set(OutputError.UNCOMPRESSED_TABLES) == {suffix for suffix, kind in tables.SUFFIXES.items() if kind != "parquet"}


def test_a_picture_too_large_for_a_size_limit_is_not_told_to_be_parquet(files, tmp_path):
    done = subprocess.run(["bash", "-c", f"ulimit -f 1; neurotac render {files / 'f.arrows'} -o p.png"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 1 and one_error(done.stderr) and "file too large" in done.stderr, done.stderr
    assert ".parquet" not in done.stderr


def test_eval_replaces_neither_metrics_nor_plot_when_the_plot_cannot_be_written(files, tmp_path):
    # the metrics were replaced before the plot failed: metrics of this run beside a plot of the last
    (tmp_path / "m.parquet").write_bytes(b"old metrics")
    (tmp_path / "p.png").write_bytes(b"old plot")
    done = subprocess.run(["bash", "-c", f"ulimit -f 24; neurotac eval --model {files / 'm.model'} {files / 'f.arrows'} "
                           "--metrics m.parquet --plot p.png -o pred.arrows"], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 1 and one_error(done.stderr) and "cannot write p.png" in done.stderr, done.stderr
    assert (tmp_path / "m.parquet").read_bytes() == b"old metrics" and (tmp_path / "p.png").read_bytes() == b"old plot"
    assert sorted(os.listdir(tmp_path)) == ["m.parquet", "p.png"]


def test_an_output_name_too_long_for_the_file_system_is_one_line(files, tmp_path):
    # found at the final rename, after the work, as an OSError traceback
    name = "a" * 300 + ".arrows"
    code, stderr, _ = invoke(["select", "--where", "true", "-o", str(tmp_path / name), str(files / "f.arrows")])
    assert code == 1 and stderr.count("\n") == 1 and "its name is too long for the file system" in stderr, stderr
    assert os.listdir(tmp_path) == []
    code, stderr, _ = invoke(["split", "--fraction", "0.5", "--train", str(tmp_path / "t.arrows"), "--test", str(tmp_path / name),
                              str(files / "f.arrows")])
    assert code == 1 and "its name is too long" in stderr and os.listdir(tmp_path) == []
