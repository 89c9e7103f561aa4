"""Tiny frames tables for the model tests (no tests here)."""

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch


def tiny_frames(trials=8, length=12, size=(9, 9), seed=0, objects=("small", "large"), window_us=10000,
                augmented_copies=0) -> pa.Table:
    """Grasp-like trials: force rises, holds, falls; OFF events with the rise, ON with the fall."""
    height, width = size
    rng = np.random.default_rng(seed)
    names = ("trial", "frame", "t", "force", "phase", "object", "material", "source_trial", "augment")
    rows = {name: [] for name in names}
    counts = []
    third = length // 3
    for i in range(trials):
        peak = 1.0 + (i % 3)
        force = np.concatenate([np.linspace(0, peak, third), np.full(length - 2 * third, peak), np.linspace(peak, 0, third)])
        rise = np.diff(force, prepend=0.0)
        for copy in range(augmented_copies + 1):
            trial = f"t{i}" if copy == 0 else f"t{i}~noise#{copy}"
            for k in range(length):
                off = rng.poisson(0.2 + 4 * max(rise[k], 0), (height, width))
                on = rng.poisson(0.2 + 4 * max(-rise[k], 0), (height, width))
                counts.append(np.stack([off, on]))
                rows["trial"].append(trial)
                rows["frame"].append(k)
                rows["t"].append(k * window_us)
                rows["force"].append(force[k])
                rows["phase"].append("grasping" if k < third else "holding" if k < length - third else "releasing")
                rows["object"].append(objects[i % len(objects)])
                rows["material"].append(("foam", "steel")[i % 2])
                rows["source_trial"].append(f"t{i}")
                rows["augment"].append("" if copy == 0 else f"noise#{copy}")
    extra = [("source_trial", pa.string()), ("augment", pa.string())] if augmented_copies else []
    schema = sch.frames_schema(height, width, labels=["object", "material"], window_us=window_us, extra=extra)
    columns = {
        "trial": pa.array(rows["trial"]), "frame": pa.array(rows["frame"], pa.int32()), "t": pa.array(rows["t"], pa.int64()),
        "counts": sch.counts_array(np.asarray(counts, dtype=np.uint16)), "force": pa.array(rows["force"], pa.float32()),
        "phase": pa.array(rows["phase"]), "object": pa.array(rows["object"]), "material": pa.array(rows["material"]),
        "source_trial": pa.array(rows["source_trial"]), "augment": pa.array(rows["augment"]),
    }
    return pa.Table.from_arrays([columns[f.name] for f in schema], schema=schema)


def write_stream(table: pa.Table, path, chunk=None):
    import pyarrow.ipc as ipc

    with pa.OSFile(str(path), "wb") as sink:
        writer = ipc.new_stream(sink, table.schema)
        writer.write_table(table, max_chunksize=chunk)
        writer.close()
    return path
