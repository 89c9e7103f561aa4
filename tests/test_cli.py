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
