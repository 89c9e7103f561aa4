"""The root command: help, version, exits."""

import subprocess

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
