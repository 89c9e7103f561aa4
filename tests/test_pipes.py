"""What a shell sees: exits, stderr, pipes closed early, binary refused on a terminal."""

import os
import pty
import subprocess

import pytest

from tests.conftest import real_file


def sh(command: str, **kwargs):
    return subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True, **kwargs)


def test_reader_closing_early_is_quiet_and_successful():
    aedat = real_file("davis240c_rotdisk.aedat")
    done = sh(f"neurotac import {aedat} | head -c 100 > /dev/null")
    assert (done.returncode, done.stderr) == (0, b"")


def test_reader_closing_early_mid_pipeline_is_quiet():
    aedat = real_file("davis240c_rotdisk.aedat")
    done = sh(f"neurotac import {aedat} | neurotac crop --box 0,0,100,100 | head -c 1000 > /dev/null")
    assert (done.returncode, done.stderr) == (0, b"")


def test_bad_input_is_one_line_and_exit_1(tmp_path):
    (tmp_path / "junk.arrows").write_bytes(b"\xff\xff\xff\xff" + os.urandom(200))
    for command in (
        f"neurotac info {tmp_path / 'junk.arrows'}",
        f"neurotac info {tmp_path}",
        f"neurotac info {tmp_path / 'missing.parquet'}",
        f"head -c 50 {tmp_path / 'junk.arrows'} | neurotac frame --window 10ms",
    ):
        done = sh(command)
        lines = done.stderr.decode().strip().splitlines()
        assert done.returncode == 1, (command, done.stderr)
        assert len(lines) == 1 and lines[0].startswith("neurotac "), (command, done.stderr)
        assert "Traceback" not in done.stderr.decode()


def test_a_stream_cut_short_upstream_is_named():
    aedat = real_file("davis240c_rotdisk.aedat")
    done = sh(f"neurotac import {aedat} | head -c 100000 | neurotac info -")
    assert done.returncode == 1
    assert b"ended mid-table" in done.stderr


def test_bare_number_duration_is_a_usage_error():
    done = sh("neurotac frame --window 10 < /dev/null")
    assert done.returncode == 2
    assert b"unit" in done.stderr


def test_binary_output_to_a_terminal_is_refused_with_a_hint():
    aedat = real_file("davis240c_rotdisk.aedat")
    leader, follower = pty.openpty()
    done = subprocess.run(["neurotac", "import", str(aedat)], stdout=follower, stderr=subprocess.PIPE, timeout=60)
    os.close(follower)
    os.close(leader)
    assert done.returncode == 1
    assert b"terminal" in done.stderr and b"-o" in done.stderr


def test_file_and_pipe_give_the_same_description(tmp_path):
    aedat = real_file("davis240c_rotdisk.aedat")
    piped = sh(f"neurotac import {aedat} | neurotac info -")
    made = sh(f"neurotac import {aedat} -o {tmp_path / 'a.parquet'} && neurotac info {tmp_path / 'a.parquet'}")
    assert piped.returncode == made.returncode == 0
    assert piped.stdout == made.stdout


def test_duckdb_reads_our_parquet(tmp_path):
    duckdb = pytest.importorskip("duckdb")
    aedat = real_file("davis240c_rotdisk.aedat")
    assert sh(f"neurotac import {aedat} -o {tmp_path / 'a.parquet'}").returncode == 0
    assert duckdb.sql(f"SELECT count(*) FROM '{tmp_path / 'a.parquet'}'").fetchall()[0][0] == 374_296


def test_info_after_crop_does_not_claim_the_file_gave_the_size():
    aedat = real_file("davis240c_rotdisk.aedat")
    done = sh(f"neurotac import {aedat} | neurotac crop --box 0,0,100,80 | neurotac info -")
    sensor = [line for line in done.stdout.decode().splitlines() if line.startswith("sensor")]
    assert done.returncode == 0 and sensor and sensor[0].split()[1] == "100x80"
    assert "from the file" not in sensor[0]


def test_sync_and_info_read_a_process_substitution(tmp_path):
    """A pipe's first bytes are not peeked at and lost: sync and info take `<(...)` like a file."""
    sim = tmp_path / "sim"
    assert sh(f"neurotac simulate --preset ch4 --trials 1 --seed 3 --out {sim}").returncode == 0
    camera = next(p for p in sim.glob("*.aedat") if p.name != "still.aedat")
    force = sim / f"{camera.stem}_force.csv"
    synced = sh(f"neurotac sync <(cat {camera}) --force {force} -o {tmp_path / 'r.arrows'}")
    assert synced.returncode == 0, synced.stderr
    described = sh(f"neurotac info <(cat {tmp_path / 'r.arrows'})")
    assert described.returncode == 0 and b"recordings" in described.stdout, described.stderr
