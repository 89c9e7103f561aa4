"""`neurotac info` on every table kind and on camera files: one describe() dict, text and JSON."""

import json
import re

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from click.testing import CliRunner

from neurotac_cli import schema as sch
from neurotac_cli.cli import cli
from neurotac_cli.describe import describe, format_text
from tests.conftest import real_file


def described(table: pa.Table) -> dict:
    return describe(table.schema, table.to_batches(max_chunksize=3))


def info_cli(tmp_path, table, *args):
    path = tmp_path / "t.parquet"
    pq.write_table(table, path)
    result = CliRunner().invoke(cli, ["info", str(path), *args], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


def test_events_rows_span_rate_and_on_share(tmp_path):
    table = sch.events_table([100, 200, 150, 1_000_100], [0, 1, 2, 3], [0, 1, 1, 0], [1, 1, 0, 1], 4, 2)
    info = described(table)
    assert info["kind"] == "events" and info["rows"] == 4 and info["trials"] == 1
    assert info["sensor"] == {"width": 4, "height": 2}
    assert info["span_us"] == 1_000_000 and info["event_rate_per_s"] == 4.0
    assert info["on_share"] == 0.75 and info["backward_steps"] == 1 and info["largest_backward_step_us"] == 50
    text = info_cli(tmp_path, table)
    assert "4x2" in text and re.search(r"ON\ share\s+0\.750", text) and "1 backward steps, the largest 50 µs" in text


def test_recordings_per_trial_events_force_and_labels(tmp_path):
    trials = [
        {"trial": "a", "t0": 10, "events": ([0, 5, 9], [1, 2, 3], [0, 0, 1], [1, 0, 1]), "force": ([0, 2000], [0.0, 1.5]), "labels": {"material": "foam"}},
        {"trial": "b", "t0": 99, "events": ([1], [0], [0], [0]), "force": ([0], [0.25]), "labels": {"material": "steel"}},
    ]
    table = sch.recordings_table(trials, width=4, height=2)
    info = described(table)
    assert info["kind"] == "recordings" and info["trials"] == 2 and info["events"] == 4
    assert info["labels"] == {"material": ["foam", "steel"]}
    first = info["per_trial"][0]
    assert first == {"trial": "a", "t0_us": 10, "events": 3, "span_us": 9, "on_share": 2 / 3, "force_samples": 2, "force_max_n": 1.5, "labels": {"material": "foam"}}
    text = info_cli(tmp_path, table)
    assert "label material" in text and re.search(r"a\s+3\ events", text) and "material=steel" in text


def test_each_trial_shows_how_well_it_was_synced(tmp_path):
    trials = [{"trial": name, "t0": 10, "events": ([0], [0], [0], [0]), "force": ([0], [0.0])} for name in ("a", "b")]
    sync = {"method": "xcorr", "median_us": 10_000, "trials": {"a": {"t0": 10, "score": 0.8123, "uncertainty_us": 6500},
                                                               "b": {"t0": 10, "score": 0.95, "uncertainty_us": 1875}}}
    text = info_cli(tmp_path, sch.recordings_table(trials, width=4, height=2, sync=sync))
    assert re.search(r"sync\s+\{\"median_us\":10000,\"method\":\"xcorr\"\}", text)  # settings; trials on their lines
    assert re.search(r"\ba\s.*sync xcorr r 0\.812 ±6\.5 ms", text) and re.search(r"\bb\s.*sync xcorr r 0\.95 ±1\.9 ms", text)
    led = {"method": "led", "trials": {"a": {"t0": 10, "score": 412.6}, "b": {"t0": 10, "score": 98.0}}}
    text = info_cli(tmp_path, sch.recordings_table(trials, width=4, height=2, sync=led))
    assert re.search(r"\ba\s.*sync led z 413", text) and "±" not in text


def test_frames_per_trial_window_phases_and_counts(tmp_path):
    counts = np.zeros((5, 2, 3, 4), dtype=np.uint16)
    counts[:, 1] = 1  # 12 ON per frame
    counts[:, 0, 0, 0] = 4  # 4 OFF per frame
    schema = sch.frames_schema(3, 4, labels=["material"], window_us=10_000)
    table = pa.Table.from_pydict(
        {
            "trial": ["a", "a", "a", "b", "b"],
            "frame": pa.array([0, 1, 2, 0, 1], pa.int32()),
            "t": pa.array([0, 10_000, 20_000, 0, 10_000], pa.int64()),
            "counts": sch.counts_array(counts),
            "force": pa.array([0.0, 1.0, None, 0.5, 2.0], pa.float32()),
            "phase": ["grasping", "holding", "releasing", "grasping", None],
            "material": ["foam", "foam", "foam", "rubber", "rubber"],
        },
        schema=schema,
    )
    info = described(table)
    assert info["kind"] == "frames" and info["trials"] == 2 and info["window_us"] == 10_000
    assert info["frames_per_trial"] == {"min": 2, "max": 3, "mean": 2.5}
    assert info["frame_shape"] == [2, 3, 4] and info["on_share"] == 12 / 16
    assert info["phases"] == {"grasping": 2, "holding": 1, "none": 1, "releasing": 1}
    assert info["force_range_n"] == [0.0, 2.0]
    text = info_cli(tmp_path, table)
    assert re.search(r"window\s+10\.000\ ms", text) and re.search(r"frames/trial\s+2\.\.3", text)


def test_predictions_and_metrics(tmp_path):
    predictions = pa.table({"trial": ["a", "a", "b"], "frame": pa.array([0, 1, 0], pa.int32()), "force_pred": [0.1, 0.2, 0.3]})
    predictions = predictions.replace_schema_metadata(sch.set_meta(predictions.schema, kind="predictions").metadata)
    assert described(predictions)["trials"] == 2
    metrics = pa.table({"scope": ["all", "all"], "metric": ["mse", "mae"], "value": [0.17, 0.3], "model": ["m", "m"]})
    metrics = metrics.replace_schema_metadata(sch.set_meta(metrics.schema, kind="metrics").metadata)
    info = described(metrics)
    assert info["kind"] == "metrics" and [m["metric"] for m in info["metrics"]] == ["mse", "mae"]
    assert "all  mse  0.17" in info_cli(tmp_path, metrics)


def test_predictions_are_scored_against_the_truth_they_carry(tmp_path):
    force = pa.table({"trial": ["a", "a", "b", "b"], "force": pa.array([1.0, 2.0, 0.0, 4.0], pa.float32()),
                      "force_pred": pa.array([1.5, 2.0, 0.0, 3.5], pa.float32())})
    force = force.replace_schema_metadata(sch.set_meta(force.schema, kind="predictions").metadata)
    error = described(force)["force_error"]
    assert error["frames"] == 4 and np.isclose(error["rmse_n"], np.sqrt(0.5 / 4)) and np.isclose(error["mae_n"], 0.25)
    classes = pa.table({"trial": ["a", "b", "c"], "material": ["foam", "steel", None], "material_pred": ["foam", "foam", "steel"]})
    classes = classes.replace_schema_metadata(sch.set_meta(classes.schema, kind="predictions").metadata)
    assert described(classes)["accuracy"] == {"material": {"correct": 1, "trials": 2}}
    assert "material accuracy 50.0% (1 of 2 with a known material)" in info_cli(tmp_path, classes)


def test_a_camera_file_is_decoded_and_described(tmp_path):
    result = CliRunner().invoke(cli, ["info", str(real_file("prophesee_vga_faery.evt2.raw")), "--json"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    assert info["camera_file"]["format"] == "evt2" and info["rows"] == 521_252 and info["sensor"] == {"width": 640, "height": 480}
    assert info["history"] == []
    text = CliRunner().invoke(cli, ["info", str(real_file("atis_ncars_loris.dat"))]).output
    assert "not imported yet" in text and "extent of the events" in text


def test_an_empty_events_table_is_described_not_refused(tmp_path):
    text = info_cli(tmp_path, sch.events_table([], [], [], [], 240, 180))
    assert re.search(r"rows\s+0", text)


def test_history_is_listed(tmp_path):
    table = sch.events_table([1], [0], [0], [1], 2, 2)
    history = [{"command": "import", "args": {"files": ["a.aedat"]}, "version": "0.1.0"}]
    table = table.replace_schema_metadata(sch.set_meta(table.schema, history=history).metadata)
    assert 'import files=["a.aedat"]  (neurotac 0.1.0)' in format_text(described(table))


def test_a_model_file_is_described_from_its_header(tmp_path):
    from neurotac_cli import tables
    from tests.model.helpers import tiny_frames

    tables.write(str(tmp_path / "f.arrows"), tiny_frames(trials=6))
    runner = CliRunner()
    trained = runner.invoke(cli, ["train", "--model", "material-timing", "-o", str(tmp_path / "m.model"), str(tmp_path / "f.arrows")])
    assert trained.exit_code == 0, trained.output
    text = runner.invoke(cli, ["info", str(tmp_path / "m.model")], catch_exceptions=False).output
    assert "material-timing (material)" in text and "classes" in text and "trained on frames made by:" in text
    info = json.loads(runner.invoke(cli, ["info", "--json", str(tmp_path / "m.model")]).output)
    assert info["kind"] == "model" and info["task"] == "material" and info["training"]["trials"] >= 1
    (tmp_path / "cut.model").write_bytes((tmp_path / "m.model").read_bytes()[:8])
    cut = runner.invoke(cli, ["info", str(tmp_path / "cut.model")])
    assert cut.exit_code == 1 and "is not a neurotac model file" in cut.output and "camera format" not in cut.output


def test_a_file_that_cannot_be_read_is_one_line(tmp_path, monkeypatch):
    # the model sniffing opened it first, and a permission error went up as a traceback
    import neurotac_cli.describe as describe_module

    path = tmp_path / "locked.arrows"
    path.write_bytes(b"whatever")

    def refused(name, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(name))

    monkeypatch.setattr(describe_module, "open", refused, raising=False)
    result = CliRunner().invoke(cli, ["info", str(path)])
    assert result.exit_code == 1, result.exception
    assert result.stderr == f"neurotac info: error: {path}: permission denied\n"


def test_a_text_file_that_is_no_csv_is_not_called_a_force_log(tmp_path):
    (tmp_path / "notes.md").write_text("# Notes\n\nA line, with a comma.\nAnother line without one\n")
    result = CliRunner().invoke(cli, ["info", str(tmp_path / "notes.md")])
    assert result.exit_code == 1 and "cannot read the CSV file (" in result.output and "force log" not in result.output
