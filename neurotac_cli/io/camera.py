"""Camera files in: sniff the format, decode in chunks, hand out `events` record batches.

Every format module exposes `open_<format>(path, head, sensor) -> Decoded`: the sensor the file
declares (or None), a function that yields (t, x, y, p) numpy chunks from the start of the data
(callable again for a second pass), and extra metadata (AEDAT4 triggers). This module turns them
into Arrow batches with the `events` schema, checks coordinates against the sensor, and turns every
low-level decoding failure into one `FormatError` line.
"""

import codecs
import ctypes
import os
import shutil
import sys
import tempfile
from typing import Callable, Iterator

import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import FormatError, InputError, NeurotacError, OutputError, SchemaError, cannot_open
from neurotac_cli.io import reader
from neurotac_cli.io.hdf5 import SIGNATURE as HDF5_SIGNATURE, is_hdf5
from neurotac_cli.io.reader import Decoded
from neurotac_cli.io.readers import OPENERS
from neurotac_cli.io.text import BOM
from neurotac_cli.provenance import file_sha256
from neurotac_cli.tables import is_terminal
from neurotac_cli.units import MAX_SIDE

# A file cut inside one of these is named as cut, not read as text that holds no rows.
SIGNATURES = ((b"#!AER-DAT", "AEDAT"), (b"Event Stream", "Event Stream"), (HDF5_SIGNATURE, "HDF5"))

FORMATS = ("aedat2", "aedat3", "aedat4", "evt2", "evt21", "evt3", "dat", "es", "csv", "text", "hdf5")
FORMAT_NAMES = {
    "aedat2": "AEDAT 2.0 (jAER)",
    "aedat3": "AEDAT 3.1 (cAER)",
    "aedat4": "AEDAT 4.0",
    "evt2": "Prophesee EVT 2.0 raw",
    "evt21": "Prophesee EVT 2.1 raw",
    "evt3": "Prophesee EVT 3.0 raw",
    "dat": "Prophesee DAT",
    "es": "Event Stream",
    "csv": "CSV text (t,x,y,p)",
    "text": "whitespace text (t x y p, seconds)",
    "hdf5": "HDF5 events",
}


def _keep_decoded_chunks_on_the_heap():
    """glibc hands blocks above its mmap threshold straight back to the OS when freed, and trims the
    heap top above its trim threshold, so decoding chunk after chunk (each chunk's output freed once
    written) page-faults every output afresh, which on a small file costs several times the decoding
    itself (docs/design.md, "Allocator thresholds"). A fixed 32 MiB mmap threshold and a 128 MiB trim
    threshold keep chunk-sized blocks for reuse. Linux/glibc only; elsewhere nothing changes."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD
        libc.mallopt(-1, 128 << 20)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError):
        pass


_keep_decoded_chunks_on_the_heap()


def trial_name(path) -> str:
    """A recording's default trial id: its file name without the suffix, and without an EVT marker
    before `.raw` (`grasp.aedat4` -> `grasp`, `rec.evt3.raw` -> `rec`)."""
    stem, suffix = os.path.splitext(os.path.basename(str(path)))
    if suffix.lower() == ".raw" and os.path.splitext(stem)[1].lower() in (".evt2", ".evt21", ".evt3"):
        stem = os.path.splitext(stem)[0]
    return stem


def is_table(path) -> bool:
    """True when `path` holds an Arrow IPC stream, Arrow file or Parquet table (stdin counts as a table)."""
    if path in (None, "-"):
        return True
    try:
        with open(path, "rb") as handle:
            head = handle.read(8)
    except OSError:
        return False
    return head.startswith((b"\xff\xff\xff\xff", b"ARROW1", b"PAR1"))


def detect_format(path, head: bytes) -> str:
    """The camera format of a file from its first bytes (and, for Prophesee raw files, its header)."""
    name = os.path.basename(str(path))
    cut = next((label for magic, label in SIGNATURES if 3 <= len(head) <= len(magic) and magic.startswith(head)), None)
    if cut:
        raise FormatError(f"{name}: the file holds only {len(head)} bytes, the start of an {cut} file's signature (is it the whole file?)")
    if head.startswith(b"#!AER-DAT2") or head.startswith(b"#!AER-DAT1"):
        if head.startswith(b"#!AER-DAT1"):
            raise FormatError(f"{name}: AEDAT 1.0 is not supported (convert it to AEDAT 2.0 or 4.0 with jAER or dv)")
        return "aedat2"
    if head.startswith(b"#!AER-DAT3"):
        return "aedat3"
    if head.startswith(b"#!AER-DAT4"):
        return "aedat4"
    if head.startswith(b"Event Stream"):
        return "es"
    if head.startswith(b"#!AER-DAT"):
        version = (head[9:].split(maxsplit=1) or [b""])[0][:16].decode("latin-1")  # a damaged line may run on for kilobytes
        raise FormatError(f"{name}: AEDAT version {version!r} is not supported (AEDAT 2.0, 3.1 and 4.0 are)")
    if head.startswith(b"%"):
        header = _percent_header(head)
        if "evt" in header or "format" in header:
            version = (header.get("evt") or header.get("format", "")).upper().replace("EVT", "").split(";")[0].strip()
            if version in ("2.1", "21"):
                return "evt21"
            if version.startswith("3"):
                return "evt3"
            if version.startswith("2"):
                return "evt2"
            raise FormatError(f"{name}: Prophesee raw format {version!r} is not supported (EVT 2.0, 2.1 and 3.0 are)")
        if "version" in header or any("data file containing" in key for key in header) or name.lower().endswith(".dat"):
            return "dat"
        raise FormatError(f"{name}: a Prophesee header without an `evt` line (`neurotac import --format evt2`, evt21 or evt3 reads it)")
    if is_hdf5(head):
        return "hdf5"
    if head.startswith(b"\xff\xff\xff\xff") or head.startswith(b"ARROW1") or head.startswith(b"PAR1"):
        raise FormatError(f"{name} is already a table, not a camera file (use it directly, or `neurotac info {name}`)")
    if _looks_like_text(head.removeprefix(BOM)):
        first = first_data_line(head.removeprefix(BOM))
        if first.lstrip().startswith(("{", "[")):  # what `-o x.json`/`.ndjson` writes, for other tools to read
            raise FormatError(f"{name} is JSON text, which neurotac writes for other tools but does not read; "
                              "write the table with -o .parquet or .arrows (or .csv for events) to read it again")
        return "csv" if "," in first else "text"
    raise FormatError(
        f"{name}: unknown camera format (known: AEDAT 2.0/3.1/4.0, Prophesee EVT 2.0/2.1/3.0 .raw and .dat, "
        "Event Stream .es, HDF5 events, CSV t,x,y,p and text t x y p); `neurotac import --format` reads it as one of them, if it is"
    )


# formats whose files one decoder of the family could hold; --format may choose within a family
# (a Prophesee header that names the wrong EVT, text with or without commas), not across them
FAMILIES = {"evt2": "prophesee", "evt21": "prophesee", "evt3": "prophesee", "dat": "prophesee", "csv": "text", "text": "text"}


def chosen_format(name, head: bytes, fmt: str | None) -> str:
    """The format to decode a file as: `fmt` (--format) unless the first bytes say the file is of
    another family (every decoder turns any bytes into events: an AEDAT file read as EVT 3.0 gives
    hundreds of thousands of made-up events), else the one told from them."""
    if fmt is None:
        return detect_format(name, head)
    try:
        found = detect_format(name, head)
    except FormatError:  # nothing the first bytes say: --format is what it is there for
        return fmt
    if FAMILIES.get(found, found) != FAMILIES.get(fmt, fmt):
        raise FormatError(f"{os.path.basename(str(name))}: --format {fmt} reads it as {FORMAT_NAMES.get(fmt, fmt)}, "
                          f"but its first bytes are those of {FORMAT_NAMES[found]}; leave --format out")
    return fmt


def _percent_header(head: bytes) -> dict:
    """Prophesee `% key value` header lines as a dict (keys lowercased)."""
    header = {}
    for line in head.split(b"\n"):
        if not line.startswith(b"%"):
            break
        text = line[1:].decode("latin-1").strip()
        key, _, value = text.partition(" ")
        header[key.lower()] = value.strip()
        header[text.lower()] = ""
    return header


def _looks_like_text(head: bytes) -> bool:
    if not head:
        return False
    sample = head[:4096]
    try:  # UTF-8, not ASCII: a table written as CSV may hold labels such as "Stoßdämpfer"; a character cut at the end is left out
        text = codecs.getincrementaldecoder("utf-8")().decode(sample)
    except UnicodeDecodeError:
        return False
    return all(c.isprintable() or c in "\r\n\t" for c in text)


def first_data_line(head: bytes) -> str:
    """The first line of a text file's head that is neither blank nor a `#` comment ("" if none)."""
    for line in head.decode("ascii", "replace").splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            return line
    return ""


def _decoder(fmt: str):
    if fmt not in OPENERS:
        raise FormatError(f"unknown format {fmt!r} (known: {', '.join(FORMATS)})")
    return OPENERS[fmt]


def local_path(path) -> tuple[str, Callable[[], None]]:
    """A readable file path for `path`; stdin (`-`) is copied to a temporary file first."""
    if path not in (None, "-"):
        if os.path.isdir(path):
            raise InputError(f"{path} is a directory, not a file (give the camera files inside it)")
        if not os.path.exists(path):
            raise cannot_open(path, FileNotFoundError())
        if not os.access(path, os.R_OK):
            raise InputError(f"{path}: permission denied")
        return str(path), lambda: None
    source = getattr(sys.stdin, "buffer", sys.stdin)
    if source is None or is_terminal(source):
        raise InputError("no input: give a camera file, or pipe one into stdin")
    return temporary_copy(".neurotac-stdin-", "stdin", lambda sink: shutil.copyfileobj(source, sink, reader.CHUNK_BYTES),
                          "a camera file on stdin is copied whole before it is read: set TMPDIR to a folder with room, "
                          "or give the file's path")


def temporary_copy(prefix: str, name: str, fill: Callable, advice: str) -> tuple[str, Callable[[], None]]:
    """A temporary file that `fill(sink)` writes, and what removes it. A copy cut short (a second Ctrl-C,
    a full disk: an endless pipe fills it) must not stay behind; a disk that refuses it is one line
    naming the folder and `advice`."""
    handle, temporary = tempfile.mkstemp(prefix=prefix)
    remove = removal(temporary)
    try:
        with os.fdopen(handle, "wb") as sink:
            fill(sink)
    except BaseException as error:
        remove()
        if isinstance(error, OSError) and error.errno in OutputError.WHY:
            why, _ = OutputError.why(error)
            raise InputError(f"{name}: cannot copy it to {os.path.dirname(temporary)} ({why}); {advice}") from None
        raise
    return temporary, remove


def removal(temporary: str) -> Callable[[], None]:
    """What removes a temporary copy of an input: called when its reading ends, and at exit as well,
    since the events' generator holds that call in a `finally` that never runs if the generator never
    starts (an output refused before the first batch)."""
    import atexit

    def remove():
        if os.path.exists(temporary):
            os.unlink(temporary)

    atexit.register(remove)
    return remove


def read_local(local: str, name: str, sensor=None, fmt: str | None = None, cleanup=lambda: None):
    """`read_events` of a local file shown to the user as `name`; `cleanup` runs once it is read."""
    try:
        if os.path.getsize(local) == 0:
            raise InputError(f"{name} is empty (0 bytes); is it the right file?")
        with open(local, "rb") as handle:
            head = handle.read(1 << 16)
        fmt = chosen_format(name, head, fmt)
        if sensor is not None:
            sensor = (int(sensor[0]), int(sensor[1]))
        decoded = _guarded_call(name, fmt, lambda: _decoder(fmt)(local, head, sensor))
        declared = sensor or _guarded_call(name, fmt, lambda: reader.check_sensor(decoded.sensor))
        source = "option" if sensor else ("file" if decoded.sensor else "events")
        if declared is None:
            declared = _extent(name, fmt, decoded)
    except BaseException:
        cleanup()
        raise
    schema = sch.events_schema(*declared)
    entries = {"source": {"format": fmt, "file": name, "sensor_from": source, "sha256": file_sha256(local),
                          **decoded.meta.pop("source", {})}}
    if decoded.cut_bytes:
        entries["source"]["cut_bytes"] = decoded.cut_bytes
    entries.update(decoded.meta)
    schema = sch.set_meta(schema, **entries)
    return schema, _batches(name, fmt, decoded, declared, schema, cleanup)


def _extent(name: str, fmt: str, decoded: Decoded) -> tuple[int, int]:
    """The sensor of a file that does not say: the smallest one holding every event (a first pass)."""
    width = height = 0
    for t, x, y, p in _guarded(name, fmt, decoded.chunks()):
        if len(x):
            width = max(width, int(x.max()) + 1)
            height = max(height, int(y.max()) + 1)
    if max(width, height) > MAX_SIDE:  # a coordinate of 65535 is past the last pixel of the largest sensor a table holds
        raise FormatError(f"{name}: an event at {'x' if width > MAX_SIDE else 'y'} = {MAX_SIDE} would need a sensor "
                          f"{MAX_SIDE + 1} pixels wide, past the {MAX_SIDE} a side that tables hold; the file is damaged, or "
                          "its coordinates need an offset removed")
    return max(width, 1), max(height, 1)


def _batches(name, fmt, decoded: Decoded, sensor, schema, cleanup) -> Iterator[pa.RecordBatch]:
    width, height = sensor
    try:
        for t, x, y, p in _guarded(name, fmt, decoded.chunks()):
            if not len(t):
                continue
            check_inside(name, x, y, width, height, "file")
            yield sch.events_batch(t, x, y, p, schema)
    finally:
        cleanup()


def check_inside(name, x, y, width: int, height: int, what: str) -> None:
    """Refuse a chunk with events outside the sensor: the `what` (file, stream) is damaged, or its size wrong."""
    try:
        sch.check_inside(x, y, (width, height), advice=f"the {what} is damaged, or give the right size with --sensor WxH")
    except SchemaError as error:
        raise FormatError(f"{name}: {error}") from None


def _named(name: str, error: NeurotacError) -> NeurotacError:
    """The error with the file's name in front, once."""
    text = str(error)
    return error if text.startswith(name) else type(error)(f"{name}: {text}")


def _guarded_call(name, fmt, function):
    try:
        return function()
    except NeurotacError as error:
        raise _named(name, error) from None
    except (ValueError, IndexError, OverflowError, KeyError, OSError, RuntimeError, UnicodeError, TypeError) as error:
        raise FormatError(f"{name}: not a valid {FORMAT_NAMES.get(fmt, fmt)} file ({_short(error)})") from None


def _guarded(name, fmt, chunks):
    iterator = iter(chunks)
    while True:
        try:
            chunk = next(iterator)
        except StopIteration:
            return
        except NeurotacError as error:
            raise _named(name, error) from None
        except (ValueError, IndexError, OverflowError, KeyError, OSError, RuntimeError, UnicodeError, TypeError) as error:
            raise FormatError(f"{name}: not a valid {FORMAT_NAMES.get(fmt, fmt)} file ({_short(error)})") from None
        yield chunk


def _short(error: Exception) -> str:
    text = str(error).strip().splitlines()
    return text[0][:200] if text else type(error).__name__




def camera_file_stem(schema) -> str | None:
    """The trial id of the single camera file `import` recorded (`rec.evt3.raw` -> `rec`), if any."""
    name = sch.camera_source(schema).get("file")
    return trial_name(name) if name else None
