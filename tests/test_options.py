"""Shared options: the history a command records comes from its parsed parameters, and contradicting
options are one usage line with exit 2."""

import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch
from neurotac_cli import tables
from neurotac_cli.cli import cli
from tests.model.helpers import tiny_frames, write_stream


def test_history_holds_the_parameters_the_output_depends_on_and_not_where_it_went(tmp_path):
    frames = write_stream(tiny_frames(trials=2), tmp_path / "f.arrows")
    written = []
    for name in ("a.arrows", "b.arrows"):
        done = CliRunner().invoke(cli, ["crop", "--pool", "all", "--box", "1,1,6,6", str(frames), "-o", str(tmp_path / name)])
        assert done.exit_code == 0, done.output
        written.append(sch.get_meta(tables.read([str(tmp_path / name)]).schema, sch.HISTORY)[-1])
    step = written[0]
    assert step["command"] == "crop" and written[0]["args"] == written[1]["args"]
    assert step["args"]["pool"] == "all" and step["args"]["box"] == [1, 1, 6, 6] and step["args"]["warn_above"] == 0.9
    assert step["args"]["report"]["box"] == [1, 1, 6, 6]  # a streamed crop counts what it cut on stderr
    assert "cut " in done.output and " events (counted in frames)" in done.output
    assert "output" not in step["args"] and "center" not in step["args"]  # where it went; an option not given


def test_contradicting_options_are_one_usage_line_and_exit_2():
    done = CliRunner().invoke(cli, ["eval", "--grid", "layers=1,2"])
    assert done.exit_code == 2
    assert done.output.strip().splitlines() == [
        "neurotac eval: error: --grid needs --cv and --model-spec (a grid of cross-validated models) (see `neurotac eval --help`)"]


def test_an_output_path_accepts_every_suffix_the_writer_writes():
    from neurotac_cli import tables
    from neurotac_cli.options import TablePath

    assert set(TablePath.SUFFIXES) == set(tables.SUFFIXES)


def test_threads_below_1_and_negative_jobs_are_usage_errors():
    for args in (["predict", "--model", "m.model", "--threads", "0"], ["train", "--model", "tdnn", "--threads", "-1"],
                 ["eval", "--model", "m.model", "--threads", "0"], ["study", "--model-spec", "tdnn", "--jobs", "-1"],
                 ["eval", "--cv", "loo", "--model-spec", "tdnn", "-j", "-2"]):
        result = CliRunner().invoke(cli, args, input=b"")
        assert result.exit_code == 2 and "is not in the range" in result.output, (args, result.output)


def test_a_duration_takes_an_exponent_and_says_which_part_it_could_not_read():
    from neurotac_cli.errors import NeurotacError
    from neurotac_cli.units import parse_duration_us

    assert parse_duration_us("2e-3s") == 2_000 and parse_duration_us("1e1ms") == 10_000
    with pytest.raises(NeurotacError, match="its number is not one"):
        parse_duration_us("1.5.2ms")
    with pytest.raises(NeurotacError, match="a duration carries its unit"):
        parse_duration_us("10")
    with pytest.raises(NeurotacError, match="beyond any clock"):
        parse_duration_us("1e400s")
