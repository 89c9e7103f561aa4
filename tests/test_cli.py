"""The root command: help, version, exits."""

import json
import subprocess
import sys

import pytest

from click.testing import CliRunner

from neurotac_cli import __version__
from neurotac_cli.cli import COMMANDS, cli


def test_version():
    result = CliRunner().invoke(cli, ["--version"])
    assert result.exit_code == 0 and __version__ in result.output


def test_help_lists_the_commands():
    result = CliRunner().invoke(cli, ["--help"])
    assert result.exit_code == 0
    assert COMMANDS, "no command is registered"
    assert "Commands" in result.output
    listed = result.output.split("Commands:", 1)[1]
    assert all(f"  {name} " in listed for name in COMMANDS), listed


def test_unknown_command_is_a_usage_error():
    result = CliRunner().invoke(cli, ["no-such-command"])
    assert result.exit_code == 2


def test_installed_console_script_runs():
    done = subprocess.run(["neurotac", "--version"], capture_output=True, text=True)
    assert done.returncode == 0 and __version__ in done.stdout


@pytest.mark.parametrize("number, code, said", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
def test_a_signal_while_the_command_starts_ends_it_with_one_line(number, code, said):
    """A Ctrl-C while the command imported click (0.1 s after it began, on a busy machine) was raised
    inside the import: Python's traceback. Held from the entry point's first line, the verb's line."""
    code_text = (
        "import os, signal, sys\n"
        "class Finder:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        f"        if name == 'click': os.kill(os.getpid(), signal.{number})\n"
        "sys.meta_path.insert(0, Finder())\n"
        "sys.argv = ['neurotac', 'info', 'nothing.arrows']\n"
        "from neurotac_cli.start import main\n"
        "main()\n")
    done = subprocess.run([sys.executable, "-c", code_text], capture_output=True, text=True, timeout=60)
    assert done.returncode == code and done.stderr == f"neurotac info: {said}\n", done.stderr
    # a signal the process ignores (a shell's background job ignores Ctrl-C) is ignored while held too
    ignored = code_text.replace("import os, signal, sys\n", f"import os, signal, sys\nsignal.signal(signal.{number}, signal.SIG_IGN)\n")
    done = subprocess.run([sys.executable, "-c", ignored.replace("'info', 'nothing.arrows'", "'--version'")], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0 and "neurotac, version" in done.stdout, done.stderr


def test_shell_completion_completes_commands_and_options():
    import os

    env = dict(os.environ, COMP_WORDS="neurotac fr", COMP_CWORD="1", _NEUROTAC_COMPLETE="bash_complete")
    done = subprocess.run(["neurotac"], env=env, capture_output=True, text=True)
    assert done.stdout.splitlines() == ["plain,frame"]
    env.update(COMP_WORDS="neurotac frame --pad", COMP_CWORD="2")
    assert "--pad-to" in subprocess.run(["neurotac"], env=env, capture_output=True, text=True).stdout
    for shell in ("bash", "zsh", "fish"):
        env = dict(os.environ, _NEUROTAC_COMPLETE=f"{shell}_source")
        script = subprocess.run(["neurotac"], env=env, capture_output=True, text=True).stdout
        assert "neurotac" in script and "_NEUROTAC_COMPLETE" in script


def test_an_option_given_twice_is_a_usage_error_in_every_command():
    for option, args in [("--where", ["select", "--where", "material='steel'", "--where", "frame<3"]),
                         ("--fs", ["augment", "--fs", "1", "--fs", "-1"]),
                         ("--window", ["frame", "--window", "10ms", "--window", "7ms"]),
                         ("--output", ["frame", "--window", "10ms", "-o", "a.arrow", "--output", "b.arrow"])]:
        result = CliRunner().invoke(cli, args, input=b"")
        assert result.exit_code == 2, (args, result.output)
        assert f"{option} given twice; give it once" in result.output


def test_repeatable_options_and_help_still_work(tmp_path):
    result = CliRunner().invoke(cli, ["frame", "--window", "10ms", "--window", "7ms", "--help"])
    assert result.exit_code == 0 and "Bin each trial" in result.output
    result = CliRunner().invoke(cli, ["simulate", "--trials", "1", "--set", "no_such=1", "--set", "other=2", "--out", str(tmp_path)])
    assert "given twice" not in result.output and "unknown simulator parameter 'no_such'" in result.output


def test_a_name_given_twice_to_a_repeatable_name_value_option_is_a_usage_error():
    for args in (["sync", "x.aedat", "--label", "material=A", "--label", "material=B"],
                 ["simulate", "--set", "on_threshold=0.3", "--set", "on_threshold=0.4"]):
        result = CliRunner().invoke(cli, args)
        assert result.exit_code == 2 and "given twice; give each NAME once" in result.output, result.output


def test_an_error_naming_a_path_with_a_newline_or_bytes_not_utf8_is_one_line(tmp_path):
    """A real shell, because CliRunner cannot show the bytes a terminal or a log gets."""
    import os

    for name, shown in ((b"no\nsuch.arrows", "no\\nsuch.arrows"), (b"no\xffsuch.arrows", "no\\xffsuch.arrows")):
        done = subprocess.run([b"neurotac", b"info", os.fsencode(tmp_path) + b"/" + name], capture_output=True)
        assert done.returncode == 1 and done.stderr.count(b"\n") == 1, done.stderr
        assert done.stderr.decode() == f"neurotac info: error: {tmp_path}/{shown}: no such file\n"


def small_frames(folder, n: int = 30) -> str:
    """A tiny frames table on disk, of trials enough that its info, text or JSON, is over 1 KiB."""
    import numpy as np
    import pyarrow as pa

    from neurotac_cli import schema as sch, tables

    counts = np.random.default_rng(0).poisson(0.3, (3 * n, 2, 8, 8)).astype(np.uint16)
    table = pa.Table.from_pydict({"trial": [f"trial-{i:02d}" for i in range(n) for _ in range(3)],
                                  "frame": pa.array([0, 1, 2] * n, pa.int32()), "t": pa.array([0, 10_000, 20_000] * n, pa.int64()),
                                  "counts": sch.counts_array(counts), "force": pa.array([0.0, 1.0, 2.0] * n, pa.float32()),
                                  "phase": ["grasping", "holding", "releasing"] * n}, schema=sch.frames_schema(8, 8, window_us=10_000))
    tables.write(str(folder / "f.arrows"), table)
    return str(folder / "f.arrows")


def shell(command: str, cwd):
    return subprocess.run(["bash", "-c", command], capture_output=True, text=True, cwd=cwd)


def one_error_line(done, who: str) -> bool:
    return done.returncode == 1 and done.stderr.count("\n") == 1 and done.stderr.startswith(f"{who}: error: cannot write")


def test_text_on_a_stdout_that_fills_is_one_error_line_not_a_cut_success(tmp_path):
    # Python's buffered stdout took the file-size limit's short write as whole and dropped the rest
    frames = small_frames(tmp_path)
    for command, who in [(f"neurotac info {frames} --json", "neurotac info"), (f"neurotac info {frames} --all", "neurotac info"),
                         ("neurotac --help", "neurotac"), ("neurotac train --help", "neurotac train")]:
        done = shell(f"ulimit -f 1; {command} > out.txt", tmp_path)
        assert one_error_line(done, who), (command, done.returncode, done.stderr)
        assert "file too large" in done.stderr
    done = shell(f"ulimit -f 64; neurotac info {frames} --json > out.txt", tmp_path)
    assert done.returncode == 0 and json.loads((tmp_path / "out.txt").read_text())["kind"] == "frames"


def test_a_closed_stdout_is_one_error_line_for_tables_text_and_help(tmp_path):
    frames = small_frames(tmp_path)
    for command, who in [(f"neurotac select --where true {frames}", "neurotac select"), (f"neurotac info {frames} --all", "neurotac info"),
                         (f"neurotac crop --pool 2x2 {frames}", "neurotac crop"), ("neurotac --help", "neurotac"),
                         ("neurotac", "neurotac")]:
        done = shell(f"{command} >&-", tmp_path)
        assert one_error_line(done, who) and "stdout is closed" in done.stderr, (command, done.returncode, done.stderr)
    done = shell(f"neurotac select --where true -o kept.arrows {frames} >&-", tmp_path)  # stdout not needed: no error
    assert done.returncode == 0 and (tmp_path / "kept.arrows").stat().st_size > 0, done.stderr


def read_after_a_pause(command: list[str], tmp_path) -> tuple[int, bytes]:
    """Run `command` with stdout a non-blocking pipe read only after it has filled."""
    import fcntl
    import os
    import time

    read, write = os.pipe()
    fcntl.fcntl(write, fcntl.F_SETFL, fcntl.fcntl(write, fcntl.F_GETFL) | os.O_NONBLOCK)
    process = subprocess.Popen(command, stdout=write, stderr=subprocess.DEVNULL, cwd=tmp_path)
    os.close(write)
    time.sleep(1.5)
    data = b"".join(iter(lambda: os.read(read, 1 << 16), b""))
    os.close(read)
    return process.wait(timeout=60), data


def test_a_non_blocking_stdout_that_fills_gets_every_byte(tmp_path):
    # a full non-blocking pipe's write moves nothing and says so with None: the table was cut at
    # the pipe's 64 KiB, exit 0
    frames = small_frames(tmp_path, n=400)
    for command in (["neurotac", "select", "--where", "true", frames], ["neurotac", "train", "--help"]):
        expected = subprocess.run(command, capture_output=True, cwd=tmp_path).stdout
        if command[1] == "train":  # text, through stdout's own buffer: written often enough to fill the pipe
            command, expected = ["bash", "-c", "for i in $(seq 20); do neurotac train --help; done"], expected * 20
        assert len(expected) > 1 << 16 and read_after_a_pause(command, tmp_path) == (0, expected), command


def test_a_full_non_blocking_buffered_file_is_waited_on_too():
    """A library caller's stdout is a BufferedWriter, which raises BlockingIOError when full."""
    import fcntl
    import io
    import os
    import threading
    import time

    from neurotac_cli.whole import flush_whole, write_whole

    read, write = os.pipe()
    fcntl.fcntl(write, fcntl.F_SETFL, fcntl.fcntl(write, fcntl.F_GETFL) | os.O_NONBLOCK)
    data = bytes(range(256)) * 2048  # 512 KiB, eight pipes full
    raw = io.FileIO(write, "w")
    sink = io.BufferedWriter(raw)

    def write_all():
        try:
            write_whole(sink, memoryview(data))
            flush_whole(sink)
        finally:  # the reader's end of file, whatever happened
            raw.close()

    writer = threading.Thread(target=write_all)
    writer.start()
    time.sleep(0.5)
    got = b""
    while chunk := os.read(read, 4096):  # slowly, so that the flush too meets a full pipe
        got += chunk
        time.sleep(0.0005)
    writer.join(timeout=30)
    os.close(read)
    assert got == data


def test_help_to_a_reader_that_has_gone_is_quiet():
    import os

    read, write = os.pipe()
    os.close(read)
    done = subprocess.run(["neurotac"], stdout=write, capture_output=False, stderr=subprocess.PIPE, text=True)
    os.close(write)
    assert (done.returncode, done.stderr) == (0, "")


def test_a_deleted_working_folder_is_said_in_one_line_before_any_work(tmp_path):
    frames = small_frames(tmp_path)
    done = shell(f"mkdir gone && cd gone && rmdir ../gone && neurotac select --where true {frames} -o {tmp_path / 'k.arrows'}", tmp_path)
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("neurotac select: error: the working folder no longer exists")
    assert not (tmp_path / "k.arrows").exists()


@pytest.mark.parametrize("number, code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_raised_inside_a_callback_python_drops_is_sent_again(tmp_path, number, code):
    """Raised in a weak reference's callback (the import system's module locks), a signal's exception
    is printed and dropped by Python: a run went on to its end, exit 0."""
    script = tmp_path / "lost.py"
    script.write_text(
        "import os, signal, sys, weakref\nfrom neurotac_cli import cli\n\n"
        "class Thing:\n    pass\n\n\n"
        f"def callback(reference):\n    os.kill(os.getpid(), signal.{number})\n"
        "    for _ in range(1000):  # the handler runs here, inside the callback\n        pass\n\n\n"
        "cli._end_on_sigterm()\nthing = Thing()\nreference = weakref.ref(thing, callback)\n"
        "try:\n    del thing\n    for _ in range(10**7):\n        pass\n"
        "except KeyboardInterrupt as error:\n    sys.exit(143 if isinstance(error, cli.Terminated) else 130)\n"
        "sys.exit(0)\n")
    ended = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60)
    assert ended.returncode == code and "Exception ignored" not in ended.stderr, ended.stderr


def test_a_run_that_ends_before_a_dropped_signal_is_sent_again_ends_as_that_signal_s(monkeypatch, capsys):
    """The signal is sent again 10 ms later: a run that ended first exited 0 without a word."""
    import threading
    import types

    from neurotac_cli import cli as root

    timers = []
    monkeypatch.setattr(threading, "Timer", lambda delay, function: types.SimpleNamespace(start=lambda: timers.append(function)))
    monkeypatch.setattr(root, "_DROPPED", [])
    root._signal_again(types.SimpleNamespace(exc_value=root.Terminated()))
    with pytest.raises(SystemExit) as ended:
        root._end_if_dropped()
    assert ended.value.code == 143 and "neurotac: terminated" in capsys.readouterr().err
    timers[0]()  # the timer, later: nothing left to send
    root._end_if_dropped()  # and nothing left to end on
