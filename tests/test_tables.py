"""The table layer: sniffing, streams, concatenation, atomic writes, history, errors at the door."""

import errno
import io
import os
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from neurotac_cli import schema, tables
from neurotac_cli.errors import InputError, NeurotacError, SchemaError


def events(n=100, width=240, height=180, seed=0):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(0, 1_000_000, n))
    return schema.events_table(t, rng.integers(0, width, n), rng.integers(0, height, n), rng.integers(0, 2, n), width, height)


def write_to(path, table, step=("test", {})):
    tables.write(str(path), table, step=step)
    return path


@pytest.mark.parametrize("suffix", [".parquet", ".arrow", ".arrows", ".feather"])
def test_every_format_round_trips_with_metadata(tmp_path, suffix):
    table = events()
    path = write_to(tmp_path / f"e{suffix}", table)
    back = tables.read([str(path)], kind="events")
    assert back.equals(table)
    assert schema.sensor_of(back.schema) == (240, 180)
    assert schema.get_meta(back.schema, schema.HISTORY)[-1]["command"] == "test"


def test_written_files_get_the_permissions_the_umask_gives(tmp_path):
    old = os.umask(0o027)
    try:
        path = write_to(tmp_path / "e.arrows", events())
    finally:
        os.umask(old)
    assert oct(path.stat().st_mode & 0o777) == oct(0o640)  # not mkstemp's 0600


def test_several_paths_are_one_table_in_order(tmp_path):
    a, b = events(50, seed=1), events(70, seed=2)
    pa_, pb = write_to(tmp_path / "a.parquet", a), write_to(tmp_path / "b.arrows", b)
    back = tables.read([str(pa_), str(pb)], kind="events")
    assert back.num_rows == 120
    assert back.column("t").to_pylist() == a.column("t").to_pylist() + b.column("t").to_pylist()


def test_concatenated_streams_on_one_source_read_as_one_table(tmp_path):
    a, b = events(50, seed=1), events(70, seed=2)
    write_to(tmp_path / "a.arrows", a)
    write_to(tmp_path / "b.arrows", b)
    joined = tmp_path / "ab.arrows"
    joined.write_bytes((tmp_path / "a.arrows").read_bytes() + (tmp_path / "b.arrows").read_bytes())
    assert tables.read([str(joined)], kind="events").num_rows == 120


def test_mismatched_sensors_are_refused(tmp_path):
    a = write_to(tmp_path / "a.arrows", events(10))
    b = write_to(tmp_path / "b.arrows", events(10, width=346, height=260))
    with pytest.raises(SchemaError, match="different sensor sizes"):
        tables.read([str(a), str(b)], kind="events")


def test_history_grows_by_one_entry_per_write(tmp_path):
    first = write_to(tmp_path / "a.arrows", events(), ("one", {"x": 1}))
    table = tables.read([str(first)])
    second = write_to(tmp_path / "b.arrows", table, ("two", {"window": 10000}))
    history = schema.get_meta(tables.read([str(second)]).schema, schema.HISTORY)
    assert [entry["command"] for entry in history] == ["one", "two"]
    assert history[1]["args"] == {"window": 10000}


def test_same_input_same_bytes(tmp_path):
    a = write_to(tmp_path / "a.parquet", events())
    b = write_to(tmp_path / "b.parquet", events())
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("cut", [9, 100, 400, -30])
def test_a_stream_cut_short_is_one_clear_error(tmp_path, cut):
    path = write_to(tmp_path / "a.arrows", events(2000))
    data = path.read_bytes()
    (tmp_path / "cut.arrows").write_bytes(data[:cut])
    with pytest.raises(InputError, match="ended mid-table|empty"):
        tables.read([str(tmp_path / "cut.arrows")], kind="events")


def test_a_stream_that_stops_between_batches_without_its_end_marker_is_refused(tmp_path):
    # what a command that fails after writing some batches leaves in the pipe: whole batches, no end marker
    table = events(2000)
    with pa.OSFile(str(tmp_path / "a.arrows"), "wb") as sink:
        writer = pa.ipc.new_stream(sink, table.schema)
        for batch in table.to_batches(max_chunksize=500)[:2]:
            writer.write_batch(batch)
    with pytest.raises(InputError, match="ended mid-table"):
        tables.read([str(tmp_path / "a.arrows")], kind="events")
    whole = write_to(tmp_path / "b.arrows", table)
    assert whole.read_bytes().endswith(tables.END_OF_STREAM)
    assert tables.read([str(whole)], kind="events").num_rows == 2000


def test_a_parquet_file_cut_short_is_one_clear_error(tmp_path):
    path = write_to(tmp_path / "a.parquet", events(2000))
    (tmp_path / "cut.parquet").write_bytes(path.read_bytes()[:-100])
    with pytest.raises(InputError, match="cut short|damaged"):
        tables.read([str(tmp_path / "cut.parquet")], kind="events")


def test_an_arrow_file_cut_short_says_so_from_a_path_and_from_a_pipe(tmp_path):
    path = write_to(tmp_path / "a.arrow", events(2000))
    cut = path.read_bytes()[: len(path.read_bytes()) // 2]
    (tmp_path / "cut.arrow").write_bytes(cut)
    with pytest.raises(InputError, match="Arrow file is cut short or damaged"):
        tables.read([str(tmp_path / "cut.arrow")], kind="events")
    done = subprocess.run(["neurotac", "info"], input=cut, capture_output=True)
    assert done.returncode == 1 and done.stderr == b"neurotac info: error: stdin: Arrow file is cut short or damaged (its footer is missing)\n"


def test_not_a_table_directory_missing_and_empty(tmp_path):
    (tmp_path / "x.csv").write_text("t,x,y,p\n1,2,3,1\n")
    (tmp_path / "empty.arrows").write_bytes(b"")
    with pytest.raises(InputError, match="not an Arrow or Parquet table"):
        tables.read([str(tmp_path / "x.csv")])
    with pytest.raises(InputError, match="is a directory"):
        tables.read([str(tmp_path)])
    with pytest.raises(InputError, match="no such file"):
        tables.read([str(tmp_path / "missing.parquet")])
    with pytest.raises(InputError, match="empty"):
        tables.read([str(tmp_path / "empty.arrows")])


def test_a_table_with_no_rows_is_refused_unless_allowed(tmp_path):
    path = write_to(tmp_path / "e.arrows", events(0))
    with pytest.raises(InputError, match="empty"):
        tables.read([str(path)], kind="events")
    assert tables.read([str(path)], kind="events", allow_empty=True).num_rows == 0


def test_wrong_kind_and_mistyped_columns_are_refused(tmp_path):
    path = write_to(tmp_path / "e.arrows", events())
    with pytest.raises(SchemaError, match="expected a frames table, got an? events table.*neurotac frame"):
        tables.read([str(path)], kind="frames")
    bad = pa.table({"t": pa.array(["a"]), "x": pa.array([1], pa.uint16()), "y": pa.array([1], pa.uint16()), "p": pa.array([1], pa.uint8())})
    pq.write_table(bad, tmp_path / "bad.parquet")
    with pytest.raises(SchemaError, match="column 't'"):
        tables.read([str(tmp_path / "bad.parquet")], kind="events")
    missing = pa.table({"a": [1]})
    pq.write_table(missing, tmp_path / "missing.parquet")
    with pytest.raises(SchemaError, match="not a neurotac table"):
        tables.read([str(tmp_path / "missing.parquet")], kind="events")


def test_tables_from_other_tools_are_recognised_and_cast(tmp_path):
    plain = pa.table({"t": pa.array([1, 2], pa.int32()), "x": pa.array([1, 2], pa.int64()), "y": pa.array([1, 2], pa.int64()), "p": pa.array([0, 1], pa.int64())})
    pq.write_table(plain, tmp_path / "plain.parquet")
    back = tables.read([str(tmp_path / "plain.parquet")], kind="events")
    assert back.schema.field("x").type == pa.uint16() and back.num_rows == 2


def test_failed_write_leaves_no_file(tmp_path):
    def batches():
        yield events(10).to_batches()[0]
        raise NeurotacError("upstream failed")

    target = tmp_path / "out.parquet"
    with pytest.raises(NeurotacError):
        tables.write(str(target), batches(), schema=events(1).schema)
    assert not target.exists()
    assert os.listdir(tmp_path) == []


def test_unknown_output_suffix_is_refused(tmp_path):
    with pytest.raises(NeurotacError, match="suffix"):
        tables.write(str(tmp_path / "out.xlsx"), events())


def test_counts_round_trip_as_a_canonical_tensor(tmp_path):
    counts = np.arange(3 * 2 * 4 * 5, dtype=np.uint16).reshape(3, 2, 4, 5)
    frames_schema = schema.frames_schema(4, 5, labels=["material"], window_us=10_000)
    table = pa.Table.from_pydict(
        {
            "trial": ["a"] * 3,
            "frame": pa.array([0, 1, 2], pa.int32()),
            "t": pa.array([0, 10_000, 20_000], pa.int64()),
            "counts": schema.counts_array(counts),
            "force": pa.array([0.0, 1.0, None], pa.float32()),
            "phase": ["grasping", "holding", None],
            "material": ["foam"] * 3,
        },
        schema=frames_schema,
    )
    path = write_to(tmp_path / "f.parquet", table)
    back = tables.read([str(path)], kind="frames")
    assert np.array_equal(schema.counts_numpy(back.column("counts")), counts)
    assert schema.label_columns(back.schema) == ["material"]
    assert schema.frames_shape(back.schema) == (4, 5)


def test_batches_flow_through_a_pipe_before_the_input_ends(tmp_path):
    """A reader sees the first batch while the writer is still running (no buffering to end of input)."""
    code = (
        "import sys, time, numpy as np, pyarrow as pa, pyarrow.ipc as ipc\n"
        "from neurotac_cli import schema\n"
        "b = schema.events_table([1],[1],[1],[1]).to_batches()[0]\n"
        "w = ipc.new_stream(sys.stdout.buffer, b.schema); w.write_batch(b); sys.stdout.buffer.flush()\n"
        "time.sleep(5); w.write_batch(b); w.close()\n"
    )
    reader = (
        "import time, sys\nfrom neurotac_cli import tables\n"
        "start = time.time(); source = tables.open_input(['-'], kind='events')\n"
        "next(source.batches); print(round(time.time() - start, 1))\n"
    )
    writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    done = subprocess.run([sys.executable, "-c", reader], stdin=writer.stdout, capture_output=True, text=True, timeout=30)
    writer.kill()
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) < 4.0


def test_outputs_that_name_one_file_are_told_from_stdout_and_from_a_link(tmp_path):
    """`-` is stdout, not a file named `-`; a link named as one output is replaced by the write, its
    target (the other output) kept."""
    from neurotac_cli.errors import UsageError
    from neurotac_cli.tables import check_folder

    (tmp_path / "sub").mkdir()
    (tmp_path / "to-sub").symlink_to(tmp_path / "sub")
    (tmp_path / "e.parquet").touch()
    (tmp_path / "m.parquet").symlink_to(tmp_path / "e.parquet")
    check_folder(str(tmp_path / "-"), "-")
    check_folder(str(tmp_path / "e.parquet"), str(tmp_path / "m.parquet"))
    for twice in ([str(tmp_path / "sub" / "a.arrows"), str(tmp_path / "to-sub" / "a.arrows")],
                  [str(tmp_path / "a.png"), str(tmp_path / "sub" / ".." / "a.png")]):
        with pytest.raises(UsageError, match="two outputs name one file"):
            check_folder(*twice)


def test_an_output_under_a_regular_file_names_the_file_not_a_missing_folder(tmp_path):
    """`file.txt/out.parquet`: "folder file.txt does not exist" would send one to make a folder that cannot be made."""
    (tmp_path / "file.txt").write_text("hi")
    for path in (tmp_path / "file.txt" / "out.parquet", tmp_path / "file.txt" / "a" / "out.parquet"):
        with pytest.raises(NeurotacError, match=f"^cannot write {path}: {tmp_path / 'file.txt'} is a file, not a folder; give a path in a folder$"):
            tables.check_folder(str(path))
    with pytest.raises(NeurotacError, match="folder .* does not exist"):
        tables.check_folder(str(tmp_path / "no" / "out.parquet"))


def test_an_arrow_file_truncated_while_it_is_read_is_one_error_not_a_bus_error(tmp_path):
    """Another program truncating an Arrow file mid-read: a memory-mapped file would kill the process
    with SIGBUS; in a child process, so that this test's process survives it."""
    path = tmp_path / "e.arrow"
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, events().schema) as writer:
        for _ in range(8):
            writer.write_table(pa.concat_tables([events(20000)] * 10))
    code = ("import os\nfrom neurotac_cli import tables\nfrom neurotac_cli.errors import NeurotacError\n"
            f"opened = tables.open_input([{str(path)!r}])\nnext(opened.batches)\nos.truncate({str(path)!r}, 1000)\n"
            "try:\n    list(opened.batches)\nexcept NeurotacError as error:\n    print(error)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout.strip()) == (0, f"{path}: {tables.TRUNCATED}"), done.stderr[-300:]


def _drain(path):
    """Read a FIFO to its end in a thread (a writer blocks until a reader opens it)."""
    import threading

    got = {}
    thread = threading.Thread(target=lambda: got.setdefault("bytes", open(path, "rb").read()), daemon=True)
    thread.start()
    return thread, got


@pytest.mark.parametrize("name", ["pipe", "pipe.parquet", "pipe.arrow"])
def test_a_pipe_given_as_output_gets_the_stream_and_stays_a_pipe(tmp_path, name):
    """`-o >(...)` or a FIFO: a pipe cannot seek, so it gets the stream stdout gets, whatever its name
    says, and is never renamed over."""
    import stat

    (tmp_path / "pipes").mkdir()
    fifo = tmp_path / "pipes" / name
    os.mkfifo(fifo)
    thread, got = _drain(fifo)
    tables.write(str(fifo), events(), step=("test", {}))
    thread.join(10)
    assert got["bytes"].startswith(tables.STREAM_MAGIC)
    (tmp_path / "copy").write_bytes(got["bytes"])
    assert tables.read([str(tmp_path / "copy")]).column("t").equals(events().column("t"))
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and os.listdir(tmp_path / "pipes") == [name]


def test_every_other_output_into_a_pipe_is_copied_in_not_renamed_over(tmp_path):
    """Model files, plots and CSV are finished in the temporary folder and copied into a pipe or
    device: a rename over /dev/null would replace it for the whole machine."""
    import stat

    fifo = tmp_path / "model"
    os.mkfifo(fifo)
    thread, got = _drain(fifo)
    with tables.atomic_file(str(fifo)) as temporary:
        assert os.path.dirname(temporary) != str(tmp_path)
        with open(temporary + ".next", "wb") as handle:  # a writer that replaces its file, as safetensors does
            handle.write(b"finished")
        os.replace(temporary + ".next", temporary)
    thread.join(10)
    assert got["bytes"] == b"finished"
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and os.listdir(tmp_path) == ["model"]


def test_ctrl_c_ends_a_write_into_a_fifo_nobody_reads(tmp_path):
    """A verb reading a pipe lets the first Ctrl-C pass (to read on to the end of its input); the
    second must end it even while it waits for a reader of its -o FIFO."""
    import signal
    import stat
    import time

    tables.write(str(tmp_path / "e.arrows"), events(), step=("test", {}))
    fifo = tmp_path / "out.arrows"
    os.mkfifo(fifo)
    process = subprocess.Popen(["neurotac", "select", "--where", "x >= 0", "-o", str(fifo)], stdin=subprocess.PIPE,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    process.stdin.write((tmp_path / "e.arrows").read_bytes())
    process.stdin.close()
    process.stdin = None
    time.sleep(3.0)  # read, and waiting for a reader
    for _ in range(2):
        process.send_signal(signal.SIGINT)
        time.sleep(0.5)
    try:
        _, stderr = process.communicate(timeout=10)
    finally:
        process.kill()
    assert process.returncode == 130 and stderr.decode().strip().count("\n") == 0, stderr
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_a_pipe_without_a_table_suffix_is_an_output_path(tmp_path):
    import click

    from neurotac_cli.options import TablePath

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert TablePath().convert(str(fifo), None, None) == str(fifo)
    with pytest.raises(click.BadParameter, match="cannot tell the table format"):
        TablePath().convert(str(tmp_path / "file"), None, None)


def test_stdout_as_an_output_needs_no_writable_working_folder(tmp_path, monkeypatch):
    """`-o -` is stdout: a read-only working folder is no reason to refuse it."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(os, "access", lambda path, mode: False)
    tables.check_folder("-")
    with pytest.raises(NeurotacError, match="cannot write"):
        tables.check_folder(str(tmp_path / "out.arrows"))


def test_crop_into_a_pipe_hands_on_each_batch_as_it_comes(tmp_path):
    """`crop -o >(...)` in a live pipe: its first frame reaches the reader while its input still runs,
    as on stdout."""
    frames = tmp_path / "f.arrows"
    subprocess.run("neurotac simulate --preset ch4 --trials 1 --synced | neurotac frame --window 10ms > " + str(frames),
                   shell=True, check=True, capture_output=True)
    fifo = tmp_path / "out"
    os.mkfifo(fifo)
    feeder = ("import sys, time, pyarrow.ipc as ipc\n"
              f"reader = ipc.open_stream(open({str(frames)!r}, 'rb'))\n"
              "writer = ipc.new_stream(sys.stdout.buffer, reader.schema)\n"
              "batch = reader.read_next_batch()\n"
              "writer.write_batch(batch.slice(0, 1)); sys.stdout.buffer.flush(); time.sleep(8)\n"
              "writer.write_batch(batch.slice(1, 1)); writer.close()\n")
    source = subprocess.Popen([sys.executable, "-c", feeder], stdout=subprocess.PIPE)
    crop = subprocess.Popen(["neurotac", "crop", "--box", "0,0,8,8", "-o", str(fifo)], stdin=source.stdout, stderr=subprocess.PIPE)
    reader = ("import time, sys\nfrom neurotac_cli import tables\n"
              f"start = time.time(); opened = tables.open_input([{str(fifo)!r}])\n"
              "next(opened.batches); print(round(time.time() - start, 1)); list(opened.batches)\n")
    try:
        done = subprocess.run([sys.executable, "-c", reader], capture_output=True, text=True, timeout=60)
    finally:
        source.kill()
        _, said = crop.communicate(timeout=30)
    assert done.returncode == 0 and crop.returncode == 0, done.stderr + said.decode()
    assert float(done.stdout) < 6.0


class _CountingRaw(io.RawIOBase):
    """An unbuffered stdout (PYTHONUNBUFFERED) that counts its system calls."""

    def __init__(self):
        self.data, self.calls = bytearray(), 0

    def writable(self):
        return True

    def write(self, chunk):
        self.calls += 1
        self.data += bytes(chunk)
        return len(chunk)


def test_a_streamed_batch_leaves_an_unbuffered_stdout_in_one_write():
    """Arrow writes a batch in a score of pieces; each was a system call that woke the reader."""
    raw = _CountingRaw()
    table = pa.table({"frame": pa.array(range(50), pa.int64()), "force": pa.array(np.linspace(0, 1, 50))})
    tables._write_stream(raw, table.schema, table.to_batches(max_chunksize=1), flush_each=True)
    assert raw.calls <= 50 + 2  # one a batch, the schema and the end (the schema goes with the first batch)
    assert not raw.closed
    assert pa.ipc.open_stream(bytes(raw.data)).read_all().equals(table)


def _frames(trial, sensor=None, window_us=10000):
    counts = schema.counts_array(np.zeros((2, 2, 3, 4), np.uint16))
    frames = schema.frames_schema(3, 4, window_us=window_us)
    table = pa.table({"trial": trial, "frame": pa.array([0, 1], pa.int32()), "t": pa.array([0, 10000], pa.int64()),
                      "counts": counts, "force": pa.array([1.0, 2.0], pa.float32()), "phase": pa.array(["holding"] * 2)})
    return table.replace_schema_metadata(schema.set_meta(frames, **({"sensor": sensor} if sensor else {})).metadata)


def test_whole_number_trial_ids_are_read_as_text_and_other_types_get_advice(tmp_path):
    path = write_to(tmp_path / "int.arrows", _frames(pa.array([7, 7], pa.int64())))
    assert tables.read([str(path)], kind="frames").column("trial").to_pylist() == ["7", "7"]
    path = write_to(tmp_path / "float.arrows", _frames(pa.array([7.5, 7.5])))
    with pytest.raises(SchemaError, match="has type double, expected string; trial ids are text or whole numbers"):
        tables.read([str(path)], kind="frames")


def test_a_frames_sensor_that_contradicts_the_counts_or_a_fractional_window_is_refused(tmp_path):
    path = write_to(tmp_path / "s.arrows", _frames(pa.array(["a", "a"]), sensor={"width": 30, "height": 30}))
    with pytest.raises(SchemaError, match="neurotac:sensor says 30x30, but the frames' counts are 4x3"):
        tables.read([str(path)], kind="frames")
    assert tables.read([str(write_to(tmp_path / "ok.arrows", _frames(pa.array(["a", "a"]))))], kind="frames").num_rows == 2
    half = _frames(pa.array(["a", "a"]))
    half = half.replace_schema_metadata(schema.set_meta(half.schema, window_us=0.5).metadata)
    pq.write_table(half, tmp_path / "half.parquet")
    with pytest.raises(SchemaError, match=r"window_us is 0.5, not a whole number of µs, 1 or more"):
        tables.read([str(tmp_path / "half.parquet")], kind="frames")


def test_outputs_written_together_are_all_replaced_or_none(tmp_path):
    # one output replaced and the next not mixes two runs (a split's trial on both sides)
    first, second = tmp_path / "a.arrows", tmp_path / "b.arrows"
    first.write_bytes(b"old a")
    second.write_bytes(b"old b")
    with pytest.raises(OSError):
        with tables.together():
            with tables.atomic_file(str(first)) as temporary:
                open(temporary, "wb").write(b"new a")
            with tables.atomic_file(str(second)):
                raise OSError(errno.EBADF, "a failure that is no output's")
    assert (first.read_bytes(), second.read_bytes()) == (b"old a", b"old b")
    assert sorted(os.listdir(tmp_path)) == ["a.arrows", "b.arrows"]
    with tables.together():
        for path, text in ((first, b"new a"), (second, b"new b")):
            with tables.atomic_file(str(path)) as temporary:
                open(temporary, "wb").write(text)
        assert first.read_bytes() == b"old a"  # nothing is replaced before the block ends
    assert (first.read_bytes(), second.read_bytes()) == (b"new a", b"new b")
    assert sorted(os.listdir(tmp_path)) == ["a.arrows", "b.arrows"]


def test_outputs_written_together_are_kept_when_stdout_s_reader_goes_away(tmp_path):
    with pytest.raises(BrokenPipeError):
        with tables.together():
            with tables.atomic_file(str(tmp_path / "a.arrows")) as temporary:
                open(temporary, "wb").write(b"new a")
            raise BrokenPipeError(errno.EPIPE, "the reader went away")  # success, as cli.py counts it
    assert (tmp_path / "a.arrows").read_bytes() == b"new a" and os.listdir(tmp_path) == ["a.arrows"]


def test_a_pipe_whose_reader_went_away_keeps_no_other_output_of_the_run_from_its_place(tmp_path):
    filled = []

    class GonePipe(tables._Finish):
        def __call__(self):
            raise BrokenPipeError(errno.EPIPE, "the reader went away")

    class Pipe(tables._Finish):
        def __call__(self):
            filled.append(self.path)

    temporary = tmp_path / ".neurotac-x.part"
    temporary.write_bytes(b"new")
    held = [GonePipe("gone", "", True, 0o022, str(tmp_path)), Pipe("open", "", True, 0o022, str(tmp_path)),
            tables._Finish(str(tmp_path / "m.arrows"), str(temporary), False, 0o022, str(tmp_path))]
    with pytest.raises(BrokenPipeError):
        tables._put_in_place(held)
    assert (tmp_path / "m.arrows").read_bytes() == b"new" and filled == ["open"]


def test_sigterm_removes_the_part_file_and_exits_143(tmp_path):
    # SIGTERM (timeout, make, SLURM) ended the process where it stood: the .part temporary stayed behind
    import signal
    import time

    stream = io.BytesIO()
    table = events(n=20_000)
    with pa.ipc.new_stream(stream, table.schema) as writer:
        writer.write_table(table, max_chunksize=1000)
    data = stream.getvalue()
    process = subprocess.Popen(["neurotac", "crop", "--pool", "2x2", "-o", str(tmp_path / "out.arrows")],
                               stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=tmp_path)
    try:
        process.stdin.write(data[: len(data) // 2])  # half the stream: crop streams, and waits on the rest with its output open
        process.stdin.flush()
        deadline = time.monotonic() + 20
        while not list(tmp_path.glob(".neurotac-*.part")) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert list(tmp_path.glob(".neurotac-*.part")), "the output's temporary file was never made"
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=10)
    finally:
        process.kill()
    assert process.returncode == 143 and stderr.decode() == "neurotac crop: terminated\n", stderr
    assert os.listdir(tmp_path) == []
