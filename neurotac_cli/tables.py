"""The only code that touches stdin, stdout and -o: sniff, read, write, metadata, history.

Reading: paths in order (`-` or none = stdin) are one table. Each source is sniffed from its first
bytes: IPC stream (0xFFFFFFFF), Arrow file (ARROW1) or Parquet (PAR1). Concatenated IPC streams on
one source (`cat a.arrows b.arrows |`) read as one table.

Writing: an IPC stream on stdout, or -o PATH by suffix, through a temporary file renamed when
complete; a pipe or device given as -o (/dev/stdout, a shell's `>(...)`) gets the stream straight
through. Every write appends one entry to `neurotac:history`.
"""

import errno
import io
import os
import stat
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterable, Iterator

import pyarrow as pa
import pyarrow.ipc as ipc

from neurotac_cli import __version__, bridges, schema as sch
from neurotac_cli.errors import InputError, NeurotacError, OutputError, SchemaError, UsageError, cannot_open, empty_path
from neurotac_cli.whole import flush_whole, write_whole

STREAM_MAGIC = b"\xff\xff\xff\xff"
FILE_MAGIC = b"ARROW1"
PARQUET_MAGIC = b"PAR1"
SUFFIXES = {".parquet": "parquet", ".pq": "parquet", ".arrow": "file", ".feather": "file", ".arrows": "stream",
            ".csv": "csv", ".json": "json", ".ndjson": "ndjson"}  # text: neurotac_cli/textout.py
TRUNCATED = "input ended mid-table; did the command before it fail?"
# An Arrow stream's writer ends it with this marker; a stream that stops between two batches without
# it is one whose writer failed or was stopped, and reading it as whole would lose its rest silently.
END_OF_STREAM = b"\xff\xff\xff\xff\x00\x00\x00\x00"


class _Prepend(io.RawIOBase):
    """Put sniffed bytes back in front of a stream. `readinto` delegates to the source's `readinto1`,
    so batches flow as soon as they arrive (a buffered `readinto` would wait for a full buffer)."""

    def __init__(self, head: bytes, source):
        self._head = memoryview(head)
        self._source = source
        self._read = getattr(source, "readinto1", None) or source.readinto
        self.tail = b""  # the last bytes read through it: does the stream end with its end-of-stream marker?

    def readable(self):
        return True

    def read(self, size=-1):
        """Fill the request unless the input ends: pyarrow takes a short read for the end of the stream,
        and a pipe returns whatever has arrived so far."""
        if size is None or size < 0:
            return self.readall()
        buffer = bytearray(size)
        view, got = memoryview(buffer), 0
        while got < size:
            n = self.readinto(view[got:])
            if not n:
                break
            got += n
        return bytes(buffer[:got])

    def readinto(self, buffer):
        if len(self._head):
            n = min(len(buffer), len(self._head))
            buffer[:n] = self._head[:n]
            self._head = self._head[n:]
        else:
            n = self._read(buffer)
        if n:
            self.tail = (self.tail + bytes(memoryview(buffer)[max(n - len(END_OF_STREAM), 0):n]))[-len(END_OF_STREAM):]
        return n

    def ended(self) -> bool:
        """The stream read so far ends with an end-of-stream marker: its writer closed it."""
        return self.tail == END_OF_STREAM


def _read_exactly(source, n: int) -> bytes:
    chunks, got = [], 0
    while got < n:
        chunk = source.read(n - got)
        if not chunk:
            break
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def sniff(head: bytes) -> str | None:
    if head.startswith(STREAM_MAGIC):
        return "stream"
    if head.startswith(FILE_MAGIC):
        return "file"
    if head.startswith(PARQUET_MAGIC):
        return "parquet"
    return None


def is_terminal(stream) -> bool:
    """Whether a stream is a terminal (False for pipes, files, and streams without a descriptor)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def _stdin():
    if sys.stdin is None:
        raise InputError("no input: give a path or pipe a table into stdin")
    stream = getattr(sys.stdin, "buffer", sys.stdin)
    if is_terminal(stream):
        raise InputError("no input: give a path, or pipe a table into stdin (e.g. `neurotac import rec.aedat | ...`)")
    if _is_pipe(stream):
        _read_on_through_interrupt()
    return stream


def _read_on_through_interrupt():
    """For a verb reading a table from a pipe: Ctrl-C reaches every process of a pipe at once. The
    first is let pass, so this verb reads on to the end of its input, which the camera's end
    (`io.live.stop_on_signals`) closes complete, and the pipe's last output is whole; a second
    interrupts as usual. Only in the main thread, where signals are handled."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return
    previous = {}

    def handler(number, frame):
        signal.signal(number, previous[number])

    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, handler)
        signal.siginterrupt(signal.SIGINT, False)


def _is_pipe(stream) -> bool:
    try:
        return stat.S_ISFIFO(os.fstat(stream.fileno()).st_mode)
    except (AttributeError, ValueError, OSError, io.UnsupportedOperation):
        return False


def open_binary(path: str):
    """Open a path (or `-` for stdin) for reading bytes, with user-facing errors."""
    if path in (None, "-"):
        return _stdin()
    if os.path.isdir(path):
        raise InputError(f"{path} is a directory, not a file")
    try:
        return open(path, "rb")
    except OSError as error:
        raise cannot_open(path, error) from None


def _source_batches(path: str) -> Iterator[tuple[pa.Schema, Iterator[pa.RecordBatch]]]:
    """Yield (schema, batches) for each table in one source (several for concatenated IPC streams)."""
    name = "stdin" if path in (None, "-") else path
    source = open_binary(path)
    try:  # from here on the file is closed however this ends, a refusal of its first bytes included
        head = _read_exactly(source, 8)
        fmt = sniff(head)
        if fmt is None:
            if not head:
                raise InputError(f"{name} is empty; did the command before it fail?")
            raise InputError(
                f"{name} is not an Arrow or Parquet table (for camera files use `neurotac import`; "
                "tables are Arrow IPC streams, Arrow files or Parquet)"
            )
        if fmt == "stream":
            stream = _Prepend(head, source)
            first = True
            while True:
                if not first:
                    more = _read_exactly(stream, 8)
                    if not more:
                        return
                    if sniff(more) != "stream":
                        raise InputError(f"{name}: bytes after the end of an Arrow stream are not another stream")
                    stream = _Prepend(more, stream)
                first = False
                reader = ipc.open_stream(stream)
                yield reader.schema, _guard(_whole(reader, stream, name), name)
        else:
            data = pa.BufferReader(head + source.read()) if path in (None, "-") else None
            if fmt == "file":
                try:
                    # read, not memory-mapped: a mapped file that another program truncates while it is
                    # read kills the process with SIGBUS, without a word
                    reader = ipc.open_file(data if data is not None else pa.OSFile(path))
                except pa.ArrowInvalid:  # it starts as an Arrow file (sniffed), so its end is what is missing
                    raise InputError(f"{name}: Arrow file is cut short or damaged (its footer is missing)") from None
                yield reader.schema, _guard((reader.get_batch(i) for i in range(reader.num_record_batches)), name)
            else:
                import pyarrow.parquet as pq  # only for Parquet: its import costs a pipe's every process

                parquet = pq.ParquetFile(data if data is not None else path)
                schema = parquet.schema_arrow
                yield schema, _guard(parquet.iter_batches(batch_size=65536), name, schema)
    except NeurotacError:
        raise
    except (pa.ArrowInvalid, pa.ArrowIOError, OSError, pa.ArrowNotImplementedError) as error:
        raise InputError(f"{name}: {_describe(error)}") from None
    finally:
        if path not in (None, "-"):
            source.close()


def _whole(reader, stream: _Prepend, name: str) -> Iterator[pa.RecordBatch]:
    """The stream's batches, then an error if it ended without its end-of-stream marker."""
    yield from reader
    if not stream.ended():
        raise InputError(f"{name}: {TRUNCATED}")


def _describe(error: Exception) -> str:
    text = str(error).splitlines()[0] if str(error) else type(error).__name__
    lowered = text.lower()
    # "bytes available": a stream cut inside its end-of-stream marker ("only 3 bytes available")
    if any(word in lowered for word in ("expected to", "end of stream", "truncated", "eof", "too short", "bytes available")):
        return TRUNCATED
    if "was null or length 0" in text:  # a second end-of-stream marker where a schema was expected
        return "the stream holds an end marker where its schema should be (two streams written into one file?)"
    if "Parquet magic bytes not found" in text or "footer" in text.lower():
        return "Parquet file is cut short or damaged (its footer is missing)"
    return f"cannot read table ({text})"


def _guard(batches: Iterable[pa.RecordBatch], name: str, schema: pa.Schema | None = None) -> Iterator[pa.RecordBatch]:
    try:
        for batch in batches:
            if schema is not None and batch.schema.metadata != schema.metadata:
                batch = pa.RecordBatch.from_arrays(batch.columns, schema=schema)
            yield batch
    except (pa.ArrowInvalid, pa.ArrowIOError, OSError, pa.ArrowNotImplementedError) as error:
        raise InputError(f"{name}: {_describe(error)}") from None


@dataclass
class Input:
    """The tables on the command line, read lazily as one: schema (with merged metadata) and batches."""

    schema: pa.Schema
    batches: Iterator[pa.RecordBatch]
    kind: str | None

    def read_all(self) -> pa.Table:
        return pa.Table.from_batches(list(self.batches), schema=self.schema)


def open_input(paths, kind=None, allow_empty=False) -> Input:
    """Open the inputs as one table. `kind` (str or tuple) is checked at the door.

    Several paths are opened up front, so their kinds, sensors and histories are checked before
    any batch flows; tables concatenated on one pipe are checked as they arrive.
    """
    paths = list(paths) or ["-"]
    opened = []
    for path in paths:
        tables = _source_batches(path)
        try:
            opened.append((next(tables), tables))
        except StopIteration:
            raise InputError(f"{path}: no table in it") from None
    return _checked_input(opened, paths, kind, allow_empty)


def open_table(table: pa.Table, kind=None, allow_empty=False) -> Input:
    """A table in memory (the Python API's input) checked as `open_input` checks a file at the door:
    header, kind, columns, nulls, a trial or frame given twice, no rows."""
    return _checked_input([((table.schema, iter(table.to_batches())), iter(()))], [], kind, allow_empty)


def _checked_input(opened: list, paths: list, kind, allow_empty: bool) -> Input:
    """The opened tables ((schema, batches), further tables on the same source) as one checked Input."""
    for (other, _), _ in opened:
        sch.check_header(other)
    (schema, first_batches), first_rest = opened[0]
    schema, first_batches = bridges.accept(schema, first_batches)  # DuckDB/Polars/evlib layouts
    opened[0] = ((schema, first_batches), first_rest)
    found = sch.validate(schema, kind) if kind else sch.table_kind(schema)
    if not kind and found in sch.REQUIRED:
        sch.validate(schema, found)  # a table that says what it is, but lacks its columns
    if found and sch.kind_of(schema) is None:
        schema = sch.set_meta(schema, kind=found)
    if found in sch.REQUIRED:
        schema = sch.conform_schema(schema, found)
    for (other, _), _ in opened[1:]:
        _check_compatible(schema, bridges.accept(other)[0], found)
    if len(opened) > 1:
        histories = [sch.get_meta(other, sch.HISTORY, []) for (other, _), _ in opened]
        if any(h != histories[0] for h in histories[1:]):
            schema = sch.set_meta(schema, history=[{"command": "concat", "args": {"inputs": histories}, "version": __version__}])

    unique = sch.UniqueRows(found if kind else None)  # commands that group by trial; `info` only describes

    def batches():
        count = 0
        for (_, first), rest in opened:
            for batch in _conformed(first, schema, found):
                unique.check(batch)
                count += batch.num_rows
                yield batch
            for other, more in rest:
                sch.check_header(other)
                _check_compatible(schema, bridges.accept(other)[0], found)
                for batch in _conformed(more, schema, found):
                    unique.check(batch)
                    count += batch.num_rows
                    yield batch
        if count == 0 and not allow_empty:
            named = ", ".join(path for path in paths if path != "-")
            raise InputError(f"{named + ': ' if named else ''}input {found + ' table' if found else 'table'} has no rows "
                             "(an empty recording, or the command before it failed)")

    return Input(schema=schema, batches=batches(), kind=found)


def _conformed(batches, schema: pa.Schema, kind: str | None):
    rows = 0
    for batch in batches:
        batch, rows = bridges.conform_batch(batch, schema, rows), rows + batch.num_rows
        if kind in sch.REQUIRED:
            batch = sch.conform(batch, kind)
        if not batch.schema.equals(schema, check_metadata=False):
            batch = _align(batch, schema)
        yield pa.RecordBatch.from_arrays(batch.columns, schema=_conformed_schema(schema, batch))


def _conformed_schema(schema: pa.Schema, batch: pa.RecordBatch) -> pa.Schema:
    if batch.schema.equals(schema, check_metadata=False):
        return schema
    return batch.schema.with_metadata(schema.metadata)


def _align(batch: pa.RecordBatch, schema: pa.Schema) -> pa.RecordBatch:
    if set(batch.schema.names) != set(schema.names):
        raise SchemaError(
            f"input tables have different columns ({', '.join(schema.names)} vs {', '.join(batch.schema.names)})"
        )
    try:
        return pa.RecordBatch.from_arrays([batch.column(name).cast(schema.field(name).type) for name in schema.names], schema=schema)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as error:
        raise SchemaError(f"input tables have different column types ({error})") from None


def _check_compatible(first: pa.Schema, other: pa.Schema, kind):
    other_kind = sch.table_kind(other)
    if kind and other_kind != kind:
        raise SchemaError(f"cannot read a {other_kind} table after a {kind} table as one input")
    a, b = sch.sensor_of(first), sch.sensor_of(other)
    if a and b and a != b:
        raise SchemaError(f"input tables have different sensor sizes ({a[0]}x{a[1]} vs {b[0]}x{b[1]}); crop them alike first")
    windows = sch.unlike_windows(first, other)
    if windows:
        shown = [f"{w} µs" if w else "no recorded window" for w in windows]
        raise SchemaError(f"input frames have different windows ({shown[0]} vs {shown[1]}); frame them alike with `neurotac frame --window`")


def read(paths, kind=None, allow_empty=False) -> pa.Table:
    """Read all inputs into one table (validated as `kind`)."""
    return open_input(paths, kind, allow_empty).read_all()


# ---------------------------------------------------------------- writing


def history_entry(command: str, args: dict) -> dict:
    return {"command": command, "args": dict(args), "version": __version__}


def with_step(schema: pa.Schema, step) -> pa.Schema:
    """Append the history entry `step = (command, args)` to the schema's metadata."""
    if step is None:
        return schema
    command, args = step
    history = list(sch.get_meta(schema, sch.HISTORY, []))
    history.append(history_entry(command, args))
    return sch.set_meta(schema, history=history)


def refuse_terminal():
    if is_terminal(sys.stdout):
        raise NeurotacError(
            "refusing to write a binary Arrow table to a terminal (pipe it into another command, "
            "e.g. `| neurotac info -`, or write a file with -o out.parquet)"
        )


def is_special(path: str) -> bool:
    """An existing path that is not a regular file or folder: a pipe (a shell's `>(...)`, a FIFO),
    /dev/stdout or /dev/null. It is written straight through, with the stream stdout gets (CSV or
    JSON where its suffix names them)."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def open_special(path: str):
    """A pipe or device (`is_special`) opened for writing. A FIFO is opened once a reader has it open,
    waited for here: a plain open waits in the kernel, where a Ctrl-C handler that lets the first
    press pass (a verb reading a pipe, a live import) restarts it, so no Ctrl-C would ever end it."""
    import time

    if not stat.S_ISFIFO(os.stat(path).st_mode):
        return open(path, "wb")
    while True:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            break
        except OSError as error:
            if error.errno != errno.ENXIO:  # ENXIO: no reader yet
                raise
        time.sleep(0.05)
    os.set_blocking(fd, True)
    return os.fdopen(fd, "wb")


def output_format(path: str) -> str:
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in SUFFIXES:
        if is_special(path):
            return "stream"
        raise NeurotacError(f"cannot tell the format of {path!r} from its suffix (use .parquet, .arrow, .feather or .arrows; .csv, .json or .ndjson for tables without tensors)")
    return SUFFIXES[suffix]


def check_not_inputs(inputs, **outputs) -> None:
    """A side output (`--metrics`, `--train`, a training's curve) that is one of the input files would
    replace the data read with a table of another kind: refused before the work. (`-o` over its own
    input is a command run in place, and allowed.) `outputs`: option name (underscores for dashes) -> path."""
    files = [path for path in inputs if path not in (None, "-") and os.path.isfile(path)]
    for option, path in outputs.items():
        if path in (None, "-") or not os.path.isfile(path):
            continue
        for source in files:
            if os.path.samefile(path, source):
                raise UsageError(f"--{option.replace('_', '-')} {path} is also an input: writing it would replace the data "
                                 "read; give it another path")


def check_folder(*paths) -> None:
    """One clear error if the folder of any of `paths` does not exist, or if two of them name one
    file, where the last written would silently replace the other (a command that runs for minutes
    checks its outputs first, so its work is not lost at the end)."""
    seen = {}
    for path in paths:
        if path == "":  # an unset shell variable: found now, not after the work, when the write fails
            raise UsageError(empty_path("output"))
        if path == "-" or path == os.devnull:  # not files in a folder: /dev/null takes any number of outputs
            continue
        # the folder resolved, the name not: a write renames over a link named here, not its target
        real = os.path.join(os.path.realpath(os.path.dirname(os.path.abspath(path))), os.path.basename(path))
        if real in seen:
            raise UsageError(f"two outputs name one file ({seen[real]} and {path}): the second would replace the first; "
                             "give each its own path")
        seen[real] = path
    for path in paths:
        if path == "-":  # stdout: the working folder need not be writable
            continue
        directory = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(directory):
            above = next((folder for folder in _folders_up(directory) if os.path.exists(folder)), directory)
            if not os.path.isdir(above):  # `file.txt/out.parquet`: saying the folder is missing would send one to make it
                raise NeurotacError(f"cannot write {path}: {above} is a file, not a folder; give a path in a folder")
            raise NeurotacError(f"cannot write {path}: folder {directory} does not exist")
        # a pipe or device is written where it is (a shell's >(...) lies in /proc, in no folder one writes in)
        if not is_special(path) and not os.access(directory, os.W_OK | os.X_OK):
            read_only = os.statvfs(directory).f_flag & os.ST_RDONLY
            raise OutputError.from_os(path, OSError(errno.EROFS if read_only else errno.EACCES, "cannot write"))
        if len(os.fsencode(os.path.basename(path))) > _longest_name(directory):  # else found at the rename, after the work
            raise OutputError.from_os(path, OSError(errno.ENAMETOOLONG, "name too long"))


def _longest_name(directory: str) -> int:
    """The longest file name, in bytes, the folder's file system takes (255 on most)."""
    try:
        longest = os.pathconf(directory, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255
    return longest if longest > 0 else 255  # -1: the file system states no limit


def _folders_up(directory: str) -> Iterator[str]:
    """`directory` and each folder above it, nearest first."""
    while True:
        yield directory
        parent = os.path.dirname(directory)
        if parent == directory:
            return
        directory = parent


@contextmanager
def atomic_file(path: str):
    """A temporary file beside `path` to write into: it replaces `path` when the block ends without
    an error and is removed when it fails, so a failed run never leaves a half-written file that
    looks whole and an existing `path` is kept. It gets the permissions a file the shell creates
    gets (mkstemp's are 0600). A missing, full, read-only or vanished folder is one clear error.
    A pipe or device (`is_special`: /dev/null, a shell's `>(...)`) is never renamed over: the
    finished file's bytes are copied into it, and the temporary file sits in the temporary folder
    (the device's folder, /dev, is not one to write in). Within `together()` the replacing waits
    for the end of that block."""
    check_folder(path)
    special = is_special(path)
    folder = tempfile.gettempdir() if special else os.path.dirname(os.path.abspath(path))
    try:
        handle, temporary = tempfile.mkstemp(prefix=".neurotac-", suffix=".part", dir=folder)
    except OSError as error:
        raise OutputError.from_os(path, error) from None
    os.close(handle)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temporary, 0o666 & ~umask)
    held = False
    try:
        yield temporary
        finish = _Finish(path, temporary, special, umask, folder)
        if _held is not None:
            _held.append(finish)
            held = True
        else:
            finish()
    except OSError as error:
        raise _output_error(error, path, folder) from None
    finally:
        if not held and os.path.exists(temporary):
            os.unlink(temporary)


def _output_error(error: OSError, path: str, folder: str) -> Exception:
    """An error of writing `path` as its one line; any other (the block also pulls the input) as it is."""
    if error.errno not in OutputError.WHY or (error.errno == errno.ENOENT and os.path.isdir(folder)):
        return error
    return OutputError.from_os(path, error, kept=os.path.exists(path))


@dataclass
class _Finish:
    """What puts a finished temporary file in its place: renamed over `path`, or copied into a pipe."""

    path: str
    temporary: str
    special: bool
    umask: int
    folder: str

    def __call__(self):
        if self.special:
            import shutil

            with open(self.temporary, "rb") as finished, open_special(self.path) as sink:
                shutil.copyfileobj(finished, sink)
        else:
            os.chmod(self.temporary, 0o666 & ~self.umask)  # again: writers that replace the file (safetensors) make it 0600
            os.replace(self.temporary, self.path)


_held: list[_Finish] | None = None  # within `together()`: the outputs finished and not yet put in place


@contextmanager
def together():
    """The outputs of one run (`atomic_file`, so every `write` to a path) put in place together: each
    is finished into its temporary file, and all are renamed when the block ends without an error,
    none when it fails in the block (a rename failing among the renames at its end, which a written
    temporary in the output's own folder hardly does, leaves those before it in place). One output replaced and the next not mixes runs: a split's training table new
    and its test table old puts a trial on both sides; metrics of this run beside a plot of the last.
    A reader of stdout that went away is success (cli.py): the files are put in place then too.
    A block within a block is part of the outer one."""
    global _held
    if _held is not None:
        yield
        return
    _held = []
    try:
        yield
    except BrokenPipeError:
        _put_in_place(_release())
        raise
    except BaseException:
        for finish in _release():
            if os.path.exists(finish.temporary):
                os.unlink(finish.temporary)
        raise
    _put_in_place(_release())


def _release() -> list[_Finish]:
    global _held
    held, _held = _held, None
    return held


def _put_in_place(held: list[_Finish]):
    """Files renamed first (a rename hardly fails once its temporary is written), pipes last; a pipe
    whose reader went away does not keep the outputs after it from their places."""
    gone = None
    try:
        for finish in sorted(held, key=lambda finish: finish.special):
            try:
                finish()
            except BrokenPipeError as error:
                gone = error
            except OSError as error:
                raise _output_error(error, finish.path, finish.folder) from None
        if gone is not None:
            raise gone
    finally:
        for finish in held:
            if os.path.exists(finish.temporary):
                os.unlink(finish.temporary)


def write(output: str | None, data, step=None, schema: pa.Schema | None = None, flush_each: bool = False):
    """Write a table, or an iterable of record batches with `schema`, to `output` (None = stdout).

    `step = (command, args)` is appended to the history. With an iterable, batches are written
    as they come, so memory does not grow with the input; `flush_each` hands each batch on stdout
    or a pipe to the reader at once (a live stream) rather than when the pipe's buffer fills (a
    file is written whole either way).
    """
    if isinstance(data, pa.Table):
        schema = data.schema
        batches: Iterable[pa.RecordBatch] = data.to_batches()
    else:
        if schema is None:
            raise ValueError("write() needs a schema for a batch iterable")
        batches = data
    schema = with_step(schema, step)
    if output in (None, "-"):
        refuse_terminal()
        _write_stream(getattr(sys.stdout, "buffer", sys.stdout), schema, batches, flush_each)
        return
    fmt = output_format(output)
    if is_special(output) and fmt not in ("csv", "json", "ndjson"):
        # a pipe cannot seek, which Parquet and the Arrow file need: it gets stdout's stream,
        # which every neurotac command reads whatever the name says
        try:
            handle = open_special(output)
        except OSError as error:
            raise OutputError.from_os(output, error) from None
        with handle:
            _write_stream(handle, schema, batches, flush_each)
        return
    with atomic_file(output) as temporary:
        if fmt in ("csv", "json", "ndjson"):
            from neurotac_cli.textout import write_text

            write_text(temporary, fmt, schema, batches)
        elif fmt == "parquet":
            import pyarrow.parquet as pq

            writer = pq.ParquetWriter(temporary, schema, compression="zstd")
            for batch in batches:
                writer.write_batch(_with_schema(batch, schema))
            writer.close()
        else:
            with pa.OSFile(temporary, "wb") as sink:
                writer = (ipc.new_file if fmt == "file" else ipc.new_stream)(sink, schema)
                for batch in batches:
                    writer.write_batch(_with_schema(batch, schema))
                writer.close()


STREAM_BUFFER = 1 << 16  # bytes: a frame of 115x115 counts with its columns fits, and leaves in one write


def _write_stream(raw, schema: pa.Schema, batches, flush_each: bool):
    """The Arrow IPC stream, which needs no seeking, into a binary file object (stdout, a pipe)."""
    sink = _WholeWrites(raw)
    writer = ipc.new_stream(sink, schema)
    for batch in batches:
        writer.write_batch(_with_schema(batch, schema))
        if flush_each:
            sink.flush()
    writer.close()
    sink.flush()


class _WholeWrites:
    """stdout for Arrow's writer, each write carried to its last byte (`whole.write_whole`): Arrow
    takes every write as whole, so a pipe's write that a signal interrupts (the Ctrl-C a live pipe
    ends on, whose handler only asks the stream to stop) or a full non-blocking stdout would end the
    stream mid-table.

    An unbuffered stdout (PYTHONUNBUFFERED, which many containers set) is buffered here: Arrow writes
    a batch in a score of pieces (its metadata, each buffer, the padding), and a system call for each
    would wake the reader at the pipe's other end as often; a batch leaves in one write when flushed."""

    def __init__(self, sink):
        self.sink, self.position = sink, 0
        self.pending = bytearray() if isinstance(sink, io.RawIOBase) else None

    @property
    def closed(self) -> bool:
        return self.sink.closed

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        size = len(view)
        if self.pending is None:
            write_whole(self.sink, view)
        else:
            self.pending += view
            if len(self.pending) >= STREAM_BUFFER:
                self._drain()
        self.position += size
        return size

    def _drain(self):
        if self.pending:
            pending, self.pending = self.pending, bytearray()
            write_whole(self.sink, memoryview(pending))

    def flush(self):
        if self.pending is not None:
            self._drain()
        flush_whole(self.sink)

    def tell(self) -> int:
        return self.position


def _with_schema(batch: pa.RecordBatch, schema: pa.Schema) -> pa.RecordBatch:
    if batch.schema.equals(schema, check_metadata=True):
        return batch
    try:
        return pa.RecordBatch.from_arrays(batch.columns, schema=schema)
    except (pa.ArrowInvalid, TypeError):
        raise SchemaError(f"internal: batch columns {batch.schema.names} do not match {schema.names}") from None
