"""Writes carried to their last byte, for the process's stdout and the Arrow stream written to it.

A raw write may move fewer bytes than it was given: a signal interrupts a pipe's write, a file
reaches `ulimit -f`, a disk fills. A non-blocking stdout (a parent that set O_NONBLOCK on the pipe
it shares, as Node.js and some job runners do) that is full moves none and says so with None.
Python's buffered layers and Arrow's writer take each of these as whole and drop the rest.
"""

import select


def write_whole(raw, view: memoryview) -> None:
    """Write all of `view` to the file `raw` (raw, or buffered), waiting where a non-blocking one is
    full, as a blocking one would; an error (a full disk, a reader gone) is raised by the write that
    meets it."""
    while len(view):
        try:
            moved = raw.write(view)
        except BlockingIOError as error:  # a buffered file (a library caller's) takes what fits and says so
            moved = error.characters_written
        if not moved:
            select.select([], [raw.fileno()], [])
            continue
        view = view[moved:]


def flush_whole(sink) -> None:
    """Flush the buffered file `sink`, waiting where a non-blocking one is full (its flush raises
    BlockingIOError with what it could not write still held)."""
    while True:
        try:
            sink.flush()
            return
        except BlockingIOError:
            select.select([], [sink.fileno()], [])
