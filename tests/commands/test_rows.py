"""select, concat, split: rows by a condition, tables joined with checks, trials split whole."""

import re
import subprocess

import numpy as np
import pyarrow as pa
import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.errors import NeurotacError, SchemaError, UsageError
from neurotac_cli.ops.rows import concat, select, split
from tests.model.helpers import tiny_frames


def test_select_keeps_tensors_and_metadata_and_drops_null_conditions():
    frames = tiny_frames(trials=4)
    kept, report = select(frames, "object = 'small' AND frame BETWEEN 2 AND 4")
    assert report == {"kept": 6, "dropped": 42}
    assert kept.schema.equals(frames.schema, check_metadata=True)
    assert set(kept.column("trial").to_pylist()) == {"t0", "t2"} and set(kept.column("frame").to_pylist()) == {2, 3, 4}
    nulls = frames.set_column(frames.schema.get_field_index("object"), "object", pa.array([None] * frames.num_rows, pa.string()))
    with pytest.raises(NeurotacError, match="no row matches --where \"object <> 'small'\""):
        select(nulls, "object <> 'small'")


def test_select_with_a_window_function_keeps_the_rows_it_names():
    # DuckDB returns a window function's rows in its own order: the answer must still land on the right rows
    frames = tiny_frames(trials=3)
    force = frames.column("force").to_numpy()
    kept, _ = select(frames, "row_number() OVER (ORDER BY force DESC) <= 4")
    assert sorted(kept.column("force").to_pylist(), reverse=True) == pytest.approx(np.sort(force)[::-1][:4])
    last, _ = select(frames, "frame = max(frame) OVER (PARTITION BY trial)")
    assert last.column("frame").to_pylist() == [11, 11, 11]


@pytest.mark.parametrize("expression, words", [("frame <", "syntax error"), ("size > 1", 'column "size" not found'),
                                               ("frame + 1", "is not a condition"), ("read_csv('/etc/passwd') IS NULL", "cannot evaluate"),
                                               ("sum(frame) > 0", "not a condition on each row"), ("  ", "empty"),
                                               ("frame < 3 -- the start", "cannot hold `--`"),
                                               ("'yes'", "gives VARCHAR values"), ("material", "gives VARCHAR values")])
def test_select_refuses_what_it_cannot_evaluate(expression, words):
    with pytest.raises(NeurotacError, match=words):
        select(tiny_frames(trials=2), expression)


@pytest.mark.parametrize("expression, words", [("random() < 0.5", "calls random()"), ("frame < 3 AND RANDOM() < 0.5", "calls random()"),
                                               ("uuid() IS NOT NULL", "calls uuid()"), ("now() > TIMESTAMP '2000-01-01'", "calls now()"),
                                               ("current_date > DATE '2000-01-01'", "calls current_date"),
                                               ("frame IN (SELECT frame FROM input_rows USING SAMPLE 50%)", "samples rows")])
def test_select_refuses_a_condition_whose_answer_changes_from_run_to_run(expression, words):
    with pytest.raises(UsageError, match=re.escape(words)):
        select(tiny_frames(trials=2), expression)
    assert select(tiny_frames(trials=2), "object <> 'random()'")[1]["kept"] > 0  # a string is not a call


def test_select_command_refuses_a_condition_no_row_matches_in_one_line(tmp_path):
    path = str(tmp_path / "f.arrows")
    tables.write(path, tiny_frames(trials=2))
    result = CliRunner().invoke(cli, ["select", "--where", "frame < 0", path, "-o", str(tmp_path / "s.arrows")])
    assert result.exit_code == 1 and result.stderr.count("\n") == 1 and "no row matches --where 'frame < 0'" in result.stderr
    assert not (tmp_path / "s.arrows").exists()


def test_concat_refuses_a_trial_twice_or_renames_it():
    frames = tiny_frames(trials=2)
    with pytest.raises(SchemaError, match="trial 't0' is in both a and b"):
        concat([("a", frames), ("b", frames)])
    table, notes = concat([("a", frames), ("b", frames), ("c", frames)], rename=True)
    assert sorted(set(table.column("trial").to_pylist())) == ["t0", "t0~2", "t0~3", "t1", "t1~2", "t1~3"]
    assert len(notes) == 2 and table.schema.equals(frames.schema, check_metadata=True)


def test_concat_refuses_frames_of_another_window():
    with pytest.raises(SchemaError, match="frame window"):
        concat([("a", tiny_frames(trials=1)), ("b", tiny_frames(trials=1, seed=1, window_us=7000))])


def test_concat_refuses_frames_that_do_not_record_their_window_beside_frames_that_do():
    known = tiny_frames(trials=1)
    unknown = tiny_frames(trials=1, seed=1, window_us=7000)
    unknown = unknown.replace_schema_metadata({k: v for k, v in unknown.schema.metadata.items() if k != sch.WINDOW.encode()})
    for parts in ([("a", known), ("b", unknown)], [("b", unknown), ("a", known)]):
        with pytest.raises(SchemaError, match="b does not record its frame window"):
            concat(parts)


def test_several_inputs_read_as_one_refuse_frames_without_a_window_beside_frames_with_one(tmp_path):
    known = tiny_frames(trials=1)
    unknown = tiny_frames(trials=1, seed=1)
    unknown = unknown.replace_schema_metadata({k: v for k, v in unknown.schema.metadata.items() if k != sch.WINDOW.encode()})
    tables.write(str(tmp_path / "a.arrows"), known)
    tables.write(str(tmp_path / "b.arrows"), unknown)
    with pytest.raises(SchemaError, match="different windows \\(10000 µs vs no recorded window\\)"):
        tables.read([str(tmp_path / "a.arrows"), str(tmp_path / "b.arrows")], kind="frames")


def test_split_by_fraction_is_seeded_keeps_copies_with_their_source_and_stratifies():
    frames = tiny_frames(trials=8, augmented_copies=1)
    train, test, report = split(frames, fraction=0.25, per="object", seed=3)
    again = split(frames, fraction=0.25, per="object", seed=3)[2]
    assert report["test"] == again["test"] and len(report["test"]) == 2
    test_sources = set(test.column("source_trial").to_pylist())
    assert not test_sources & set(train.column("source_trial").to_pylist())
    assert {"small", "large"} == set(test.column("object").to_pylist())  # one trial of each object
    assert train.num_rows + test.num_rows == frames.num_rows


def test_split_by_a_condition_and_refusals():
    frames = tiny_frames(trials=4)
    train, test, _ = split(frames, where="object = 'large'")
    assert set(test.column("trial").to_pylist()) == {"t1", "t3"}
    with pytest.raises(NeurotacError, match="leaves the test table empty"):
        split(frames, where="object = 'huge'")
    with pytest.raises(NeurotacError, match="either --fraction"):
        split(frames)
    with pytest.raises(UsageError, match="--where chooses the test trials itself"):
        split(frames, where="object = 'large'", per="object")
    with pytest.raises(NeurotacError, match="every --per group holds one trial"):
        split(frames, fraction=0.5, per="trial")


def test_split_command_writes_both_tables(tmp_path):
    source = str(tmp_path / "f.arrows")
    tables.write(source, tiny_frames(trials=4))
    result = CliRunner().invoke(cli, ["split", source, "--fraction", "0.5", "--train", str(tmp_path / "a.parquet"),
                                      "--test", str(tmp_path / "b.parquet")])
    assert result.exit_code == 0, result.output
    a, b = tables.read([str(tmp_path / "a.parquet")]), tables.read([str(tmp_path / "b.parquet")])
    assert a.num_rows == b.num_rows == 24 and sch.get_meta(b.schema, sch.HISTORY)[-1]["args"]["part"] == "test"


def test_split_refuses_an_unknown_suffix_before_writing_either_table(tmp_path):
    source = str(tmp_path / "f.arrows")
    tables.write(source, tiny_frames(trials=4))
    result = CliRunner().invoke(cli, ["split", source, "--fraction", "0.5", "--train", str(tmp_path / "a.arrows"),
                                      "--test", str(tmp_path / "b.txt")])
    assert result.exit_code == 2 and "--test" in result.output and not (tmp_path / "a.arrows").exists()


def test_split_writes_its_file_before_a_stdout_that_closes_early(tmp_path):
    source = str(tmp_path / "f.arrows")
    tables.write(source, tiny_frames(trials=4, size=(120, 120)))  # more than a pipe holds
    done = subprocess.run(f"neurotac split {source} --fraction 0.5 --train - --test {tmp_path}/b.arrows | head -c 100 > {tmp_path}/head.bin",
                          shell=True, executable="/bin/bash", capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and tables.read([str(tmp_path / "b.arrows")]).num_rows == 24, done.stderr


def test_a_new_users_workflow_by_shell_pipes(tmp_path):
    """A folder of simulated grasps to a drawn montage, a selection, a split, a model and CSV predictions."""
    script = f"""
    set -euo pipefail
    cd {tmp_path}
    neurotac simulate --preset ch4 --trials 6 --seed 5 --out sim 2>/dev/null
    neurotac sync --manifest sim/manifest.csv | neurotac frame --window 10ms \\
      | neurotac crop --size 60x60 --center auto --pool 2x2 > frames.arrows 2>/dev/null
    neurotac render frames.arrows --every 4 -o montage.png 2>/dev/null
    neurotac select --where "phase IS NOT NULL" frames.arrows 2>/dev/null \\
      | neurotac split --fraction 0.34 --seed 1 --train train.arrows --test test.arrows 2>/dev/null
    neurotac train --model tdnn --epochs 2 train.arrows -o force.model 2>/dev/null
    neurotac eval --model force.model test.arrows -o predictions.csv 2>/dev/null
    head -1 predictions.csv
    """
    done = subprocess.run(["bash", "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().startswith('"trial","frame","t"') and "force_pred" in done.stdout
    assert (tmp_path / "montage.png").stat().st_size > 0
    assert oct((tmp_path / "force.model").stat().st_mode & 0o077) == oct((tmp_path / "frames.arrows").stat().st_mode & 0o077)
    counts = np.loadtxt(tmp_path / "predictions.csv", delimiter=",", skiprows=1, usecols=(1,))
    assert len(counts) > 0


def test_concat_names_the_column_that_differs():
    frames = tiny_frames(trials=2)
    other = tiny_frames(trials=2).drop_columns(["object"])
    other = other.set_column(0, "trial", pa.array([f"x{t}" for t in other.column("trial").to_pylist()]))
    with pytest.raises(SchemaError, match="b has no object"):
        concat([("a", frames), ("b", other)])


def test_concat_refuses_events_tables_whose_clocks_would_run_on_as_one(tmp_path):
    path = str(tmp_path / "e.arrows")
    tables.write(path, sch.events_table(np.arange(3), np.array([1, 2, 3]), np.array([1, 2, 3]), np.array([0, 1, 0]), 8, 8))
    result = CliRunner().invoke(cli, ["concat", path, path, "-o", str(tmp_path / "both.arrows")])
    assert result.exit_code == 1 and "one recording on one clock" in result.stderr and not (tmp_path / "both.arrows").exists()
    assert CliRunner().invoke(cli, ["concat", path, "-o", str(tmp_path / "one.arrows")]).exit_code == 0


def test_split_replaces_neither_table_when_the_second_cannot_be_written(tmp_path):
    # the training table used to be replaced before the test table failed: a trial on both sides of a split
    tables.write(str(tmp_path / "in.arrows"), tiny_frames(trials=8))
    (tmp_path / "train.arrows").write_bytes(b"old train")
    (tmp_path / "test.arrows").write_bytes(b"old test")
    size = (tmp_path / "in.arrows").stat().st_size
    limit_kb = size // 2 // 1024  # the training eighth fits, the test seven eighths do not
    done = subprocess.run(["bash", "-c", f"ulimit -f {limit_kb}; neurotac split --fraction 0.875 --seed 1 "
                           "--train train.arrows --test test.arrows in.arrows"], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert "cannot write test.arrows" in done.stderr
    assert (tmp_path / "train.arrows").read_bytes() == b"old train"
    assert (tmp_path / "test.arrows").read_bytes() == b"old test"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.arrows", "test.arrows", "train.arrows"]
