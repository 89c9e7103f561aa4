"""`-o x.csv|.json|.ndjson`: tables without tensors as text; tensors refused with what to do; `info`
says when it shows part of a table."""

import csv
import json

import numpy as np
import pyarrow as pa
from click.testing import CliRunner

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.errors import NeurotacError


def metrics_table(n=3):
    table = pa.table({"scope": ["all"] * n, "metric": [f"m{i}" for i in range(n)], "value": [0.5, float("nan"), 2.0] * (n // 3),
                      "model": ["tdnn"] * n})
    return table.replace_schema_metadata(sch.set_meta(table.schema, kind="metrics").metadata)


def test_metrics_as_csv_json_and_ndjson_hold_the_same_rows(tmp_path):
    for suffix in ("csv", "json", "ndjson"):
        tables.write(str(tmp_path / f"m.{suffix}"), metrics_table(), step=("eval", {}))
    with open(tmp_path / "m.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["metric"] for row in rows] == ["m0", "m1", "m2"] and rows[2]["value"] == "2"
    as_json = json.loads((tmp_path / "m.json").read_text())
    as_ndjson = [json.loads(line) for line in (tmp_path / "m.ndjson").read_text().splitlines()]
    assert as_json == as_ndjson
    assert as_json[1] == {"scope": "all", "metric": "m1", "value": None, "model": "tdnn"}  # NaN: JSON has none


def test_frames_are_refused_with_what_to_do_and_nothing_is_left(tmp_path):
    frames = pa.table({"trial": ["a"], "frame": pa.array([0], pa.int32()), "t": [0],
                       "counts": sch.counts_array(np.zeros((1, 2, 2, 2), np.uint16))})
    try:
        tables.write(str(tmp_path / "f.csv"), frames)
        raise AssertionError("frames written as CSV")
    except NeurotacError as error:
        assert "column 'counts' holds tensors" in str(error) and "write .parquet" in str(error)
    assert list(tmp_path.iterdir()) == []


def test_recordings_go_to_json_as_arrays_and_are_refused_by_csv(tmp_path):
    recordings = sch.recordings_table([{"trial": "r", "t0": 5, "events": ([1, 2], [0, 1], [0, 0], [1, 0]), "force": ([0], [1.5])}])
    tables.write(str(tmp_path / "r.ndjson"), recordings)
    row = json.loads((tmp_path / "r.ndjson").read_text())
    assert row["events"][1] == {"t": 2, "x": 1, "y": 0, "p": 0} and row["force"] == [{"t": 0, "value": 1.5}]
    try:
        tables.write(str(tmp_path / "r.csv"), recordings)
        raise AssertionError("nested columns written as CSV")
    except NeurotacError as error:
        assert "column 'events' holds nested values" in str(error)


def test_a_command_writes_events_as_csv(tmp_path):
    source = str(tmp_path / "e.arrows")
    tables.write(source, sch.events_table([1, 2, 3], [0, 1, 2], [0, 0, 1], [1, 0, 1], width=4, height=2))
    result = CliRunner().invoke(cli, ["crop", "--box", "0,0,2,2", source, "-o", str(tmp_path / "e.csv")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "e.csv").read_text().splitlines() == ['"t","x","y","p"', "1,0,0,1", "2,1,0,0"]


def test_info_says_how_much_of_the_metrics_it_shows_and_shows_all_when_asked(tmp_path):
    path = str(tmp_path / "m.parquet")
    tables.write(path, metrics_table(300))
    short = CliRunner().invoke(cli, ["info", path]).output
    assert "... 50 of 300 rows shown (all of them: --all" in short
    everything = CliRunner().invoke(cli, ["info", "--all", path]).output
    assert everything.count("(tdnn)") == 300 and "rows shown" not in everything
    assert len(json.loads(CliRunner().invoke(cli, ["info", "--json", "--all", path]).output)["metrics"]) == 300
