"""Tables that went through DuckDB, Polars or evlib come back as neurotac tables, and score the same."""

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from neurotac_cli import model as models, schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.errors import SchemaError
from neurotac_cli.model import evaluate
from tests.model.helpers import tiny_frames

duckdb = pytest.importorskip("duckdb")


def duckdb_copy(source, target, where="true"):
    duckdb.connect().execute(f"COPY (SELECT * FROM '{source}' WHERE {where}) TO '{target}' (FORMAT parquet)")


def counts_of(table):
    return sch.counts_numpy(table.column("counts"))


def test_duckdb_copy_of_square_frames_reads_back_equal(tmp_path):
    frames = tiny_frames(trials=3)
    pq.write_table(frames, tmp_path / "f.parquet")
    duckdb_copy(tmp_path / "f.parquet", tmp_path / "d.parquet")
    assert pa.types.is_list(pq.read_schema(tmp_path / "d.parquet").field("counts").type)  # what DuckDB writes
    back = tables.read([str(tmp_path / "d.parquet")], kind="frames")
    np.testing.assert_array_equal(counts_of(back), counts_of(frames))
    assert sch.sensor_of(back.schema) == (9, 9)


def test_flat_counts_of_a_frame_that_is_not_square_need_the_size(tmp_path, monkeypatch):
    frames = tiny_frames(trials=2, size=(8, 9))
    pq.write_table(frames.replace_schema_metadata(None), tmp_path / "f.parquet")
    duckdb_copy(tmp_path / "f.parquet", tmp_path / "d.parquet")
    refused = CliRunner().invoke(cli, ["info", str(tmp_path / "d.parquet")])
    assert refused.exit_code == 1 and "give it: neurotac --frame-size WxH" in refused.output
    monkeypatch.setenv("NEUROTAC_FRAME_SIZE", "")  # restored after the test: --frame-size sets it for the process
    given = CliRunner().invoke(cli, ["--frame-size", "9x8", "info", "--json", str(tmp_path / "d.parquet")])
    assert given.exit_code == 0 and '"frame_shape": [\n    2,\n    8,\n    9\n  ]' in given.output
    np.testing.assert_array_equal(counts_of(tables.read([str(tmp_path / "d.parquet")])), counts_of(frames))
    monkeypatch.setenv("NEUROTAC_FRAME_SIZE", "10x10")
    with pytest.raises(SchemaError, match="row 0 hold 144 values, expected 200"):
        tables.read([str(tmp_path / "d.parquet")])


def test_metadata_gives_the_size_of_flat_counts(tmp_path):
    frames = tiny_frames(trials=2, size=(8, 9))
    flat = frames.set_column(frames.schema.get_field_index("counts"), "counts",
                             pa.array(list(counts_of(frames).reshape(len(frames), -1)), pa.list_(pa.uint16())))
    tables.write(str(tmp_path / "flat.arrows"), flat)
    np.testing.assert_array_equal(counts_of(tables.read([str(tmp_path / "flat.arrows")])), counts_of(frames))


def test_nested_fixed_size_lists_carry_their_shape(tmp_path):
    frames = tiny_frames(trials=2, size=(8, 9))
    values = pa.array(counts_of(frames).reshape(-1).astype(np.int64))
    nested = pa.FixedSizeListArray.from_arrays(pa.FixedSizeListArray.from_arrays(pa.FixedSizeListArray.from_arrays(values, 9), 8), 2)
    table = frames.set_column(frames.schema.get_field_index("counts"), "counts", nested).replace_schema_metadata(None)
    pq.write_table(table, tmp_path / "n.parquet")
    back = tables.read([str(tmp_path / "n.parquet")], kind="frames")
    np.testing.assert_array_equal(counts_of(back), counts_of(frames))


def test_polars_round_trip_reads_back_equal(tmp_path):
    pl = pytest.importorskip("polars")
    frames = tiny_frames(trials=2)
    pq.write_table(frames, tmp_path / "f.parquet")
    pl.read_parquet(tmp_path / "f.parquet").filter(pl.col("frame") < 6).write_parquet(tmp_path / "p.parquet")
    back = tables.read([str(tmp_path / "p.parquet")], kind="frames")
    np.testing.assert_array_equal(counts_of(back), counts_of(frames)[np.tile(np.arange(12) < 6, 2)])


def test_frames_through_duckdb_and_polars_score_the_same_in_eval(tmp_path):
    pl = pytest.importorskip("polars")
    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("tdnn", epochs=2), seed=0)
    _, expected = evaluate.evaluate_model(model, frames)
    pq.write_table(frames, tmp_path / "f.parquet")
    duckdb_copy(tmp_path / "f.parquet", tmp_path / "d.parquet")
    pl.read_parquet(tmp_path / "d.parquet").write_parquet(tmp_path / "dp.parquet")  # DuckDB, then Polars
    for path in ("d.parquet", "dp.parquet"):
        _, rows = evaluate.evaluate_model(model, tables.read([str(tmp_path / path)], kind="frames"))
        assert rows == expected


def test_frames_through_pandas_score_the_same_in_eval(tmp_path):
    pytest.importorskip("pandas")
    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("tdnn", epochs=2), seed=0)
    _, expected = evaluate.evaluate_model(model, frames)
    frame = frames.to_pandas()  # counts become flat numpy arrays, one per row
    frame.to_parquet(tmp_path / "p.parquet")
    back = tables.read([str(tmp_path / "p.parquet")], kind="frames")
    assert back.schema.field("counts").type == frames.schema.field("counts").type
    _, rows = evaluate.evaluate_model(model, back)
    assert rows == expected


def test_evlib_events_with_a_duration_and_signed_polarity(tmp_path):
    t = pa.array([1_000, 2_500, 4_000], pa.duration("us"))
    evlib = pa.table({"x": pa.array([1, 2, 3], pa.int16()), "y": pa.array([0, 1, 2], pa.int16()), "t": t,
                      "polarity": pa.array([-1, 1, -1], pa.int8())})
    pq.write_table(evlib, tmp_path / "e.parquet")
    events = tables.read([str(tmp_path / "e.parquet")], kind="events")
    assert events.column("t").to_pylist() == [1_000, 2_500, 4_000] and events.column("p").to_pylist() == [0, 1, 0]
    nanoseconds = evlib.set_column(2, "t", pa.array([1_000_999, 2_000_000, 3_000_001], pa.duration("ns")))
    pq.write_table(nanoseconds, tmp_path / "ns.parquet")
    assert tables.read([str(tmp_path / "ns.parquet")], kind="events").column("t").to_pylist() == [1_000, 2_000, 3_000]


def test_an_evlib_events_file_frames_from_the_command_line(tmp_path):
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, 50_000, 200))
    evlib = pa.table({"x": rng.integers(0, 8, 200).astype(np.int16), "y": rng.integers(0, 6, 200).astype(np.int16),
                      "t": pa.array(t, pa.duration("us")), "polarity": rng.choice([-1, 1], 200).astype(np.int8)})
    pq.write_table(evlib, tmp_path / "e.parquet")
    code = "from neurotac_cli.cli import main; main()"
    done = subprocess.run([sys.executable, "-c", code, "frame", "--window", "10ms", "--sensor", "8x6", str(tmp_path / "e.parquet"),
                           "-o", str(tmp_path / "f.arrows")], capture_output=True)
    assert done.returncode == 0, done.stderr
    assert counts_of(tables.read([str(tmp_path / "f.arrows")])).sum() == 200


def test_faery_csv_with_its_sensor_in_the_header_and_crlf_lines(tmp_path):
    from neurotac_cli.io.events import read_events_table

    (tmp_path / "faery.csv").write_bytes(b"t,x@346,y@260,on\r\n10,1,2,1\r\n20,345,259,0\r\n35,3,4,1\r\n")
    events = read_events_table(str(tmp_path / "faery.csv"))
    assert sch.sensor_of(events.schema) == (346, 260)
    assert [events.column(n).to_pylist() for n in "txyp"] == [[10, 20, 35], [1, 345, 3], [2, 259, 4], [1, 0, 1]]


@pytest.mark.parametrize("size", ["10x10", "7x7"])
def test_fixed_size_lists_of_another_frame_size_are_refused_in_one_line(tmp_path, monkeypatch, size):
    frames = tiny_frames(trials=2, size=(8, 9))
    flat = frames.set_column(frames.schema.get_field_index("counts"), "counts",
                             pa.FixedSizeListArray.from_arrays(pa.array(counts_of(frames).ravel()), 2 * 8 * 9))
    pq.write_table(flat.replace_schema_metadata(None), tmp_path / "f.parquet")
    monkeypatch.setenv("NEUROTAC_FRAME_SIZE", "")
    refused = CliRunner().invoke(cli, ["--frame-size", size, "info", str(tmp_path / "f.parquet")])
    assert refused.exit_code == 1 and "row 0 hold 144 values" in refused.output and "Traceback" not in refused.output


def _flat(frames):
    return frames.set_column(frames.schema.get_field_index("counts"), "counts",
                             pa.array(list(counts_of(frames).reshape(len(frames), -1)), pa.list_(pa.uint16())))


def test_a_frame_size_given_against_the_tables_own_is_refused(tmp_path, monkeypatch):
    tables.write(str(tmp_path / "flat.arrows"), _flat(tiny_frames(trials=2, size=(6, 6))))  # 72 values: 4x9 would reshape them
    monkeypatch.setenv("NEUROTAC_FRAME_SIZE", "9x4")
    with pytest.raises(SchemaError, match=r"--frame-size 9x4 \(NEUROTAC_FRAME_SIZE\) contradicts the table's own frame size 6x6"):
        tables.read([str(tmp_path / "flat.arrows")])
    monkeypatch.setenv("NEUROTAC_FRAME_SIZE", "6x6")  # agreeing with it is no conflict
    assert tables.read([str(tmp_path / "flat.arrows")]).num_rows == 24


def test_flat_counts_of_mixed_sizes_name_the_first_row_of_another_size_in_a_later_batch(tmp_path, monkeypatch):
    small, large = _flat(tiny_frames(trials=1, size=(4, 4))), _flat(tiny_frames(trials=1, size=(5, 5), seed=1))
    import pyarrow.ipc as ipc

    with pa.OSFile(str(tmp_path / "mixed.arrows"), "wb") as sink:
        writer = ipc.new_stream(sink, small.replace_schema_metadata(None).schema)
        for part in (small, large):
            writer.write_table(part.replace_schema_metadata(None))
        writer.close()
    monkeypatch.setenv("NEUROTAC_FRAME_SIZE", "")
    with pytest.raises(SchemaError, match=r"row 12 hold 50 values where the rows before it hold 32 \(2x4x4\): the table mixes frame sizes"):
        tables.read([str(tmp_path / "mixed.arrows")])
