"""Several camera files, a directory or a glob: one trial per file, named after it."""

import numpy as np
import pytest
from click.testing import CliRunner

from neurotac_cli import schema as sch, tables
from neurotac_cli.cli import cli
from neurotac_cli.io.writers import aedat2_bytes


def write_camera(path, start_us, n=50):
    t = start_us + np.arange(n) * 1_000
    path.write_bytes(aedat2_bytes(t, np.arange(n) % 240, np.arange(n) % 180, np.arange(n) % 2))


@pytest.fixture
def folder(tmp_path):
    data = tmp_path / "rec"
    data.mkdir()
    write_camera(data / "grasp-01.aedat", 1_000_000)
    write_camera(data / "grasp-02.aedat", 9_000_000, n=30)
    (data / "grasp-01_force.csv").write_text("t,force\n0,0\n")  # not a camera file: left out
    return data


def run(*args):
    return CliRunner().invoke(cli, list(args))


@pytest.mark.parametrize("given", ["{d}", "{d}/*.aedat", "{d}/grasp-01.aedat {d}/grasp-02.aedat"])
def test_a_directory_a_glob_or_several_files_give_one_trial_per_file(folder, tmp_path, given):
    out = str(tmp_path / "r.arrows")
    result = run("import", *given.format(d=folder).split(), "-o", out)
    assert result.exit_code == 0, result.output
    recordings = tables.read([out], kind="recordings")
    assert recordings.column("trial").to_pylist() == ["grasp-01", "grasp-02"]
    assert recordings.column("t0").to_pylist() == [1_000_000, 9_000_000]
    frames = run("frame", "--window", "10ms", out, "-o", str(tmp_path / "f.arrows"))
    assert frames.exit_code == 0, frames.output
    framed = tables.read([str(tmp_path / "f.arrows")])
    per_trial = {trial: framed.column("trial").to_pylist().count(trial) for trial in ("grasp-01", "grasp-02")}
    assert per_trial == {"grasp-01": 5, "grasp-02": 3}  # 50 ms and 30 ms of events, not the 8 s between them
    assert sch.counts_numpy(framed.column("counts")).sum() == 80


def test_one_stream_keeps_one_events_table(folder, tmp_path):
    out = str(tmp_path / "e.arrows")
    assert run("import", "--one-stream", str(folder), "-o", out).exit_code == 0
    assert tables.read([out], kind="events").num_rows == 80


def test_trials_named_alike_and_empty_folders_are_refused(folder, tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    write_camera(other / "grasp-01.aedat", 0)
    result = run("import", str(folder), str(other), "-o", str(tmp_path / "x.arrows"))
    assert result.exit_code == 1 and "would both be trial 'grasp-01'" in result.output
    empty = tmp_path / "empty"
    empty.mkdir()
    result = run("import", str(empty), "-o", str(tmp_path / "x.arrows"))
    assert result.exit_code == 1 and "holds no camera files" in result.output


def test_a_folder_of_camera_files_and_force_logs_syncs_in_one_command(tmp_path):
    import shutil
    import subprocess

    sim = tmp_path / "sim"
    subprocess.run(["neurotac", "simulate", "--preset", "ch4", "--trials", "2", "--seed", "6", "--out", str(sim)],
                   check=True, capture_output=True)
    folder = tmp_path / "grasps"
    folder.mkdir()
    for path in sim.iterdir():
        if path.name.endswith(("-01.aedat", "-01_force.csv")):
            shutil.copy(path, folder / path.name)
    first = run("sync", str(folder), "-o", str(tmp_path / "r.arrows"))
    assert first.exit_code == 0, first.output
    assert "wrote" in first.output and (folder / "manifest.csv").read_text().splitlines()[0] == "trial,events,force"
    assert sorted(tables.read([str(tmp_path / "r.arrows")]).column("trial").to_pylist()) == sorted(
        p.stem for p in folder.glob("*.aedat"))
    (folder / "manifest.csv").write_text((folder / "manifest.csv").read_text().replace("trial,events,force", "trial,events,force,material", 1)
                                         .replace(".csv\n", ".csv,steel\n"))
    again = run("sync", str(folder), "-o", str(tmp_path / "r2.arrows"))
    assert again.exit_code == 0 and "using" in again.output
    assert set(tables.read([str(tmp_path / "r2.arrows")]).column("material").to_pylist()) == {"steel"}
    (folder / "manifest.csv").unlink()
    shutil.copy(next(folder.glob("*_force.csv")), folder / "spare-01_force.csv")  # a grasp whose camera file is missing
    paired = run("sync", str(folder), "-o", str(tmp_path / "r4.arrows"))
    assert paired.exit_code == 0 and "1 force log(s) have no camera file of their name and were left out (spare-01_force.csv)" in paired.output
    (folder / "manifest.csv").unlink()
    (folder / "spare-01_force.csv").unlink()
    next(folder.glob("*_force.csv")).unlink()
    refused = run("sync", str(folder), "-o", str(tmp_path / "r3.arrows"))
    assert refused.exit_code == 1 and "no force log for 1 camera file(s)" in refused.output
