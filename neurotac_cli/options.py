"""Options shared by commands, as decorators, and the click parameter types for units."""

import os

import click

from neurotac_cli.errors import NeurotacError
from neurotac_cli.units import parse_duration_us, parse_ints, parse_size


class ParamType(click.ParamType):
    """A parameter type whose name is shown in help as written: click upper-cases a type's name
    (`WxH` -> `WXH`, `N|longest` -> `N|LONGEST`), which then reads as a value the type refuses."""

    def get_metavar(self, param, ctx=None):
        return self.name


class Duration(ParamType):
    """A duration with its unit (`10ms`, `500us`, `1.5s`), as integer microseconds."""

    name = "DURATION"

    def __init__(self, positive: bool = False, longest_us: int = 2**62, at_least_zero: bool = False):
        self.positive, self.longest_us = positive, longest_us  # times are int64 µs: room left to add them
        self.at_least_zero = at_least_zero

    def convert(self, value, param, ctx):
        try:
            us = value if isinstance(value, int) else parse_duration_us(value)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)
        if self.positive and us <= 0:
            self.fail(f"expected a positive duration, got {value!r}", param, ctx)
        if self.at_least_zero and us < 0:
            self.fail(f"expected a duration of 0 or more, got {value!r}", param, ctx)
        if abs(us) > self.longest_us:
            self.fail(f"{value!r} is longer than the longest duration taken here, {self.longest_us} µs", param, ctx)
        return us


class FiniteRange(click.FloatRange):
    """click's FloatRange, refusing NaN and infinities: NaN passes both of a range's comparisons, so it
    reached the code behind the option (a traceback, or a check that then never held)."""

    def convert(self, value, param, ctx):
        import math

        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number in the range {self._describe_range()}", param, ctx)
        return number


class Finite(ParamType):
    """A finite number (NaN and inf refused: they pass every range check), above `above` when given."""

    name = "FLOAT"

    def __init__(self, above: float | None = None):
        self.above = above

    def convert(self, value, param, ctx):
        import math

        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(number):
            self.fail(f"expected a finite number, got {value!r}", param, ctx)
        if self.above is not None and number <= self.above:
            self.fail(f"expected a number above {self.above:g}, got {value!r}", param, ctx)
        return number


class Size(ParamType):
    """`WIDTHxHEIGHT`, as a (width, height) tuple."""

    name = "WxH"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            return parse_size(value)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)


class KeyValue(ParamType):
    """`name=value`, as a (name, value) tuple."""

    name = "NAME=VALUE"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        name, sep, text = str(value).partition("=")
        if not sep or not name:
            self.fail(f"expected NAME=VALUE, got {value!r}", param, ctx)
        return name.strip(), text.strip()


def distinct_names(ctx, param, pairs):
    """Callback of a repeatable NAME=VALUE option: one NAME twice would keep only its last VALUE."""
    names = [name for name, _ in pairs]
    for name in names:
        if names.count(name) > 1:
            raise click.BadParameter(f"{name} given twice; give each NAME once", ctx=ctx, param=param)
    return pairs


class IntTuple(ParamType):
    """`count` comma-separated whole numbers >= 0 (`60,30,115,115`), as a tuple; `words` also accepted as they are."""

    def __init__(self, count: int, example: str, name: str, words: tuple = ()):
        self.count, self.example, self.name, self.words = count, example, name, words

    def convert(self, value, param, ctx):
        if isinstance(value, tuple) or value in self.words:
            return value
        try:
            return parse_ints(value, self.count)
        except NeurotacError:
            self.fail(f"expected {self.name}, e.g. {self.example}, got {value!r}", param, ctx)


def one_stdin(ctx, param, paths):
    """Callback of input path arguments: `-` names stdin once."""
    if list(paths).count("-") > 1:
        raise click.BadParameter(f"- (stdin) is given {list(paths).count('-')} times; stdin holds one input", ctx, param)
    return paths


def input_paths(function):
    return click.argument("paths", nargs=-1, type=click.Path(dir_okay=False, allow_dash=True), callback=one_stdin)(function)


class TablePath(click.Path):
    """A path to write a table to: its suffix names the format, so an unknown one is a usage error,
    but for a pipe or device (/dev/stdout, a shell's `>(...)`), which gets stdout's stream."""

    SUFFIXES = (".parquet", ".pq", ".arrow", ".feather", ".arrows", ".csv", ".json", ".ndjson")  # as tables.SUFFIXES

    def __init__(self):
        super().__init__(dir_okay=False, writable=True, allow_dash=True)

    def convert(self, value, param, ctx):
        from neurotac_cli.tables import is_special  # here: loading pyarrow for --help costs every command's start

        if value == "":
            from neurotac_cli.errors import empty_path

            self.fail(empty_path("output"), param, ctx)
        path = super().convert(value, param, ctx)
        if path != "-" and os.path.splitext(str(path))[1].lower() not in self.SUFFIXES and not is_special(str(path)):
            self.fail(f"cannot tell the table format of {path!r} from its suffix (use .parquet, .arrow, .feather or .arrows; .csv, .json or .ndjson for tables without tensors)", param, ctx)
        return path


class PlotPath(click.Path):
    """A path to draw a figure to: its suffix names the image format."""

    SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".eps")

    def __init__(self):
        super().__init__(dir_okay=False, writable=True)

    def convert(self, value, param, ctx):
        path = super().convert(value, param, ctx)
        if os.path.splitext(str(path))[1].lower() not in self.SUFFIXES:
            self.fail(f"cannot tell the image format of {path!r} from its suffix (use {', '.join(self.SUFFIXES)})", param, ctx)
        return path


def output_option(function):
    return click.option(
        "-o",
        "--output",
        type=TablePath(),
        default=None,
        help="Write to this file (.parquet, .arrow, .feather or .arrows by suffix; .csv, .json or .ndjson for "
        "tables without tensors) instead of stdout; a pipe or device (/dev/stdout, a shell's >(...)) gets stdout's stream.",
    )(function)


class Pool(ParamType):
    name = "KxL|all"

    def convert(self, value, param, ctx):
        if value in (None, "all") or isinstance(value, tuple):
            return value
        return Size().convert(value, param, ctx)


def crop_box_options(streaming: bool = False):
    """--box, --size, --center, --pool: the contact area to keep (crop; sense, `streaming`, whose
    centre is given: `auto` needs the whole input)."""
    # `auto` is parsed for a stream too, so that it is refused with its reason rather than as a malformed X,Y
    center = click.option("--center", type=IntTuple(2, "120,90", "X,Y" if streaming else "X,Y|auto", words=("auto",)), default=None,
                          help="Centre of the --size box (`neurotac crop --center auto` on a recording of the rig prints it)." if streaming
                          else "Centre of the --size box: X,Y, or `auto` = the contact area's centre from the whole input (printed, "
                          "and recorded in history; `auto` reads the whole input before writing a frame, so on a live stream give X,Y).")

    def decorate(function):
        for option in reversed([
            click.option("--box", type=IntTuple(4, "60,30,115,115", "X,Y,W,H"), default=None, help="Keep this box: left, top, width, height in pixels."),
            click.option("--size", type=Size(), default=None, help="Keep a WxH box centred at --center (thesis: 115x115 in ch. 4, 140x150 in ch. 5)."),
            center,
            click.option("--pool", type=Pool(), default=None, help="Sum KxL neighbouring pixels (2x2: 140x150 -> 70x75), or `all`: one pixel per channel."),
        ]):
            function = option(function)
        return function

    return decorate


CAMERA_FORMATS = ["aedat2", "aedat3", "aedat4", "evt2", "evt21", "evt3", "dat", "es", "csv", "text", "hdf5"]  # io.camera.FORMATS, without its imports


def camera_input_options(function):
    """--format, --follow, --idle-timeout, --realtime, --speed: how a camera is read (import, sense)."""
    for option in reversed([
        click.option("--format", "fmt", type=click.Choice(CAMERA_FORMATS), default=None,
                     help="Read the files as this format instead of telling it from their first bytes."),
        click.option("--follow", is_flag=True, help="Read the file while the camera still writes it (like `tail -f`), passing events on "
                     "as they arrive; a file not there yet is waited for as long as --idle-timeout; ends when it stops growing for "
                     "--idle-timeout, or on Ctrl-C, with the output complete."),
        click.option("--idle-timeout", type=Duration(positive=True), default="2s", show_default=True,
                     help="With --follow: end once the file (or the pipe) has not grown for this long, or when the file has not "
                     "appeared, or nothing has been written into the FIFO, after this long."),
        click.option("--realtime", is_flag=True, help="Replay at the recorded speed: each millisecond of events is passed on "
                     "when that much time has passed since the first event (to test a controller against a recording); "
                     "where the camera's clock is reset (steps back a second or more, and stays back), the pace goes on from there (warned)."),
        click.option("--speed", type=Finite(above=0), default=None,
                     help="With --realtime: replay this many times faster than recorded (e.g. 10) [default: 1]."),
    ]):
        function = option(function)
    return function


def replay_speed(realtime: bool, speed: float | None) -> float | None:
    """The replay pace `import_events` takes (None: no replay); --speed alone is a usage error."""
    if speed is not None and not realtime:
        raise click.UsageError("--speed sets the pace of a replay: give it with --realtime")
    return (speed or 1.0) if realtime else None


def idle_timeout_needs_follow(follow: bool) -> None:
    """--idle-timeout ends a followed file (or pipe): without --follow nothing waits, so a value the
    user gave would change nothing. Its default is no choice of the user's, hence the parameter's
    source and not its value."""
    given = click.get_current_context().get_parameter_source("idle_timeout") != click.core.ParameterSource.DEFAULT
    if given and not follow:
        raise click.UsageError("--idle-timeout ends a followed file once it stops growing: give it with --follow, or leave it out")


def seed_option(function):
    return click.option(
        "--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
        help="Seed of every random draw: same seed, same bytes."
    )(function)


def study_options(function):
    """`--jobs`, `--scheduler`, `--cache`: how a command runs many independent tasks (folds, grid
    points, seeds) through `neurotac_cli.study.run_tasks`. Adds the parameters `jobs`, `scheduler`, `cache`."""
    function = click.option(
        "--cache",
        type=click.Path(file_okay=False),
        default=None,
        envvar="NEUROTAC_CACHE",
        help="Keep each finished task's result in this folder, so a re-run of an interrupted study "
        "runs only the tasks still missing [env NEUROTAC_CACHE].",
    )(function)
    function = click.option(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        envvar="NEUROTAC_SCHEDULER",
        help="Run the tasks on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786 (see docs/studies.md; "
        "SLURM/PBS through dask-jobqueue) [env NEUROTAC_SCHEDULER].",
    )(function)
    function = click.option(
        "--jobs",
        "-j",
        type=click.IntRange(min=0),
        default=1,
        show_default=True,
        envvar="NEUROTAC_JOBS",
        help="Run this many tasks at once in local processes (0: one per CPU). Results do not depend on it "
        "[env NEUROTAC_JOBS].",
    )(function)
    return function


# --------------------------------------------------------------------------------------------------
# History

# Where a command's results go and how fast they are computed, not what they are: left out of the
# history, so the same request writes the same bytes whatever the output paths or worker count.
NOT_IN_HISTORY = frozenset({"output", "metrics_path", "plot", "plot_trials", "curve", "jobs", "scheduler", "cache", "threads",
                            "device"})


def history(unused=(), **extra) -> tuple[str, dict]:
    """The history step `(command, args)` of the running command: every parsed parameter the output
    depends on (none left out, None and unused repeatable options dropped, and the parameters named in
    `unused`: those that do not apply to this run, such as a session's settings when it made trials),
    then `extra` (reports)."""
    ctx = click.get_current_context()
    args = {name: _plain(value) for name, value in ctx.params.items()
            if name not in NOT_IN_HISTORY and name not in unused and value is not None and value != ()}
    args.update({name: value for name, value in extra.items() if value is not None})
    return ctx.info_name, args


def _plain(value):
    """A parameter as JSON: tuples become lists, (name, value) pairs `name=value`."""
    if isinstance(value, tuple):
        if value and all(isinstance(item, tuple) and len(item) == 2 for item in value):
            return [f"{name}={text}" for name, text in value]
        return [_plain(item) for item in value]
    return value


# --------------------------------------------------------------------------------------------------
# Models: hyperparameters, validation, folds, progress

# (option, parameter, type, help); None defaults take each model's thesis value.
HYPERPARAMETERS = [
    ("--layers", "layers", int, "Hidden layers: tdnn k (thesis 4), lstm (6), cnnlstm conv layers (4), convlstm (4), deform-gru GRU layers (1), material-dnn k (2)."),
    ("--units", "units", int, "Units per layer: tdnn n (thesis 40), lstm (32), cnnlstm LSTM units (32), material-dnn n (30)."),
    ("--delays", "delays", int, "tdnn: previous frames fed with the current one (thesis 3)."),
    ("--filters", "filters", int, "cnnlstm, convlstm: filters per convolutional layer (thesis 3)."),
    ("--kernel", "kernel", int, "cnnlstm, convlstm: square kernel size (thesis 3, i.e. 3x3)."),
    ("--dropout", "dropout", float, "Dropout rate: cnnlstm, convlstm after the first three layers (thesis 0.4); deform-gru, material-curves."),
    ("--dense", "dense", int, "convlstm: hidden units of the dense head (0: one linear layer; default 0)."),
    ("--hidden", "hidden", int, "deform-gru: GRU units (default 32)."),
    ("--members", "members", int, "deform-gru: GRUs on the same features, each trained with its own draw of validation trials (with --val-fraction), their estimates averaged (default 3; 1: one GRU)."),
    ("--memory-frames", "memory_frames", int, "deform-gru: time constant in frames of its deformation map and counts (default 0 = sums since the trial start; --contacts sets 3000)."),
    ("--layout-grid", "layout_grid", int, "deform-gru: side of an optional coarse spatial layout grid of its features (default 0 = none; 4 fits seen sizes better, unseen sizes worse)."),
    ("--restarts", "restarts", int, "gp: random restarts of the marginal-likelihood optimiser (default 3)."),
    ("--max-points", "max_points", int, "gp: training frames kept, a random subset (default 1500; cost grows as n^3)."),
    ("--points", "points", int, "material models: samples each accumulation curve is resampled to (thesis 30)."),
    ("--adapt-by", "adapt_by", str, "material models: standardise the features per value of this label (e.g. object: each "
     "object size a domain) when training, and when classifying per value of it, or over all the input's grasps where "
     "the input has no such label, each domain of at least 8 grasps about balanced across the classes: for an object "
     "size or a sensor training never saw (default: none)."),
    ("--lr", "lr", float, "Adam learning rate (thesis 0.001)."),
    ("--beta1", "beta1", float, "Adam beta1 (thesis 0.9)."),
    ("--beta2", "beta2", float, "Adam beta2 (thesis 0.999)."),
    ("--batch-size", "batch_size", int, "Trials per minibatch (default 8)."),
    ("--epochs", "epochs", int, "Most epochs (default 500); early stopping usually ends sooner."),
    ("--patience", "patience", int, "Stop after this many epochs without validation improvement, restoring the best weights (thesis 20; deform-gru 40)."),
    ("--weight-decay", "weight_decay", float, "Adam weight decay (default 0)."),
]

NONZERO_HELP = ("Score only frames whose measured force is not exactly zero (thesis 4.6: the zero padding to the "
                "longest trial is left out); a noisy log's rest frames stay: to score frames in contact only, "
                "`neurotac select --where \"phase <> 'none'\"` first.")
GRID_HELP = ("Hyperparameters to vary, as train's option names with _ for -: layers=1..5, units=5,10,...,40, "
             "lr=1e-3,1e-2 (A..B inclusive, A..B:STEP, A,B,...,Z continues the step). Repeat it or put several "
             "in one quoted argument; a single value fixes a parameter (epochs=30), as does its option (--epochs 30).")


def checked_grid(ctx, param, specs):
    """Callback of --grid: a grid that does not parse is refused before any input is read."""
    from neurotac_cli.study import parse_grid

    parse_grid(specs)
    return specs


def hyperparameter_options(function):
    for option, name, kind, text in reversed(HYPERPARAMETERS):
        function = click.option(option, name, type=kind, default=None, help=text)(function)
    return function


def hyperparameters(values: dict) -> dict:
    """The hyperparameter options among a command's parameters, by name (None where not given)."""
    return {name: values.get(name) for _, name, _, _ in HYPERPARAMETERS}


def validation_options(function):
    function = click.option("--val-per", default=None, metavar="LABEL",
                            help="With --val-fraction: draw validation trials per value of this label [default: object "
                            "(the thesis: one per size) for force models, the class label for classifiers].")(function)
    function = click.option("--val-where", default=None, metavar="LABEL=VALUE",
                            help="Validate on the trials with this label value, e.g. object=bolt15.")(function)
    function = click.option("--val-fraction", type=FiniteRange(0, 1, max_open=True), default=None,
                            help="Validate on this fraction of source trials, drawn per --val-per value (default 0.1 when no other choice is given).")(function)
    function = click.option("--val-trials", default=None, metavar="ID,ID,...",
                            help="Validate on these trials (comma-separated ids; with --contacts a session's id holds out every "
                            "contact found in it).")(function)
    return function


def fold_options(prefix: str = ""):
    """--repeats, --val-fraction, --val-per, --label: how `neurotac study` and `eval --cv` train each fold
    (`prefix` starts the help of those that apply to --cv only, e.g. "With --cv: ")."""

    def text(words: str) -> str:
        return prefix + words if prefix else words[0].upper() + words[1:]

    def decorate(function):
        for option in reversed([
            click.option("--repeats", type=click.IntRange(min=1), default=1, show_default=True,
                         help=text("train every fold with this many seeds (thesis 10).")),
            click.option("--val-fraction", type=FiniteRange(0, 1, max_open=True), default=0.1, show_default=True,
                         help=text("validation share of each fold's training trials, drawn per --val-per value "
                                   "(thesis: one per size).")),
            click.option("--val-per", default=None, metavar="LABEL",
                         help=text("label whose values each get validation trials [default: object for force models, "
                                   "the class label for classifiers].")),
            click.option("--label", default="material", show_default=True, help="Classifiers: the label column."),
        ]):
            function = option(function)
        return function

    return decorate


def device_option(function):
    """`--device`: where gradient-trained force models train (parameter `device`); `use_device` applies it."""
    return click.option(
        "--device", default="cpu", show_default=True, envvar="NEUROTAC_DEVICE", metavar="cpu|cuda|cuda:N",
        help="Where force networks train (lstm, cnnlstm, convlstm, tdnn, deform-gru): cpu, or a CUDA GPU with a "
        "CUDA build of torch. Models come back to the CPU to be saved and run. GPU trainings differ from CPU ones "
        "in the last digits and are cached apart; `--jobs` processes share the GPU [env NEUROTAC_DEVICE].",
    )(function)


def use_device(device: str):
    """Check `--device` before any work and hand it to this process's trainings and the worker
    processes it starts (model.fit.training_device reads it back)."""
    from neurotac_cli.model.fit import DEVICE_VARIABLE, training_device

    os.environ[DEVICE_VARIABLE] = device
    training_device()


MOST_THREADS = 1024


def threads_option(default: int, text: str = "CPU threads for torch."):
    """`--threads`: how many CPU threads torch uses (parameter `threads`). Bounded: OpenMP aborts the
    process, or it dies of a segmentation fault, when it cannot start the threads asked for (measured
    from about 20000 on a machine that allows 96000 processes)."""
    return click.option("--threads", type=click.IntRange(1, MOST_THREADS), default=default, show_default=True, help=text)


def progress_printer(command: str, every: int = 25, quiet_s: float = 30.0):
    """Progress on stderr: every message on a terminal (overwriting epoch lines); otherwise the first
    epoch, every 25th, and any epoch that ends 30 s or more after the last line shown (a slow model
    shows it is alive), besides every message that is not an epoch line. A message that is a warning
    is written as every warning is, `neurotac COMMAND: warning: ...`."""
    import re
    import sys
    import time

    from neurotac_cli.tables import is_terminal

    interactive = is_terminal(sys.stderr)
    shown = [time.monotonic()]

    def show(message: str):
        line = re.match(r"\S+(?: member \d+/\d+)?: epoch (\d+) ", message)  # `fit`'s per-epoch line, of a member or not
        if line:
            epoch = int(line.group(1))
            if interactive:
                click.echo("\r" + message[:150].ljust(150), err=True, nl=False)
                return
            if epoch != 1 and epoch % every and time.monotonic() - shown[0] < quiet_s:
                return
        elif interactive:
            click.echo("", err=True)
        click.echo(f"neurotac {command}: {message}" if message.startswith("warning: ") else message, err=True)
        shown[0] = time.monotonic()

    return show


def echo_lines(command: str, lines, prefix: str = "") -> None:
    """Each line on stderr as `neurotac COMMAND: PREFIXline` (PREFIX e.g. `warning: `)."""
    for line in lines:
        click.echo(f"neurotac {command}: {prefix}{line}", err=True)


def typed_options(*names) -> list[str]:
    """Those of `names` (parameter names) given on the running command's command line, as options
    (`--val-fraction`): an environment variable set for a whole session is not the user's request."""
    ctx = click.get_current_context()
    return ["--" + name.replace("_", "-") for name in names if ctx.get_parameter_source(name) == click.core.ParameterSource.COMMANDLINE]


def label_given() -> bool:
    """Whether the user gave --label (not its default) to the running command."""
    return click.get_current_context().get_parameter_source("label") != click.core.ParameterSource.DEFAULT


def refuse_label_for_force(model_name: str) -> None:
    """--label chooses the class a classifier predicts: given with a force model it would change nothing."""
    from neurotac_cli.errors import UsageError
    from neurotac_cli.model.names import MATERIAL_MODELS

    if model_name not in MATERIAL_MODELS and label_given():
        raise UsageError(f"--label chooses the class a classifier predicts; {model_name} estimates force (leave --label out)")
