"""Any file tells how it was made: the camera file's checksum through `import | sync`, model files
readable like tables, and a warning when xcorr pairs a camera file with a force log it hardly matches."""

import hashlib
import os
import subprocess

import numpy as np

from neurotac_cli import schema as sch, tables
from neurotac_cli.ops.xcorr import XCORR_MIN_CORRELATION, unrelated_warnings


def test_import_then_sync_keeps_the_camera_file_and_its_checksum(tmp_path):
    sim = tmp_path / "sim"
    subprocess.run(["neurotac", "simulate", "--preset", "ch4", "--trials", "1", "--seed", "4", "--out", str(sim)], check=True,
                   capture_output=True)
    camera = next(p for p in sim.iterdir() if p.suffix == ".aedat" and p.name != "still.aedat")
    force = sim / f"{camera.stem}_force.csv"
    out = tmp_path / "rec.arrows"
    done = subprocess.run(["bash", "-o", "pipefail", "-c", f"neurotac import {camera} | neurotac sync --force {force} -o {out}"],
                          capture_output=True)
    assert done.returncode == 0, done.stderr
    schema = tables.open_input([str(out)]).schema
    digest = hashlib.sha256(camera.read_bytes()).hexdigest()
    assert sch.camera_source(schema)["sha256"] == digest
    history = sch.get_meta(schema, sch.HISTORY)
    assert [step["command"] for step in history] == ["import", "sync"]
    assert history[1]["args"]["camera"] == [{"file": camera.name, "sha256": digest}]
    assert tables.read([str(out)]).column("trial").to_pylist() == [camera.stem]  # named after the camera file


def test_files_written_by_a_writer_that_replaces_them_get_a_tables_permissions(tmp_path):
    from safetensors.numpy import save_file
    import numpy as np

    umask = os.umask(0o022)
    try:
        with tables.atomic_file(str(tmp_path / "m.model")) as temporary:
            save_file({"w": np.zeros(3, np.float32)}, temporary)
        tables.write(str(tmp_path / "t.parquet"), sch.events_table([1], [0], [0], [1], 1, 1))
    finally:
        os.umask(umask)
    assert oct(os.stat(tmp_path / "m.model").st_mode & 0o777) == oct(os.stat(tmp_path / "t.parquet").st_mode & 0o777) == "0o644"


def test_a_low_correlation_is_one_warning_naming_the_worst_trial():
    lines = unrelated_warnings({"a": {"correlation": 0.8}, "b": {"correlation": 0.31}, "c": {"correlation": XCORR_MIN_CORRELATION - 0.01}})
    assert len(lines) == 1 and "on 2 of 3 trial(s)" in lines[0] and "lowest r 0.310, b" in lines[0]
    assert unrelated_warnings({"a": {"correlation": XCORR_MIN_CORRELATION}}) == []
    assert "noise" not in lines[0]


def test_a_low_correlation_with_a_noisy_force_log_names_the_noise():
    """A simulated session whose log's noise is 4.2% of its range (0.15 N on grasps of about 3.4 N)
    was synced right by xcorr (1 ms from its blink) at r 0.22: the warning named only a wrong pairing."""
    from neurotac_cli.ops.xcorr import force_noise_share

    grasps = np.tile(np.r_[np.zeros(500), np.full(1000, 3.4)], 20)
    share = force_noise_share(grasps + np.random.default_rng(0).normal(0, 0.15, grasps.size))
    assert 0.03 < share < 0.05 and force_noise_share(grasps) == 0.0  # the range holds the noise's tails too
    line = unrelated_warnings({"s": {"correlation": 0.224, "force_noise_share": share}})[0]
    assert f"noise is {100 * share:.1f}% of its range, which alone lowers r" in line
