"""sync checks each force log against its recording: overlap, samples, finite values, plausible force."""

import subprocess

import numpy as np
import pytest

from neurotac_cli.errors import NeurotacError, SyncError
from neurotac_cli.io.force import read_force_log
from neurotac_cli.ops import sync as sy
from tests.ops.test_sync import force_log, synthetic_recording

RECORDING = synthetic_recording(6, led_off=None)  # events from 3.0 s to 3.4 s on the camera clock
AT = sy.SyncMethod(method="offset", offset_us=3_001_000)


def sync(log, method=AT):
    return sy.sync_source(sy.Source("g", RECORDING, [log]), method)


def test_a_log_inside_the_recording_passes_without_warnings():
    _, info = sync(force_log())
    assert "warnings" not in info["g"]


def test_a_log_that_does_not_overlap_the_recording_is_refused_with_both_spans():
    with pytest.raises(SyncError, match=r"does not overlap the recording \(3\.0\d\d s\.\.3\.4\d\d s\).*check --offset"):
        sync(force_log(), sy.SyncMethod(method="offset", offset_us=100_000_000_000))


def test_a_log_mostly_past_the_recording_is_a_warning():
    _, info = sync(force_log(), sy.SyncMethod(method="offset", offset_us=3_300_000))
    (warning,) = info["g"]["warnings"]
    assert "only 33% of the force log" in warning


def test_a_log_of_one_sample_is_refused():
    with pytest.raises(SyncError, match="1 sample"):
        sync(sy.ForceLog(t=np.array([0]), value=np.array([1.0])))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_and_inf_are_one_rule(tmp_path, bad):
    log = force_log()
    log.value = log.value.astype(float)
    log.value[40] = bad
    with pytest.raises(SyncError, match=r"1 force values are NaN or infinite \(the first at sample 40, 80 ms\)"):
        sync(log)
    path = tmp_path / "f.csv"
    path.write_text("t_ms,force_N\n0,0\n2,1\n4," + str(bad).replace("nan", "") + "\n6,0\n")
    with pytest.raises(NeurotacError, match="1 force values are not numbers"):
        read_force_log(str(path))


def test_a_log_negative_throughout_and_one_in_the_wrong_unit_are_warned_about():
    log = force_log()
    log.value = log.value - 50.0
    (warning,) = sync(log)[1]["g"]["warnings"]
    assert "below -0.1 N on 100% of the samples" in warning and "sign" in warning
    log = force_log()
    log.value = log.value * 1000
    (warning,) = sync(log)[1]["g"]["warnings"]
    assert "reaches 3000 N" in warning and "unit" in warning


@pytest.mark.parametrize("value", [0.0, 1.5])
def test_a_log_of_one_value_throughout_is_warned_about(value):
    """An unplugged sensor or the wrong column reads one value: every frame would be labelled with it, silently."""
    log = force_log()
    log.value = np.full(len(log.t), value)
    (warning,) = sync(log)[1]["g"]["warnings"]
    assert f"the force is {value:g} N in every one of the {len(log.t)} samples" in warning and "--force-column" in warning


def test_rest_noise_around_zero_is_not_negative():
    log = force_log()
    log.value = np.random.default_rng(0).normal(0, 0.02, len(log.t))
    assert "warnings" not in sync(log)[1]["g"]


def test_the_command_prints_each_warning_once_and_refuses_in_one_line(tmp_path):
    RECORDING_PATH = tmp_path / "rec.arrows"
    from neurotac_cli import tables

    tables.write(str(RECORDING_PATH), RECORDING)
    t_ms = np.arange(0, 301, 2)
    (tmp_path / "neg.csv").write_text("t_ms,force_N\n" + "".join(f"{t},-50\n" for t in t_ms))
    args = ["neurotac", "sync", str(RECORDING_PATH), "--method", "offset", "--force"]
    done = subprocess.run([*args, str(tmp_path / "neg.csv"), "--offset", "3001ms", "-o", str(tmp_path / "s.arrows")], capture_output=True, text=True)
    assert done.returncode == 0 and done.stderr.count("\n") == 1 and "warning" in done.stderr and "sign" in done.stderr
    done = subprocess.run([*args, str(tmp_path / "neg.csv"), "--offset", "1000s", "-o", str(tmp_path / "t.arrows")], capture_output=True, text=True)
    assert done.returncode == 1 and done.stderr.count("\n") == 1 and "does not overlap" in done.stderr
    assert done.stderr.startswith("neurotac sync: error: rec: the force log"), done.stderr  # the trial named once, by the log's check
    assert not (tmp_path / "t.arrows").exists()


def test_a_short_log_among_several_names_its_recording_and_trial_once():
    from neurotac_cli import schema as sch
    from neurotac_cli.io.force import ForceLog
    from neurotac_cli.io.manifest import Source

    t = np.arange(0, 2_000_000, 100, dtype=np.int64)
    events = sch.events_table(t, np.zeros(len(t), np.uint16), np.zeros(len(t), np.uint16), np.ones(len(t), np.uint8),
                              width=240, height=180)
    good = ForceLog(t=np.arange(0, 200_000, 2000, dtype=np.int64), value=np.ones(100), trial="a")
    short = ForceLog(t=np.arange(0, 10_000, 2000, dtype=np.int64), value=np.ones(5), trial="b")
    with pytest.raises(SyncError) as caught:
        sy.sync_sources([Source(trial="rec", events=events, force=[good, short], labels={})], sy.SyncMethod())
    assert str(caught.value).startswith("rec, trial b: the force log has 5 sample(s)"), caught.value
