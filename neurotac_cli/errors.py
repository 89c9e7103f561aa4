"""User-facing errors. Raised where a problem is found; `cli.py` turns them into one line and exit 1
(exit 2 for a UsageError)."""

import errno
import os


class NeurotacError(Exception):
    """A problem with the user's input or request: say what, why, and what to do."""


class NeurotacWarning(UserWarning):
    """What the command line writes on stderr as a warning (events lost, a huge output), raised with
    `warnings.warn` by the Python API (neurotac_cli.api), which has no stderr of its own."""


class UsageError(NeurotacError):
    """Options that cannot work together or a value an option cannot take, found past click's own
    parsing: exit 2, as click's usage errors."""


class InputError(NeurotacError):
    """Input that cannot be read: a missing file, an unknown format, a stream cut short."""


def empty_path(what: str = "") -> str:
    """The line for a path given empty: a shell variable left unset, found before any work."""
    return f"an empty {what + ' ' if what else ''}path was given (an unset shell variable?)"


def cannot_open(path, error: OSError) -> InputError:
    """The one-line error for an input path that cannot be opened for reading."""
    if path == "":  # a shell variable left unset: say so, not ": no such file"
        return InputError(empty_path())
    if isinstance(error, FileNotFoundError):
        return InputError(f"{path}: no such file")
    if isinstance(error, PermissionError):
        return InputError(f"{path}: permission denied")
    return InputError(f"{path}: cannot open ({error.strerror})")


class NoEventsError(InputError):
    """An events input without one event: nothing to frame."""


class SchemaError(NeurotacError):
    """A table of the wrong kind, or with missing, mistyped or out-of-range columns."""


class FormatError(InputError):
    """A camera or force file whose bytes do not follow its format."""


class SyncError(NeurotacError):
    """The shared instant of camera and force log cannot be found."""


class ModelError(NeurotacError):
    """A model file that cannot be used for this input, or a training request that cannot run."""


class OutsideSensorError(NeurotacError):
    """A crop box or size that does not fit the sensor (or the frames)."""


class PoolError(NeurotacError):
    """A pooling that does not fit the size it pools."""


class OutputError(NeurotacError):
    """An output that cannot be written: a full disk, a read-only or vanished folder."""

    WHY = {
        errno.ENOSPC: ("no space left on the device", "free some space or write elsewhere"),
        errno.EDQUOT: ("disk quota exceeded", "free some space or write elsewhere"),
        errno.EFBIG: ("file too large for its file system", "write it elsewhere"),
        errno.EROFS: ("read-only file system", "write elsewhere"),
        errno.EACCES: ("permission denied", "write elsewhere or change the folder's permissions"),
        errno.EPERM: ("operation not permitted", "write elsewhere or change the folder's permissions"),
        errno.ENOENT: ("its folder vanished while writing", "make the folder again and re-run"),
        errno.EIO: ("input/output error", "check the disk or network share, and write elsewhere"),
        errno.ENAMETOOLONG: ("its name is too long for the file system", "give it a shorter name"),
    }
    ONLY_WRITING = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS}  # errors that reading never gives
    # tables written uncompressed (tables.SUFFIXES): the same table as Parquet may fit under a size limit;
    # a picture, a model, a camera file or a Parquet table has no smaller form to offer
    UNCOMPRESSED_TABLES = (".arrow", ".arrows", ".feather", ".csv", ".json", ".ndjson")

    @classmethod
    def why(cls, error: OSError, target: str | None = None) -> tuple[str, str]:
        """(what went wrong, what to do) for an error writing a file (`target`, where it is known)."""
        why, what_to_do = cls.WHY.get(error.errno, (error.strerror or str(error), "write elsewhere"))
        if error.errno == errno.EFBIG and target and os.path.splitext(target)[1].lower() in cls.UNCOMPRESSED_TABLES:
            what_to_do += ", or as .parquet (compressed)"
        return why, what_to_do

    @classmethod
    def from_os(cls, target: str, error: OSError, kept: bool = False) -> "OutputError":
        why, what_to_do = cls.why(error, target)
        previous = "; the previous file is kept" if kept else ""
        return cls(f"cannot write {target} ({why}; {what_to_do}{previous})")
