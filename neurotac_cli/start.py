"""The `neurotac` command's entry point: the standard library alone, so that Ctrl-C and SIGTERM are
held from the command's first line, before click and the verb's modules are imported."""

import sys

from neurotac_cli.held import HeldSignals


def main():
    """Run the command line. A Ctrl-C or SIGTERM while it starts (importing click and the command
    group: 0.1 s and more on a busy machine) was raised inside an import and ended the run with
    Python's traceback; held, it ends the run with the verb's one line (exit 130 or 143), as one
    that comes later does."""
    held = HeldSignals()
    from neurotac_cli.cli import cli, end_as_signal, named_verb

    number = held.end()
    if number is not None:
        verb = named_verb()
        end_as_signal(number, f"neurotac{' ' + verb if verb else ''}")
    sys.exit(cli(prog_name="neurotac"))
