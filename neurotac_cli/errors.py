"""User-facing errors. Raised where a problem is found; `cli.py` turns them into one line and exit 1."""


class NeurotacError(Exception):
    """A problem with the user's input or request: say what, why, and what to do."""


class InputError(NeurotacError):
    """Input that cannot be read: a missing file, an unknown format, a stream cut short."""


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


class UsageError(NeurotacError):
    """Options that contradict each other: exit 2, as click's own usage errors."""
