"""The root `neurotac` group: a lazy registry of subcommands, and the one place errors become exit codes."""

import importlib
import importlib.util
import io
import os
import sys

import click

from neurotac_cli import __version__
from neurotac_cli.errors import NeurotacError, OutputError, UsageError
from neurotac_cli.whole import write_whole

# name -> (module under neurotac_cli.commands, one-line help). Modules are imported only when run,
# so `neurotac --help` needs neither pyarrow nor torch.
COMMANDS = {
    "simulate": ("simulate", "Simulate grasps: camera files, force logs and a manifest."),
    "import": ("import_", "Read camera files (AEDAT, EVT 2.0/2.1/3.0, DAT, ES, HDF5, text) into an events table."),
    "info": ("info", "Describe a table or camera file for a person."),
    "sync": ("sync", "Align camera events with a force log; cut and label trials."),
    "frame": ("frame", "Bin each trial's events into two-channel count frames."),
    "crop": ("crop", "Crop and pool frames, recordings or events to the contact area."),
    "augment": ("augment", "Rotate, resize, add noise, frame-shift and event-shift frames."),
    "train": ("train", "Train a force or material model on frames."),
    "eval": ("eval", "Score a model on frames: predictions, metrics, plots, cross-validation."),
    "classify": ("classify", "Predict each trial's material with a trained classifier."),
    "predict": ("predict", "Stream force estimates frame by frame, as frames arrive."),
    "sense": ("sense", "The sensor in one process: camera in, each window's force out as it closes."),
    "study": ("study", "Run a grid x folds x seeds study, locally or on a Dask cluster."),
    # data: seeing and carrying tables
    "render": ("render", "Draw events, frames, a crop box or augmented copies as PNG, GIF or MP4."),
    "select": ("select", "Keep the rows for which a condition holds (SQL): trials, labels, phases, times."),
    "concat": ("concat", "Concatenate tables of one kind, refusing trial ids they share."),
    "split": ("split", "Split into training and test tables by whole trials, seeded."),
    "export": ("export", "Write events as a camera file (EVT 3.0, AEDAT 4.0, AEDAT 2.0) or HDF5."),
}


def _available(name: str) -> bool:
    return importlib.util.find_spec(f"neurotac_cli.commands.{COMMANDS[name][0]}") is not None


class LazyGroup(click.Group):
    def list_commands(self, ctx):
        return [name for name in COMMANDS if _available(name)]

    def get_command(self, ctx, name):
        if name not in COMMANDS or not _available(name):
            return None
        module = importlib.import_module(f"neurotac_cli.commands.{COMMANDS[name][0]}")
        return getattr(module, "command")

    def resolve_command(self, ctx, args):
        name, command, rest = super().resolve_command(ctx, args)
        if command is not None and not ctx.resilient_parsing:
            _refuse_repeated_options(command, name, rest, ctx)
        return name, command, rest

    def main(self, args=None, prog_name=None, **extra):
        """click's own usage errors (a missing argument, a value of the wrong type, an unknown option)
        as one line, as the commands' own refusals are: a batch log shows one line per failure."""
        extra.pop("standalone_mode", None)
        _guard_stdout()
        _check_working_folder()
        _end_on_sigterm()
        try:
            result = super().main(args=args, prog_name=prog_name, standalone_mode=False, **extra)
            _end_if_dropped()
            if not result:
                sys.stdout.flush()  # exit 0 says the output is whole: its last bytes are written first
        except click.exceptions.NoArgsIsHelpError as error:  # bare `neurotac`: its help, readable through a pager
            _echo_help(error.ctx.get_help())
            sys.exit(0)
        except click.UsageError as error:
            _fail_usage(error.ctx.command_path if error.ctx is not None else "neurotac", error.format_message())
        except click.ClickException as error:
            error.show()
            sys.exit(error.exit_code)
        except click.exceptions.Abort as error:  # click's word for an interrupt while it parses
            terminated = isinstance(error.__context__, Terminated)
            _fail(f"neurotac: {'terminated' if terminated else 'interrupted'}", code=143 if terminated else 130)
        except (NeurotacError, OSError) as error:  # the root's own --help or --version, to a closed or full stdout
            _fail_output("neurotac", error)
        sys.exit(result if isinstance(result, int) else 0)

    def format_commands(self, ctx, formatter):
        rows = [(name, COMMANDS[name][1]) for name in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except UsageError as error:
            _fail_usage(_who(ctx), str(error))
        except NeurotacError as error:
            _fail(f"{_who(ctx)}: error: {error}")
        except BrokenPipeError:
            _quiet_exit()
        except Terminated:
            _fail(f"{_who(ctx)}: terminated", code=143)
        except KeyboardInterrupt:
            _fail(f"{_who(ctx)}: interrupted", code=130)
        except MemoryError:
            _fail(f"{_who(ctx)}: error: out of memory (process the input in smaller pieces)")
        except RuntimeError as error:
            if "can't allocate memory" not in str(error):  # torch's allocator says it so, not with MemoryError
                raise
            _fail(f"{_who(ctx)}: error: out of memory (process the input in smaller pieces, or a smaller model)")
        except OSError as error:  # writing to stdout (`> file` on a full disk); -o is handled by tables.atomic_file
            _fail_output(_who(ctx), error)


def _refuse_repeated_options(command, name, args, parent):
    """An option that takes one value, given twice, is a usage error: click would keep the last one
    and drop the other without a word. Repeatable options (`multiple`, `count`) are not checked."""
    ctx = click.Context(command, info_name=name, parent=parent)
    try:
        _, _, order = command.make_parser(ctx).parse_args(list(args))
    except click.UsageError:
        return  # the real parse reports it
    if any(getattr(param, "is_eager", False) for param in order):
        return  # --help: nothing runs
    seen = set()
    for param in order:
        if not isinstance(param, click.Option) or param.multiple or param.count:
            continue
        if param.name in seen:
            raise click.UsageError(f"{_option_name(param)} given twice; give it once", ctx=ctx)
        seen.add(param.name)


def _option_name(param) -> str:
    name = max(param.opts, key=len)  # --output rather than -o
    return f"{name}/{max(param.secondary_opts, key=len)}" if param.secondary_opts else name


def _who(ctx) -> str:
    """`neurotac CMD` for messages; the subcommand is not known to click yet while its module loads."""
    name = ctx.invoked_subcommand or named_verb()
    return f"neurotac {name}" if name else "neurotac"


def named_verb() -> str | None:
    """The subcommand the command line names, before click has parsed it (None where it names none)."""
    return next((arg for arg in sys.argv[1:] if arg in COMMANDS), None)


def _fail_usage(who: str, message: str):
    """A usage error, click's or a command's own: one line, exit 2, pointing at the command's help."""
    _fail(f"{who}: error: {' '.join(message.split())} (see `{who} --help`)", code=2)


def _fail(message: str, code: int = 1):
    try:
        sys.stdout.flush()
    except (OSError, NeurotacError):  # a reader gone, a full disk, a closed stdout: the error line matters now
        _redirect_stdout_to_devnull()
    click.echo(_one_line(message), err=True)
    sys.exit(code)


def _fail_output(who: str, error: Exception):
    """Stdout that cannot take the output: one line, exit 1 (a reader gone away: exit 0, silently)."""
    if isinstance(error, BrokenPipeError):
        _quiet_exit()
    if isinstance(error, OSError) and not isinstance(error, NeurotacError):
        if error.errno not in OutputError.ONLY_WRITING:  # not a write's: a bug, whose traceback is wanted
            raise error
        error = OutputError.from_os(error.filename or "the output", error)
    _fail(f"{who}: error: {error}")


def _echo_help(text: str):
    """The root's help for a bare `neurotac`, to a stdout that may be closed or full."""
    try:
        click.echo(text)
    except (NeurotacError, OSError) as error:
        _fail_output("neurotac", error)


def _one_line(message: str) -> str:
    """The message as one printable line: a path may hold a newline, or bytes that are not UTF-8
    (Python's surrogate escapes, shown as \\udcff), which are written as the escapes \\n and \\xff."""
    try:
        text = message.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a surrogate that no file name's byte gives
        text = message.encode("utf-8", "backslashreplace").decode("utf-8")
    return text.replace("\r", "\\r").replace("\n", "\\n")


def _redirect_stdout_to_devnull():
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    if isinstance(sys.stdout, _ClosedStdout):
        return
    try:  # what is still buffered goes to /dev/null now, not to the interpreter's last flush
        sys.stdout.flush()
    except (OSError, ValueError):
        pass


class Terminated(KeyboardInterrupt):
    """SIGTERM (what `timeout`, make and SLURM send), raised where the run is, as Ctrl-C's interrupt
    is: the same blocks clean up (an output's `.neurotac-*.part` temporary is removed), then exit 143.
    Left to its default, the signal ended the process where it stood and left the temporary behind."""


def _end_on_sigterm():
    import signal
    import threading

    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _terminate)
    if sys.unraisablehook is not _signal_again:
        _UNRAISABLE.append(sys.unraisablehook)
        sys.unraisablehook = _signal_again


def _terminate(number, frame):
    raise Terminated()


def _signal_again(unraisable):
    """A signal's exception raised inside a callback Python cannot raise from (a weak reference's,
    such as the import system's module locks, or a `__del__`) is printed and dropped, and the run
    would go on to its end with exit 0: the signal is sent again a moment later, from a thread (sent
    from here it would be raised here, and dropped again), to be raised where the run has gone on."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt):
        import signal
        import threading

        _DROPPED.append(signal.SIGTERM if isinstance(unraisable.exc_value, Terminated) else signal.SIGINT)
        threading.Timer(0.01, _send_dropped).start()
        return
    _UNRAISABLE[-1](unraisable)


_UNRAISABLE = []  # the hook `_signal_again` took the place of, for every other unraisable exception
_DROPPED = []  # signals whose exception Python dropped, not yet sent again (`_signal_again`)


def _send_dropped():
    try:
        number = _DROPPED.pop()  # one pop: this or `_end_if_dropped` acts on it, never both
    except IndexError:
        return
    os.kill(os.getpid(), number)


def _end_if_dropped():
    """A run that ended before the signal Python dropped was sent again ends as that signal's."""
    try:
        number = _DROPPED.pop()
    except IndexError:
        return
    end_as_signal(number)


def end_as_signal(number: int, who: str = "neurotac"):
    """End the run as Ctrl-C's (130, "interrupted") or SIGTERM's (143, "terminated") one line says."""
    import signal

    terminated = number == signal.SIGTERM
    _fail(f"{who}: {'terminated' if terminated else 'interrupted'}", code=143 if terminated else 130)


def _check_working_folder():
    """A working folder deleted under the shell (`rmdir` from another terminal) fails every relative
    path and some libraries deep inside (DuckDB blamed the SQL, MKL exited 2): said once, first."""
    try:
        os.getcwd()
    except FileNotFoundError:
        name = named_verb()
        _fail(f"neurotac{' ' + name if name else ''}: error: the working folder no longer exists (it was deleted or "
              "moved); cd into a folder that exists and run it again")


def _guard_stdout():
    """Stdout for the whole run: each write carried to its last byte, or an error. A closed one
    (`>&-`) is an error when written, not a silent success."""
    if sys.stdout is None:
        # fd 1 closed: /dev/null holds it, so no file this run opens takes fd 1 and is written as stdout
        devnull = os.open(os.devnull, os.O_WRONLY)
        if devnull != 1:
            os.dup2(devnull, 1)
            os.close(devnull)
        sys.stdout = _ClosedStdout()
        return
    buffer = getattr(sys.stdout, "buffer", None)
    raw = getattr(buffer, "raw", buffer)
    if not isinstance(raw, io.FileIO) or isinstance(raw, _WholeRaw):
        return  # not the process's own stdout (a test runner's), or guarded already
    sys.stdout.flush()
    whole = _WholeRaw(raw)
    # unbuffered stdout (PYTHONUNBUFFERED) stays unbuffered: tables._WholeWrites gathers its writes
    sys.stdout = io.TextIOWrapper(whole if buffer is raw else io.BufferedWriter(whole), encoding=sys.stdout.encoding,
                                  errors=sys.stdout.errors, line_buffering=sys.stdout.line_buffering,
                                  write_through=buffer is raw)


class _WholeRaw(io.RawIOBase):
    """Stdout's file, each write carried to its last byte (`whole.write_whole`). Python's buffered
    stdout takes a short write (a file reaching `ulimit -f`, a disk filling) as whole and drops the
    rest without a word, so a cut JSON would exit 0; carried on, the next write fails with the error
    that says why."""

    def __init__(self, raw: io.FileIO):
        super().__init__()
        self._raw = raw

    def writable(self):
        return True

    def fileno(self):
        return self._raw.fileno()

    def isatty(self):
        return self._raw.isatty()

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        write_whole(self._raw, view)
        return len(view)


class _ClosedStdout(io.TextIOBase):
    """Stands for a stdout closed at the start (`>&-`), which Python leaves as None and click's echo
    then skips without a word: a write, text or binary, is one error line."""

    def writable(self):
        return True

    def write(self, text):
        raise OutputError("cannot write the output: stdout is closed (`>&-`); redirect it to a file or give -o")

    @property
    def buffer(self):
        return self.write("")

    def flush(self):
        pass

    def isatty(self):
        return False


def _quiet_exit():
    """The reader of our stdout went away (`| head`): that is success, and nothing to say."""
    _redirect_stdout_to_devnull()
    sys.exit(0)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="neurotac")
@click.option("--frame-size", metavar="WxH", default=None, callback=lambda ctx, param, value: _frame_size(value), expose_value=False,
              is_eager=True, help="Frame size of frames tables whose counts came back from another tool as flat lists "
              "without neurotac's metadata (DuckDB `COPY ... TO`, Polars) [env NEUROTAC_FRAME_SIZE].")
def cli():
    """Event-camera tactile sensing: from a camera file and a force log to force estimates and materials.

    Every command reads Arrow tables (IPC stream, Arrow file or Parquet) from stdin or paths and writes
    an Arrow IPC stream to stdout, or a file with -o, so commands compose in shell pipelines:

    \b
        neurotac simulate --preset ch4 --seed 1 --synced \\
          | neurotac frame --window 10ms | neurotac crop --size 115x115 --center auto \\
          | neurotac train --model deform-gru -o force.model

    Shell completion: eval "$(_NEUROTAC_COMPLETE=bash_source neurotac)" (zsh_source, fish_source likewise).
    """


def _frame_size(value):
    """Hand --frame-size to the table reader (neurotac_cli.bridges), which reads it from the environment."""
    if value:
        from neurotac_cli.units import parse_size

        try:
            parse_size(value)
        except NeurotacError as error:
            raise click.BadParameter(str(error), param_hint="--frame-size") from None
        os.environ["NEUROTAC_FRAME_SIZE"] = value


def main():
    cli(prog_name="neurotac")
