"""The LED blink marks the sync instant and is not touch: `sync` and `simulate --synced` leave its
switch-off burst out of every trial alike, and `--keep-led` keeps it."""

import subprocess

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

from neurotac_cli import schema, tables


def run(command: str, tmp_path, name: str) -> pa.Table:
    path = tmp_path / name
    done = subprocess.run(["bash", "-o", "pipefail", "-c", f"{command} > {path}"], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    return tables.read([str(path)])


def first_frame_off(recordings: pa.Table) -> list[int]:
    """OFF events in the first 10 ms after each trial's t0."""
    events = recordings.column("events").combine_chunks()
    values = events.flatten()
    t, p = values.field("t").to_numpy(), values.field("p").to_numpy()
    trial = pc.list_parent_indices(events).to_numpy()
    return np.bincount(trial[(t >= 0) & (t < 10_000) & (p == 0)], minlength=len(events)).tolist()


def event_counts(recordings: pa.Table) -> np.ndarray:
    return pc.list_value_length(recordings.column("events")).to_numpy()


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rig")
    done = subprocess.run(["neurotac", "simulate", "--preset", "ch4", "--trials", "6", "--seed", "1", "--out", str(folder / "sim")], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    return folder


def test_sync_and_simulate_synced_leave_out_the_same_burst(rig):
    synced = run(f"neurotac sync --manifest {rig / 'sim' / 'manifest.csv'}", rig, "a.arrows")
    simulated = run("neurotac simulate --preset ch4 --trials 6 --seed 1 --synced", rig, "b.arrows")
    kept = run(f"neurotac sync --keep-led --manifest {rig / 'sim' / 'manifest.csv'}", rig, "c.arrows")
    with_burst, without, from_sim = first_frame_off(kept), first_frame_off(synced), first_frame_off(simulated)
    for full, cut, sim in zip(with_burst, without, from_sim):
        assert cut < full / 10 and sim < full / 10
    assert np.allclose(event_counts(synced), event_counts(simulated), rtol=0.02)
    info = schema.get_meta(synced.schema, schema.SYNC)
    for entry in info["trials"].values():  # the cut ends after the spike's onset, every trial
        assert entry["led_events_removed"] > 0 and entry["led_end_us"] > entry["onset_us"]
