"""Keep docs/commands/*.md in step with `--help`.

Each page holds the help text between `<!-- help:start -->` and `<!-- help:end -->`; the rest of the
page (what the command is for, worked examples, pictures) is written by hand. Run
`python -m neurotac_cli.docgen docs/commands` (or `make docs`) after changing an option;
tests/test_docgen.py fails when a page has drifted.
"""

import pathlib
import sys

import click

from neurotac_cli.cli import cli

START, END = "<!-- help:start -->", "<!-- help:end -->"


def help_text(name: str | None) -> str:
    """The --help text of `neurotac NAME` (or of the root group), as a terminal 100 columns wide shows it."""
    args = [name] if name else []
    context = cli.make_context("neurotac", [*args, "--help"], resilient_parsing=True, max_content_width=100, terminal_width=100)
    if name:
        command = cli.get_command(context, name)
        context = click.Context(command, info_name=name, parent=context, max_content_width=100, terminal_width=100)
        return command.get_help(context)
    return cli.get_help(context)


def help_block(name: str | None) -> str:
    title = f"neurotac {name} --help" if name else "neurotac --help"
    return f"{START}\n```text\n$ {title}\n{help_text(name)}\n```\n{END}"


def render(page: str, name: str | None) -> str:
    """The page with its help block replaced (or appended when the page has none yet)."""
    block = help_block(name)
    if START in page and END in page:
        head, rest = page.split(START, 1)
        _, tail = rest.split(END, 1)
        return head + block + tail
    title = f"# neurotac {name}\n\n" if name else "# neurotac\n\n"
    return (page or title) + ("\n" if page and not page.endswith("\n") else "") + "\n## Reference\n\n" + block + "\n"


def pages(folder: pathlib.Path) -> dict[pathlib.Path, str | None]:
    """Page path -> command name for every command in the registry, plus the root page."""
    context = click.Context(cli, info_name="neurotac")
    names = cli.list_commands(context)
    result = {folder / "neurotac.md": None}
    result.update({folder / f"{name}.md": name for name in names})
    return result


def main(argv=None):
    folder = pathlib.Path((argv or sys.argv[1:] or ["docs/commands"])[0])
    folder.mkdir(parents=True, exist_ok=True)
    for path, name in pages(folder).items():
        page = path.read_text() if path.exists() else ""
        updated = render(page, name)
        if updated != page:
            path.write_text(updated)
            print(f"updated {path}", file=sys.stderr)


if __name__ == "__main__":
    main()
