"""Sessions in the simulator: one recording of many grasps, its ground truth, sync and frame of a session."""

import csv
import re
import subprocess

import numpy as np
import pyarrow as pa
import pytest

from neurotac_cli.sim.config import preset_config
from neurotac_cli.sim.session import _contact_events, grasp_force, plan_session
from neurotac_cli.sim import dvs
from tests.commands.test_simulate import decode_aedat2

SHORT = ["--set", "session_hold_us=300ms..600ms", "--set", "session_rest_us=300ms..500ms",
         "--set", "slip_share=0.5", "--set", "regrasp_share=0.5", "--set", "partial_share=0.5"]


def simulate(folder, *args):
    done = subprocess.run(["neurotac", "simulate", "--session", *args, "--out", str(folder)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    assert done.stderr == b"" and done.stdout == b""
    return folder


def read_csv(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def force_log(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return data[:, 0], data[:, 1]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    return simulate(tmp_path_factory.mktemp("session"), "--grasps", "4", "--seed", "11", *SHORT)


def test_same_seed_writes_the_same_bytes_and_another_seed_does_not(session, tmp_path):
    again = simulate(tmp_path / "again", "--grasps", "4", "--seed", "11", *SHORT)
    other = simulate(tmp_path / "other", "--grasps", "4", "--seed", "12", *SHORT)
    for name in ("session00.aedat", "session00_force.csv", "manifest.csv", "grasps.csv"):
        assert (session / name).read_bytes() == (again / name).read_bytes()
    assert (session / "session00.aedat").read_bytes() != (other / "session00.aedat").read_bytes()


def test_one_led_blink_at_the_start_then_grasps_in_time_order(session):
    (row,) = read_csv(session / "manifest.csv")
    grasps = read_csv(session / "grasps.csv")
    assert int(row["true_grasps"]) == len(grasps) == 4
    t, x, y, p = decode_aedat2((session / row["events"]).read_bytes())
    t0 = int(row["true_t0_us"])
    assert np.all(np.diff(t) >= 0) and t[0] > 1_000_000
    counts, edges = np.histogram(t[p == 0], np.arange(t[0], t[-1] + 1000, 1000))
    assert abs(edges[np.argmax(counts)] - t0) <= 1000  # the biggest OFF burst is the one blink
    spikes = edges[:-1][counts > 5_000]  # the blink's OFF spike: tens of thousands of events in a millisecond
    assert spikes.size and spikes.min() > t0 - 5_000 and spikes.max() < t0 + 5_000  # no other one later
    starts = [float(g["contact_ms"]) for g in grasps]
    ends = [float(g["released_ms"]) for g in grasps]
    assert all(0 < a < b for a, b in zip(starts, ends)) and all(b + 300 <= a for b, a in zip(ends, starts[1:]))
    assert {g["material"] for g in grasps} <= {"foam", "silicone", "rubber", "steel"}


def test_manifest_intervals_match_the_force_log(session):
    (row,) = read_csv(session / "manifest.csv")
    grasps = read_csv(session / "grasps.csv")
    t_ms, force = force_log(session / row["force"])
    assert t_ms[0] == 0 and np.all(np.diff(t_ms) == 2)
    assert t_ms[-1] < float(row["true_duration_ms"]) <= t_ms[-1] + 2
    touching = np.zeros(t_ms.size, bool)
    for g in grasps:
        inside = (t_ms >= float(g["contact_ms"])) & (t_ms <= float(g["released_ms"]) + 5)
        touching |= inside
        held = (t_ms >= float(g["loaded_ms"])) & (t_ms < float(g["loaded_ms"]) + 100)
        assert np.all(force[held] > 0.4 * float(g["peak_force_n"]))
        assert abs(force[held].max() - float(g["peak_force_n"])) < 0.2 * float(g["peak_force_n"])
    assert np.abs(force[~touching]).max() < 0.05  # the Nano17's noise at rest, nothing more
    assert np.all(force[touching & (t_ms > 0)].max() > 1.0)


def test_a_session_without_grasps_is_rest_throughout(tmp_path):
    folder = simulate(tmp_path, "--grasps", "0", "--duration", "1500ms", "--seed", "2")
    (row,) = read_csv(folder / "manifest.csv")
    assert read_csv(folder / "grasps.csv") == [] and row["true_grasps"] == "0"
    _, force = force_log(folder / row["force"])
    assert force.size == 750 and np.abs(force).max() < 0.05
    t, x, y, p = decode_aedat2((folder / row["events"]).read_bytes())
    after = t[t > int(row["true_t0_us"]) + 20_000]
    rate = after.size / ((after[-1] - after[0]) * 1e-6)
    assert 0.5 * 4320 < rate < 1.5 * 4320  # background activity only: 0.1 Hz x 43,200 pixels (+ hot pixels)
    done = subprocess.run(["bash", "-o", "pipefail", "-c",
                           f"neurotac sync --manifest {folder}/manifest.csv | neurotac frame --window 10ms --phases session"],
                          capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    frames = pa.ipc.open_stream(done.stdout).read_all()
    assert set(frames["phase"].to_pylist()) == {"none"} and set(frames["grasp"].to_pylist()) == {-1}


def test_sync_makes_one_trial_spanning_the_session_by_led_or_xcorr(session):
    (row,) = read_csv(session / "manifest.csv")
    for method, tolerance in (("led", 100), ("xcorr", 3_000)):
        done = subprocess.run(["neurotac", "sync", "--manifest", str(session / "manifest.csv"), "--method", method],
                              capture_output=True)
        assert done.returncode == 0, done.stderr.decode()
        table = pa.ipc.open_stream(done.stdout).read_all()
        assert table.num_rows == 1
        assert abs(table["t0"][0].as_py() - int(row["true_t0_us"])) <= tolerance
        force_t = [item["t"] for item in table["force"][0].as_py()]
        assert force_t[-1] / 1000 > float(row["true_duration_ms"]) - 3


def test_lighting_that_swings_each_second_does_not_hide_whose_log_it_is(tmp_path):
    """A lamp 40% brighter and darker each second swings the event rate more than the grasps do: the
    log moved with the events only once the slow swing was taken out (r 0.01 as counted: warned
    "another recording's?")."""
    lit = simulate(tmp_path / "lit", "--grasps", "4", "--seed", "2", "--illumination-drift", "0.4", "--set",
                   "illumination_period_us=1s")
    done = subprocess.run(["neurotac", "sync", "--manifest", str(lit / "manifest.csv"), "-o", str(tmp_path / "r.parquet")],
                          capture_output=True)
    assert done.returncode == 0 and b"hardly moves" not in done.stderr, done.stderr.decode()


def test_a_force_log_whose_zero_drifts_gets_each_grasp_labelled_once(tmp_path):
    """`--set force_drift_n_per_min`: the log's zero climbs over the session; each grasp is still
    found once above the log's rest level where it is (read for the whole log, the later rests were
    grasps)."""
    drifting = simulate(tmp_path / "d", "--grasps", "8", "--seed", "3", "--set", "force_drift_n_per_min=0.6")
    t_ms, force = force_log(drifting / "session00_force.csv")
    assert force[-50:].mean() - force[:50].mean() > 0.3  # the zero has moved by about a tenth of a grasp
    synced = subprocess.run(["neurotac", "sync", "--manifest", str(drifting / "manifest.csv")], capture_output=True, check=True)
    framed = subprocess.run(["neurotac", "frame", "--window", "10ms", "--phases", "session"], input=synced.stdout,
                            capture_output=True, check=True)
    table = pa.ipc.open_stream(framed.stdout).read_all()
    grasp = table.column("grasp").to_numpy()
    assert grasp.max() + 1 == 8 and len(read_csv(drifting / "grasps.csv")) == 8
    said = re.search(rb"the force log's rest level moves over 1 session \(session00: by \+([0-9.]+),", framed.stderr)
    assert said and float(said[1]) == pytest.approx(force[-50:].mean() - force[:50].mean(), abs=0.06), framed.stderr
    assert b"keeps the drift (--zero rest takes it out)" in framed.stderr
    # `--zero rest`: the same grasps, the force at rest about zero from start to end
    zeroed = subprocess.run(["neurotac", "frame", "--window", "10ms", "--phases", "session", "--zero", "rest"], input=synced.stdout,
                            capture_output=True, check=True)
    again = pa.ipc.open_stream(zeroed.stdout).read_all()
    assert np.mean(again.column("grasp").to_numpy() == grasp) > 0.999 and b"taken from that level (--zero rest)" in zeroed.stderr
    at_rest = again.column("force").to_numpy()[grasp < 0]
    assert abs(at_rest[:500].mean()) < 0.02 and abs(at_rest[-500:].mean()) < 0.02


def test_frame_labels_each_grasp_of_the_session(session):
    grasps = read_csv(session / "grasps.csv")
    cmd = f"neurotac sync --manifest {session}/manifest.csv | neurotac frame --window 10ms --phases session"
    done = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    frames = pa.ipc.open_stream(done.stdout).read_all()
    assert frames.schema.field("grasp").type == pa.int32()
    index = frames["grasp"].to_numpy()
    assert sorted(set(index.tolist()) - {-1}) == list(range(len(grasps)))
    start_ms = frames["t"].to_numpy() / 1000
    for number, g in enumerate(grasps):
        mine = start_ms[index == number]
        # contact is found once the force passes 5% of the session's scale: during the loading, whatever its speed
        assert float(g["contact_ms"]) - 10 <= mine[0] <= float(g["loaded_ms"])
        assert float(g["release_ms"]) <= mine[-1] <= float(g["released_ms"]) + 10
        phases = frames["phase"].to_numpy(zero_copy_only=False)[index == number]
        assert phases[0] == "grasping" and phases[-1] == "releasing" and "holding" in phases


def test_slips_move_the_contact_along_their_direction():
    config = preset_config("ch4", groups=("steel:bolt12:1",), slip_share=1.0, slip_force_drop=(0.3, 0.3),
                           regrasp_share=0.0, partial_share=0.0, change_share=0.0, session_hold_us=(1_000_000, 1_000_000),
                           slip_us=(150_000, 150_000), slip_speed_mm_s=(20.0, 20.0))
    rng = np.random.default_rng(4)
    planned = plan_session(config, rng, 1).grasps[0]
    slip = planned.slip
    assert slip is not None and slip.end_us - slip.start_us == 150_000
    camera = dvs.make_camera(config, np.random.default_rng(1))
    residual = np.zeros(camera.shape, np.float32)
    t, x, y, p = _contact_events(config, camera, planned, residual)
    t = t - planned.offset_us
    during = (t >= slip.start_us) & (t < slip.end_us)
    assert during.sum() > 500  # a sliding face fires along its whole rim
    lead = np.array([x[during & (p == 0)].mean(), y[during & (p == 0)].mean()])
    trail = np.array([x[during & (p == 1)].mean(), y[during & (p == 1)].mean()])
    along = float(np.dot(lead - trail, slip.direction))
    assert along > 10  # darkening (OFF) ahead of the face, brightening (ON) behind it: 12 mm face, 3 mm slide
    before = grasp_force(config, planned, np.array([slip.start_us - 1_000.0]))[0]
    after = grasp_force(config, planned, np.array([slip.end_us + 1_000.0]))[0]
    assert after == pytest.approx(0.7 * before, rel=0.08)  # the drop drawn, ripple aside


def test_session_options_are_refused_outside_their_mode(tmp_path):
    for args, word in ((["--session"], "--out"), (["--session", "--synced", "--out", str(tmp_path)], "--synced"),
                       (["--grasps", "3", "--out", str(tmp_path)], "--session"),
                       (["--illumination-drift", "0.1", "--out", str(tmp_path)], "--session"),
                       (["--session", "--hold", "1s", "--out", str(tmp_path)], "session_hold_us")):
        done = subprocess.run(["neurotac", "simulate", *args], capture_output=True)
        assert done.returncode == 2 and done.stderr.decode().count("\n") == 1 and word in done.stderr.decode()


def test_frame_labels_the_true_slips_from_the_grasps_csv(session):
    slips = [(float(g["slip_start_ms"]), float(g["slip_end_ms"])) for g in read_csv(session / "grasps.csv") if g["slip_start_ms"]]
    assert slips, "the fixture's session has slips"
    cmd = (f"neurotac sync --manifest {session}/manifest.csv "
           f"| neurotac frame --window 10ms --phases session --slips {session}/grasps.csv")
    done = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True)
    assert done.returncode == 0 and done.stderr == b"", done.stderr.decode()
    frames = pa.ipc.open_stream(done.stdout).read_all()
    slip = frames["slip"].to_numpy(zero_copy_only=False)
    end_ms = frames["t"].to_numpy() / 1000 + 10
    expected = np.zeros(len(slip), dtype=bool)
    for start, end in slips:
        expected |= (end_ms > start) & (end_ms <= end)
        first = int(np.argmax(slip & (end_ms > start)))
        assert start < end_ms[first] <= start + 10  # the first frame holding the slip's events
    assert (slip == expected).all()


def test_true_slips_naming_no_recorded_trial_are_warned_about_and_label_nothing(session, tmp_path):
    (tmp_path / "slips.csv").write_bytes(b"\xef\xbb\xbfsession,slip_start_ms,slip_end_ms\nsession99,100,200\n")  # a spreadsheet's BOM
    cmd = f"neurotac sync --manifest {session}/manifest.csv | neurotac frame --window 10ms --slips {tmp_path}/slips.csv"
    done = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    assert "session99" in done.stderr.decode() and done.stderr.decode().startswith("neurotac frame: warning:")
    assert not pa.ipc.open_stream(done.stdout).read_all()["slip"].to_numpy(zero_copy_only=False).any()


def test_slips_drawn_that_no_hold_can_hold_are_counted(tmp_path):
    done = subprocess.run(["neurotac", "simulate", "--session", "--grasps", "3", "--seed", "4", "--set", "slip_share=1",
                           "--set", "slip_us=2s..3s", "--out", str(tmp_path / "s")], capture_output=True, text=True)
    assert done.returncode == 0 and "2 of the 3 slips drawn had no hold long enough" in done.stderr
    rows = read_csv(tmp_path / "s" / "grasps.csv")
    assert sum(1 for row in rows if row["slip_start_ms"]) == 1


def test_a_share_of_bright_objects_presses_those_grasps_with_on_events():
    config = preset_config("ch4", groups=("steel:bolt12:1",), bright_share=0.5, slip_share=0.0, regrasp_share=0.0,
                           partial_share=0.0, change_share=0.0, session_hold_us=(300_000, 300_000))
    grasps = plan_session(config, np.random.default_rng(4), 8).grasps
    contrasts = [planned.physics["object_contrast"] for planned in grasps]
    assert set(contrasts) == {config.object_contrast, config.bright_contrast}
    assert len(set(contrasts[:4])) == 2
    camera = dvs.make_camera(config, np.random.default_rng(1))
    for planned in grasps[:4]:
        t, _, _, p = _contact_events(config, camera, planned, np.zeros(camera.shape, np.float32))
        pressing = (t - planned.offset_us) < planned.grasp.loaded_us
        share_on = float(p[pressing].mean())
        assert share_on > 0.7 if planned.physics["object_contrast"] < 0 else share_on < 0.3
