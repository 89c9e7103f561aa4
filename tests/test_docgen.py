"""The command pages in docs/commands carry each command's --help text as it is now."""

import pathlib

import pytest

from neurotac_cli import docgen

DOCS = pathlib.Path(__file__).resolve().parent.parent / "docs" / "commands"


@pytest.mark.parametrize("path,name", sorted(docgen.pages(DOCS).items(), key=lambda item: str(item[0])), ids=lambda v: str(v))
def test_command_page_matches_help(path, name):
    assert path.exists(), f"{path} is missing: run `make docs`"
    page = path.read_text()
    assert docgen.render(page, name) == page, f"{path} has drifted from --help: run `make docs`"


def test_every_option_has_help():
    import click

    from neurotac_cli.cli import cli

    context = click.Context(cli, info_name="neurotac")
    for name in cli.list_commands(context):
        command = cli.get_command(context, name)
        for param in command.params:
            if isinstance(param, click.Option):
                assert param.help, f"neurotac {name} {param.opts[0]} has no help text"
