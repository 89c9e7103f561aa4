"""`neurotac import` as a user meets it: real pipes, files, DuckDB, and one-line errors with exit 1."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch
from neurotac_cli.cli import cli
from tests.conftest import real_file

BIN = Path(sys.executable).parent
NEUROTAC = str(BIN / "neurotac") if (BIN / "neurotac").exists() else shutil.which("neurotac")


def shell(command: str, cwd=None):
    return subprocess.run(
        ["bash", "-o", "pipefail", "-c", command], capture_output=True, cwd=cwd, timeout=120, env={"PATH": f"{BIN}:/usr/bin:/bin"}
    )


def make(path: Path, data: bytes) -> str:
    path.write_bytes(data)
    return str(path)


def run(args, input=None):
    return CliRunner().invoke(cli, args, input=input, catch_exceptions=False)


def test_pipe_and_parquet_describe_the_same_and_duckdb_counts_the_rows(tmp_path):
    aedat = real_file("davis240c_rotdisk.aedat")
    piped = shell(f"neurotac import {aedat} | neurotac info -")
    assert piped.returncode == 0, piped.stderr
    stored = shell(f"neurotac import {aedat} -o a.parquet && neurotac info a.parquet", cwd=tmp_path)
    assert stored.returncode == 0, stored.stderr
    assert piped.stdout == stored.stdout
    assert b"374,296" in piped.stdout and b"240x180" in piped.stdout
    as_json = shell(f"neurotac import {aedat} | neurotac info - --json")
    assert json.loads(as_json.stdout) == json.loads(shell("neurotac info a.parquet --json", cwd=tmp_path).stdout)
    duckdb = pytest.importorskip("duckdb")
    assert duckdb.sql(f"SELECT count(*) FROM '{tmp_path / 'a.parquet'}'").fetchall() == [(374_296,)]


def test_reader_closing_early_is_quiet_and_successful():
    aedat = real_file("davis240c_rotdisk.aedat")
    done = shell(f"neurotac import {aedat} | head -c 100 > /dev/null")
    assert (done.returncode, done.stderr) == (0, b"")


def test_import_writes_the_events_kind_sensor_and_history(tmp_path):
    path = real_file("prophesee_hd_expelliarmus.evt3.raw")
    out = tmp_path / "e.parquet"
    assert run(["import", str(path), "-o", str(out)]).exit_code == 0
    table = pq.read_table(out)
    assert sch.kind_of(table.schema) == "events" and sch.sensor_of(table.schema) == (1280, 720)
    assert table.num_rows == 219_596
    history = sch.get_meta(table.schema, sch.HISTORY)
    assert history[-1]["command"] == "import" and history[-1]["args"]["paths"] == [str(path)]


def test_import_from_stdin(tmp_path):
    path = real_file("atis_ncars_loris.es")
    out = tmp_path / "e.arrows"
    done = shell(f"neurotac import - -o {out} < {path}")
    assert done.returncode == 0, done.stderr
    from neurotac_cli.tables import read

    assert read([str(out)]).num_rows == 4_407


def test_several_files_are_one_table_in_order(tmp_path):
    es, dat = real_file("atis_ncars_loris.es"), real_file("atis_ncars_loris.dat")
    out = tmp_path / "two.parquet"
    result = run(["import", "--one-stream", str(dat), str(dat), "-o", str(out), "--sensor", "304x240"])
    assert result.exit_code == 0, result.output
    assert pq.read_table(out).num_rows == 2 * 4_407
    mixed = run(["import", "--one-stream", str(es), str(real_file("davis240c_rotdisk.aedat")), "-o", str(out)])
    assert mixed.exit_code == 1 and "different sensor sizes" in mixed.output
    joined = run(["import", "--one-stream", str(es), str(dat), "-o", str(out)])  # the DAT's size is guessed: it fits the ES's
    assert joined.exit_code == 0 and sch.sensor_of(pq.read_schema(out)) == (54, 239)


def test_sensor_option_overrides_and_too_small_a_sensor_is_an_error(tmp_path):
    dat = real_file("atis_ncars_loris.dat")
    result = run(["import", str(dat), "--sensor", "20x20", "-o", str(tmp_path / "x.parquet")])
    assert result.exit_code == 1
    assert "outside the 20x20 sensor" in result.output
    assert not (tmp_path / "x.parquet").exists()


@pytest.mark.parametrize(
    "setup, expected",
    [
        (lambda d: str(d), "holds no camera files"),
        (lambda d: str(d / "missing.aedat"), "no such file"),
        (lambda d: make(d / "empty.aedat", b""), "is empty"),
        (lambda d: make(d / "x.bin", bytes(range(256)) * 4), "unknown camera format"),
        (lambda d: make(d / "bad.csv", b"t,x,y,p\n1,2,3,1\n2,2,3,1\noops\n"), "line 4"),
        (lambda d: make(d / "v3.aedat", b"#!AER-DAT3.1\r\n"), "AEDAT 3.1"),
        (lambda d: make(d / "v5.aedat", b"#!AER-DAT5.0\r\n1 2 3 1\n"), "AEDAT version '5.0' is not supported"),
        (lambda d: make(d / "long.aedat", b"#!AER-DAT" + b"x" * 70_000), "AEDAT version 'xxxxxxxxxxxxxxxx' is not"),
        (lambda d: make(d / "cut.aedat4", b"#!AER"), "holds only 5 bytes, the start of an AEDAT file's signature"),
        (lambda d: make(d / "cut.es", b"Event"), "the start of an Event Stream file's signature"),
        (lambda d: make(d / "cut.h5", b"\x89HDF\r"), "the start of an HDF5 file's signature"),
    ],
    ids=["directory", "missing", "empty", "unknown", "bad-row", "aedat3", "aedat5", "aedat-long", "cut-aedat", "cut-es", "cut-hdf5"],
)
def test_bad_inputs_give_one_line_and_exit_1(tmp_path, setup, expected):
    path = setup(tmp_path)
    done = shell(f"neurotac import '{path}' -o {tmp_path / 'out.parquet'}")
    lines = done.stderr.decode().strip().splitlines()
    assert done.returncode == 1
    assert len(lines) == 1 and lines[0].startswith("neurotac import: error: ") and expected in lines[0], lines


@pytest.mark.parametrize("how", ["file", "stdin"])
def test_a_format_of_another_family_than_the_files_signature_is_refused(tmp_path, how):
    """Every decoder turns any bytes into events: an AEDAT 2.0 file read as EVT 3.0 gave made-up
    events on a 2728x2048 sensor with only a warning about its last byte."""
    from neurotac_cli.io.writers import write_aedat2

    path = tmp_path / "grasp.aedat"
    write_aedat2(path, np.arange(0, 4000, 10), np.full(400, 5), np.full(400, 6), np.arange(400) % 2)
    source, data = (str(path), None) if how == "file" else ("-", path.read_bytes())
    result = run(["import", "--format", "evt3", source, "-o", str(tmp_path / "out.parquet")], input=data)
    assert result.exit_code == 1 and result.output.count("\n") == 1, result.output
    assert "--format evt3 reads it as Prophesee EVT 3.0 raw, but its first bytes are those of AEDAT 2.0 (jAER)" in result.output
    assert run(["import", "--format", "aedat2", source, "-o", str(tmp_path / "out.parquet")], input=data).exit_code == 0


def test_an_idle_timeout_without_follow_is_a_usage_error_and_its_default_is_not(tmp_path):
    """It was ignored without a word: nothing waits for a file that is not followed. Given at its
    default value it is refused all the same: the user chose it."""
    path = make(tmp_path / "e.csv", b"t,x,y,p\n1,2,3,1\n2,2,3,0\n")
    for args in (["--idle-timeout", "2s"], ["--idle-timeout", "5s", "--one-stream", path]):
        result = run(["import", *args, path, "-o", str(tmp_path / "o.parquet")])
        assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
        assert "--idle-timeout ends a followed file once it stops growing: give it with --follow" in result.output
    assert run(["import", path, "-o", str(tmp_path / "o.parquet")]).exit_code == 0


def test_a_table_given_to_import_is_refused_with_a_hint(tmp_path):
    table = sch.events_table([1, 2], [0, 1], [0, 1], [1, 0], 4, 4)
    path = tmp_path / "t.parquet"
    pq.write_table(table, path)
    result = run(["import", str(path), "-o", str(tmp_path / "o.parquet")])
    assert result.exit_code == 1 and "already a table" in result.output


def test_binary_output_to_a_terminal_is_refused():
    done = subprocess.run(
        ["script", "-qec", f"{NEUROTAC} import {real_file('atis_ncars_loris.dat')}", "/dev/null"], capture_output=True, timeout=60
    ) if shutil.which("script") else None
    if done is None:
        pytest.skip("`script` is not installed")
    assert b"refusing to write a binary" in done.stdout


def test_text_import_round_trips_through_csv(tmp_path):
    rng = np.random.default_rng(2)
    t = np.sort(rng.integers(0, 10**8, 1000))
    x, y, p = rng.integers(0, 240, 1000), rng.integers(0, 180, 1000), rng.integers(0, 2, 1000)
    csv = tmp_path / "e.csv"
    csv.write_text("t,x,y,p\n" + "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in zip(t, x, y, p)))
    out = tmp_path / "e.parquet"
    assert run(["import", str(csv), "--sensor", "240x180", "-o", str(out)]).exit_code == 0
    table = pq.read_table(out)
    assert sch.sensor_of(table.schema) == (240, 180)
    assert np.array_equal(table["t"].to_numpy(), t) and np.array_equal(table["y"].to_numpy(), y)


@pytest.mark.parametrize("path, name", [("d/grasp.aedat4", "grasp"), ("rec.evt3.raw", "rec"), ("rec.EVT21.raw", "rec"),
                                        ("g.v2.csv", "g.v2"), ("plain", "plain"), ("x.raw", "x")])
def test_a_recording_names_its_trial_after_the_file(path, name):
    from neurotac_cli.io.camera import trial_name

    assert trial_name(path) == name


def test_sizes_guessed_from_the_events_give_way_to_the_largest_or_to_a_stated_one(tmp_path):
    """One camera's text files: each guess is only the smallest sensor holding its events."""
    (tmp_path / "a.csv").write_text("t,x,y,p\n1,239,179,1\n")
    (tmp_path / "b.csv").write_text("t,x,y,p\n5,2,2,0\n")
    (tmp_path / "c.csv").write_text("t,x@100,y@100,on\n5,2,2,0\n")
    for paths, size in (("a.csv b.csv", (240, 180)), ("b.csv c.csv", (100, 100))):
        out = tmp_path / "o.parquet"
        done = run(["import", *(str(tmp_path / p) for p in paths.split()), "-o", str(out)])
        assert done.exit_code == 0, done.output
        assert sch.sensor_of(pq.read_schema(out)) == size
    done = run(["import", str(tmp_path / "c.csv"), str(tmp_path / "a.csv"), "-o", str(tmp_path / "o.parquet")])
    assert done.exit_code == 1 and "a.csv: 240x180 (guessed from its events)" in done.output
