"""Camera bytes as they arrive: a recording still being written (`--follow`), a pipe, a FIFO, stdin;
and a finished recording replayed at its recorded speed.

AEDAT 4.0, EVT 3.0, EVT 2.1, EVT 2.0, AEDAT 2.0, Event Stream and DAT are read front to back, so they are
decoded as their bytes arrive: each read's whole records become one batch, and a record cut by the
read (a writer caught mid-record) waits in a buffer for its rest. The decoders are the ones files use
(the compiled word kernels with their state carried across reads; AEDAT 4.0 packets through the
`aedat` library, one read's whole packets at a time), so a stream gives the same events as the file.

What a stream cannot give: metadata that depends on the whole recording. The sensor of a text or DAT
file that does not declare it (a pass over every event) and external triggers (written into the
schema, which goes out before the first event) are such. Text, and a DAT without a size, piped in
without --sensor, are copied to a temporary file and read whole; a followed file refuses them; the
triggers of a stream are counted in a note instead of kept.
"""

import os
import select
import stat
import struct
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import FormatError, InputError, cannot_open
from neurotac_cli.io.reader import check_sensor

STREAMED = ("aedat4", "evt3", "evt2", "evt21", "aedat2", "aedat3", "es", "dat")
POLL_S = 0.0002  # a followed file is checked for new bytes this often while it grows (a pipe wakes the reader itself):
# a camera writes every millisecond or so, and the poll's wait is part of every window's latency
IDLE_POLL_S = 0.002  # ... and this often once nothing has arrived for IDLE_AFTER_S (a fifth of the CPU time)
IDLE_AFTER_S = 0.1
WAKE_S = 0.05  # a reader blocked on a pipe looks at the stop request this often
READ_BYTES = 1 << 20  # at most this much is decoded into one batch
TAIL_BYTES = 64  # a followed file's last bytes read, compared before each read to find a rewrite
REWRITE_FROM = 4096  # bytes: past every format's header, which some writers update in place at the end
SNIFF_BYTES = 1 << 16
REPLAY_SLICE_US = 1000  # a replay releases the events of each millisecond of camera time together


@dataclass
class Stream:
    """An events table being read: its schema, its batches (lazily), and notes for the user (things
    the stream could not keep), filled in as the batches are read."""

    schema: pa.Schema
    batches: Iterator[pa.RecordBatch]
    notes: list = field(default_factory=list)
    rows: int = 0  # events read so far (by `io.events.import_events`'s batches)


def is_stream(path) -> bool:
    """Whether `path` (`-` = stdin) is a pipe, FIFO or other input that can be read only once, front to back."""
    try:
        if path in (None, "-"):
            if sys.stdin is None:
                return False
            mode = os.fstat(sys.stdin.fileno()).st_mode
        else:
            mode = os.stat(path).st_mode
    except (OSError, ValueError, AttributeError):
        return False
    return not stat.S_ISREG(mode) and not stat.S_ISDIR(mode)


class Feed:
    """The new bytes of a file being written, a pipe or stdin.

    `read()` gives the bytes that arrived (b"" when none did yet) and None at the end: the end of a
    pipe; the end of a regular file unless followed; for a followed file or pipe, no new byte for
    `idle_timeout` seconds; or `stop()` turning true.
    """

    def __init__(self, fd: int, follow: bool = False, idle_timeout: float = 2.0, stop: Callable[[], bool] = lambda: False,
                 path=None):
        self.fd, self.follow, self.idle_timeout, self.stop, self.path = fd, follow, idle_timeout, stop, path
        self.regular = stat.S_ISREG(os.fstat(fd).st_mode)
        self.last = time.monotonic()
        self.ended = False
        self.shrunk = None  # (bytes read, bytes left) where a followed file was cut shorter while read
        self.rewritten = False  # a followed file's bytes already read changed under the offset
        self.tail = b""  # the last bytes read from a followed file, checked before each read
        self.replaced = False  # a followed file's name came to name another file (one renamed over it)
        # every read lands in this one buffer: os.read(fd, READ_BYTES) asks malloc for READ_BYTES each
        # time and shrinks it to the few kB that came; glibc carves those requests out of its heap, and
        # the holes they leave, each a little short of the next request, make a live import's memory
        # grow for as long as it runs
        self.chunk = bytearray(READ_BYTES)

    def read(self) -> bytes | None:
        if self.ended or self.stop():
            return None
        if self.regular:
            if self.follow and self._rewritten():
                self.rewritten, self.ended = True, True
                return None
            data = self._read()
            if not data and self.follow:
                # a file cut shorter than what was read (rewritten, or truncated to start afresh) would
                # never grow past the offset again: its new bytes must not be waited for in silence
                mine = os.fstat(self.fd)
                at = os.lseek(self.fd, 0, os.SEEK_CUR)
                if mine.st_size < at:
                    self.shrunk, self.ended = (at, mine.st_size), True
                    return None
                idle = time.monotonic() - self.last >= IDLE_AFTER_S
                if idle and self._replaced(mine):  # a file renamed over this one stops it growing: looked for once idle
                    self.replaced, self.ended = True, True
                    return None
                time.sleep(IDLE_POLL_S if idle else POLL_S)
        else:
            ready, _, _ = select.select([self.fd], [], [], WAKE_S)
            data = self._read() if ready else b""
            if ready and not data:
                self.ended = True
                return None
        now = time.monotonic()
        if data:
            self.last = now
            return data
        if not self.follow and self.regular:
            self.ended = True
            return None
        if self.follow and now - self.last >= self.idle_timeout:
            self.ended = True
            return None
        return b""

    def _replaced(self, mine: os.stat_result) -> bool:
        """True when the followed name now names another file than `mine` (the open one's stat): the
        open one will never grow again, and the new one's bytes would not be read. A name gone
        (renamed away, the camera still writing through it) is followed on."""
        if self.path in (None, "-"):
            return False
        try:
            named = os.stat(self.path)
        except OSError:
            return False
        return (named.st_ino, named.st_dev) != (mine.st_ino, mine.st_dev)

    def _rewritten(self) -> bool:
        """True when the bytes just before the offset are no longer those read there: the file was
        truncated and written again past the offset between two polls, which its size alone shows as
        growth (the new recording's middle would be decoded as the old one's continuation). Looked at
        past the first 4 KiB only, where a writer that updates its header in place does not write."""
        if len(self.tail) < TAIL_BYTES:
            return False
        at = os.lseek(self.fd, 0, os.SEEK_CUR)
        if at - TAIL_BYTES < REWRITE_FROM:
            return False
        there = os.pread(self.fd, TAIL_BYTES, at - TAIL_BYTES)
        return len(there) == TAIL_BYTES and there != self.tail  # fewer: the file shrank, said as such

    def _read(self) -> bytes:
        count = os.readv(self.fd, [self.chunk])
        data = bytes(memoryview(self.chunk)[:count])
        if self.follow and count:
            self.tail = data[-TAIL_BYTES:] if count >= TAIL_BYTES else (self.tail + data)[-TAIL_BYTES:]
        return data


def open_stream(path, sensor=None, fmt: str | None = None, follow: bool = False, idle_timeout: float = 2.0,
                stop: Callable[[], bool] = lambda: False) -> Stream:
    """An events stream from a pipe, stdin, or (`follow`) a file still being written.

    Blocks until the camera header has arrived. Formats that cannot be streamed are copied to a
    temporary file and read whole (a pipe), or refused (a followed file).
    """
    from neurotac_cli.io import camera

    name = "stdin" if path in (None, "-") else os.path.basename(str(path))
    if follow and path not in (None, "-"):
        _wait_for(path, idle_timeout, stop)
    fd, decoder = _open_fd(path, stop, name, idle_timeout if follow else None), None
    closed = []

    def close():
        """Once only: a second close of the number would close whatever file was opened on it since."""
        if not closed:
            closed.append(True)
            _close(fd, path)

    try:
        feed = Feed(fd, follow, idle_timeout, stop, path)
        buffer = _read_until(feed, bytearray(), lambda data, end: _sniffed(data, end))
        if stop() and not _sniffed(buffer, False):
            raise InputError(f"{name}: stopped before the camera header had arrived (no table to write)")
        if not buffer:
            waited = f" after waiting {idle_timeout:g} s" if follow else ""
            shown = name if path in (None, "-") else str(path)  # the path as given: /dev/null is not "null"
            raise InputError(f"{shown} is empty (0 bytes){waited}; is it the right file, and is the camera writing it?")
        fmt = camera.chosen_format(name, bytes(buffer[:SNIFF_BYTES]), fmt)
        if sensor is not None:
            sensor = (int(sensor[0]), int(sensor[1]))
        if fmt not in STREAMED:
            return _whole(name, fmt, feed, buffer, sensor, follow, close)
        buffer = _read_until(feed, buffer, lambda data, end: header_length(fmt, data, end) is not None)
        length = camera._guarded_call(name, fmt, lambda: header_length(fmt, buffer, True))
        header = bytes(buffer[:length])
        decoder = camera._guarded_call(name, fmt, lambda: _decoder(fmt, header, sensor))
        del buffer[:length]
        _settle(name, fmt, feed, buffer, decoder)
        declared = sensor or camera._guarded_call(name, fmt, lambda: check_sensor(decoder.sensor))
        if declared is None:
            decoder.close()
            decoder = None
            return _whole(name, fmt, feed, bytearray(header) + buffer, sensor, follow, close)
    except BaseException:
        if decoder is not None:  # AEDAT 4.0's keeps a temporary file
            decoder.close()
        close()
        raise
    schema = sch.events_schema(*declared)
    source = "option" if sensor else "file"
    entries = {"source": {"format": fmt, "file": name, "sensor_from": source, **decoder.meta.pop("source", {})}}
    schema = sch.set_meta(schema, **entries, **decoder.meta)
    stream = Stream(schema, iter(()))
    stream.batches = _batches(name, fmt, feed, buffer, decoder, declared, schema, stream.notes, close)
    return stream


def _settle(name, fmt, feed: Feed, pending: bytearray, decoder):
    """Read on until the decoder's metadata is complete, so that it goes out with the schema. An EVT 2.1
    stream whose header does not give its word order waits here for its first TIME_HIGH word (no event
    before that word can be decoded, so none is held back by the wait); an AEDAT 2.0 stream that names
    no chip, for the 16 records that tell DVS128 from DAVIS."""
    from neurotac_cli.io import camera

    while not camera._guarded_call(name, fmt, lambda: decoder.settled(pending, False)):
        data = feed.read()
        if data is None:
            camera._guarded_call(name, fmt, lambda: decoder.settled(pending, True))
            return
        pending += data


def _wait_for(path, idle_timeout: float, stop: Callable[[], bool]):
    """A followed file that does not exist yet is waited for up to `idle_timeout`: the pipe may be
    started before the camera's recorder creates its file."""
    if os.path.lexists(path):
        return
    end = time.monotonic() + idle_timeout
    while not os.path.lexists(path):
        if stop():
            raise InputError(f"{path}: stopped before the file appeared (no table to write)")
        if time.monotonic() >= end:
            raise InputError(f"{path}: no such file after waiting {idle_timeout:g} s (--idle-timeout); "
                             "is the camera writing it, and is the path right?")
        time.sleep(IDLE_POLL_S)


def _open_fd(path, stop: Callable[[], bool] = lambda: False, name: str = "", idle_timeout: float | None = None) -> int:
    if path in (None, "-"):
        from neurotac_cli.tables import is_terminal

        if sys.stdin is None or is_terminal(sys.stdin):
            raise InputError("no input: give a camera file, or pipe one into stdin")
        return sys.stdin.fileno()
    if os.path.isdir(path):
        raise InputError(f"{path} is a directory, not a file (give the camera files inside it)")
    try:
        if sys.platform.startswith("linux") and stat.S_ISFIFO(os.stat(path).st_mode):
            return _open_fifo(path, stop, name or str(path), idle_timeout)
        return os.open(path, os.O_RDONLY)
    except OSError as error:
        raise cannot_open(path, error) from None


def _open_fifo(path, stop: Callable[[], bool], name: str, idle_timeout: float | None = None) -> int:
    """A FIFO, once a writer has opened it (given up after `idle_timeout` s, where followed). A plain
    open blocks in the kernel until then, and the stop request's handler restarts it there
    (SA_RESTART), so Ctrl-C and SIGTERM would never end an import of a FIFO nobody writes to. Opened
    without blocking, it is waited on here instead: Linux reports such a FIFO neither readable nor
    hung up until a writer comes."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    deadline = None if idle_timeout is None else time.monotonic() + idle_timeout
    try:
        while not select.select([fd], [], [], WAKE_S)[0]:
            if stop():
                raise InputError(f"{name}: stopped before anything wrote into the FIFO (no table to write)")
            if deadline is not None and time.monotonic() > deadline:
                raise InputError(f"{name}: nothing was written into the FIFO in {idle_timeout:g} s (--idle-timeout); "
                                 "is the camera writing it?")
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _close(fd: int, path):
    if path not in (None, "-"):
        try:
            os.close(fd)
        except OSError:
            pass


def _read_until(feed: Feed, buffer: bytearray, done: Callable[[bytes, bool], bool]) -> bytearray:
    """Read into `buffer` until `done(buffer, at_end)`, or the feed ends."""
    while not done(buffer, False):
        data = feed.read()
        if data is None:
            return buffer
        buffer += data
    return buffer


def _sniffed(data: bytes, at_end: bool) -> bool:
    """Whether enough of a stream has arrived to tell its format (its whole header, for the text headers)."""
    if at_end or len(data) >= SNIFF_BYTES:
        return True
    if data.startswith(b"#!AER-DAT4"):
        return True
    if data[:1] in (b"%", b"#"):
        return _lines_length(data, data[:1]) < len(data)
    return len(data) >= 20


def _lines_length(data: bytes, marker: bytes) -> int:
    """Bytes of the leading header lines starting with `marker` (a `% end` line closes a Prophesee header);
    len(data) while the last such line is still incomplete."""
    offset = 0
    while data[offset : offset + 1] == marker:
        end = data.find(b"\n", offset)
        if end < 0:
            return len(data)
        line = bytes(data[offset + 1 : end]).strip().lower()
        offset = end + 1
        if marker == b"%" and line == b"end":
            break
    return offset


def header_length(fmt: str, data: bytes, at_end: bool) -> int | None:
    """Bytes of the camera header at the start of `data`, or None while it is still incomplete (a
    line header is complete once a data byte follows it, or the stream has ended)."""
    from neurotac_cli.io import aedat2, aedat3, eventstream

    if fmt == "aedat4":
        length = 18 + struct.unpack_from("<I", data, 14)[0] if len(data) >= 18 else len(data) + 1
    elif fmt == "aedat3":
        length = aedat3.header_length(bytes(data))
        if length is None:
            if at_end:
                raise FormatError("the AEDAT 3.1 header has no `#!END-HEADER` line (is it the whole file?)")
            return None
    elif fmt == "es":
        length = eventstream.HEADER
    else:
        found = aedat2.header_length(bytes(data)) if fmt == "aedat2" else _lines_length(data, b"%")
        if found == len(data) and not (at_end and data.endswith(b"\n")):
            if at_end:
                raise FormatError(f"the camera header is cut short: the input ended mid-line after {len(data)} bytes (is it the whole file?)")
            return None
        # a DAT header is followed by its event type and size bytes (absent in a file with no events)
        if fmt == "dat" and len(data) < found + 2 and not at_end:
            return None
        length = found + 2 if fmt == "dat" and len(data) >= found + 2 else found
    if length <= len(data):
        return length
    if at_end:
        raise FormatError(f"the camera header is cut short: the input ended after {len(data)} bytes (is it the whole file?)")
    return None


def _whole(name, fmt, feed: Feed, buffer: bytearray, sensor, follow, close) -> Stream:
    """A stream of a format read whole: copied to a temporary file (a pipe), or refused (a followed file)."""
    from neurotac_cli.io import camera

    label = camera.FORMAT_NAMES.get(fmt, fmt)
    if follow:
        if fmt in STREAMED:
            raise InputError(f"{name}: {label} does not declare the sensor size, which takes a pass over the whole "
                             "file to find; give --sensor WxH to follow it")
        raise InputError(f"{name}: {label} is read whole, not followed (--follow reads AEDAT 4.0, EVT 3.0/2.1/2.0, "
                         "AEDAT 2.0/3.1, Event Stream and DAT); import it without --follow once it is written")
    def fill(sink):
        sink.write(buffer)
        while (data := feed.read()) is not None:
            sink.write(data)

    temporary, remove = camera.temporary_copy(".neurotac-stream-", name, fill, f"{label} from a pipe is copied whole before "
                                              "it is read: set TMPDIR to a folder with room, or import a file")
    close()
    schema, batches = camera.read_local(temporary, name, sensor, fmt, remove)
    return Stream(schema, batches)


def _batches(name, fmt, feed: Feed, pending: bytearray, decoder, sensor, schema, notes, cleanup) -> Iterator[pa.RecordBatch]:
    """Each read's whole records as one batch; a record cut at the end of the stream is noted, not kept."""
    from neurotac_cli.io import camera

    width, height = sensor
    try:
        while True:
            usable = camera._guarded_call(name, fmt, lambda: decoder.complete(pending))
            if usable:
                block = bytes(pending[:usable])
                del pending[:usable]
                t, x, y, p = camera._guarded_call(name, fmt, lambda: decoder.decode(block))
                if len(t):
                    camera.check_inside(name, x, y, width, height, "stream")
                    yield sch.events_batch(t, x, y, p, schema)
            if decoder.finished:
                break
            data = feed.read()
            if data is None:
                break
            pending += data
        cut = len(pending) + decoder.held()
        if cut and not decoder.finished:
            notes.append(cut_note(name, cut))
        if feed.shrunk:
            notes.append(f"{name}: the file shrank from {feed.shrunk[0]:,} to {feed.shrunk[1]:,} bytes while it was followed "
                         "(rewritten or truncated by another program); the events read before were kept and the rest "
                         "left out: import the new file on its own")
        if feed.rewritten:
            notes.append(f"{name}: the file was rewritten while it was followed (the bytes already read changed); the "
                         "events read before were kept and the rest left out: import the new file on its own")
        if feed.replaced:
            notes.append(f"{name}: another file was renamed over it while it was followed; the events of the file first "
                         "opened were kept and the new file's left out: import the new file on its own")
        if decoder.triggers:
            notes.append(f"{name}: {decoder.triggers} external trigger events were not kept (a stream's metadata goes out "
                         "before they arrive); import the finished file for `sync --method trigger`")
    finally:
        decoder.close()
        cleanup()


def cut_note(name: str, cut_bytes: int) -> str:
    """What the user is told of a camera input whose last record was cut short and left out."""
    return (f"{name}: the last {cut_bytes} bytes are a record cut short (the input ended, or was stopped, "
            "mid-record); they were left out")


def _decoder(fmt: str, header: bytes, sensor):
    from neurotac_cli.io import live_decoders

    return live_decoders.DECODERS[fmt](header, sensor)


def replay(batches: Iterator[pa.RecordBatch], speed: float = 1.0, stop: Callable[[], bool] = lambda: False,
           slice_us: int = REPLAY_SLICE_US, clock=time.monotonic, sleep=time.sleep,
           notes: list | None = None) -> Iterator[pa.RecordBatch]:
    """The batches again, each event released when the wall-clock time since the first event reaches
    its camera time (divided by `speed`): the events of each `slice_us` of camera time go out together
    once that slice has passed. Events that step back in time go out with the slice they are in; a
    clock that is reset (`_ClockSteps`: a camera reset, a wrapped counter) is paced again from where
    it went back, with a line in `notes` (else its backlog would go out at once, unpaced until the
    clock caught up); a stop request ends the replay at once."""
    start_t = start_wall = None
    last, clock_state = 0, _ClockSteps(notes)
    try:
        for batch in batches:
            if batch.num_rows == 0:
                continue
            t = clock_state.paced(batch.column("t").to_numpy().astype(np.int64))
            if start_t is None:
                start_t, start_wall = int(t[0]), clock()
            slices = np.maximum.accumulate(np.maximum((t - start_t) // slice_us, last))
            edges = np.concatenate(([0], np.flatnonzero(np.diff(slices)) + 1, [len(t)]))
            for begin, end in zip(edges[:-1], edges[1:]):
                due = start_wall + (int(slices[begin]) + 1) * slice_us / 1e6 / speed
                while (wait := due - clock()) > 0:
                    if stop():
                        return
                    sleep(min(wait, WAKE_S))
                if stop():
                    return
                yield batch.slice(begin, end - begin)
            last = int(slices[-1])
    finally:
        clock_state.note()


REPLAY_RESET_US = 1_000_000  # a replay's clock stepping back this far ...
REPLAY_RESET_EVENTS = 100  # ... and staying back for this many events in a row was reset (one stray time is no reset)


class _ClockSteps:
    """The times a replay paces by: a camera's times, each reset of its clock taken out (a step back
    of REPLAY_RESET_US or more that REPLAY_RESET_EVENTS events in a row stay behind: the events after
    it follow on from the latest time before it). A stray event behind goes out with the slice it is
    in. `note()` says them all in one line."""

    def __init__(self, notes: list | None):
        self.notes, self.offset, self.peak = notes, 0, None
        self.behind = 0  # events in a row at the end of the last batch that lay a reset's step behind
        self.resets, self.largest, self.first_at = 0, 0, None

    def paced(self, t: np.ndarray) -> np.ndarray:
        out = t + self.offset
        while True:
            before = np.maximum.accumulate(np.concatenate(([out[0] if self.peak is None else self.peak], out[:-1])))
            k = self._reset_at(out < before - REPLAY_RESET_US)
            if k is None:
                break
            shift = int(before[k] - out[k])
            out[k:] += shift
            self.offset += shift
            self.resets, self.largest = self.resets + 1, max(self.largest, shift)
            self.first_at = int(t[k]) if self.first_at is None else self.first_at
        self.peak = int(out.max()) if self.peak is None else max(self.peak, int(out.max()))
        return out

    def _reset_at(self, back: np.ndarray) -> int | None:
        """The first event of the first run of REPLAY_RESET_EVENTS behind (a run the last batch began
        counts its events there); None where there is none, the run at the batch's end kept."""
        from neurotac_cli.metrics import runs

        found = runs(back)
        for begin, end in found:
            if end - begin + (self.behind if begin == 0 else 0) >= REPLAY_RESET_EVENTS:
                self.behind = 0
                return begin
        begin, end = found[-1] if found else (0, 0)
        self.behind = (end - begin + (self.behind if begin == 0 else 0)) if end == len(back) and found else 0
        return None

    def note(self):
        if self.resets and self.notes is not None:
            many = f"{self.resets} times, by up to {self.largest / 1e6:.4g} s, first" if self.resets > 1 else f"{self.largest / 1e6:.4g} s"
            self.notes.append(f"the camera's clock steps back {many} at t {self.first_at} µs; the replay paces the events after "
                              "each step from where the clock went back (their times are kept)")


def stop_on_signals() -> Callable[[], bool]:
    """A stop request that Ctrl-C and SIGTERM set instead of interrupting, so live input ends with
    the output complete; a second signal interrupts as usual."""
    import signal
    import threading

    requested = threading.Event()

    def handler(number, frame):
        requested.set()
        signal.signal(number, previous[number])

    previous = {number: signal.signal(number, handler) for number in (signal.SIGINT, signal.SIGTERM)}
    for number in previous:
        signal.siginterrupt(number, False)  # a write blocked on a full pipe resumes (Arrow's writer would fail on EINTR)
    return requested.is_set

