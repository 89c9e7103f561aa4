"""The table kinds of the data contract: builders, validators and metadata helpers.

Kinds (schema metadata key `neurotac:kind`): events, recordings, frames, predictions, metrics.
See docs/formats.md for the contract as built.
"""

import json

import numpy as np
import pyarrow as pa

from neurotac_cli.errors import SchemaError, UsageError
from neurotac_cli.units import MAX_SIDE

KIND = "neurotac:kind"
SENSOR = "neurotac:sensor"
WINDOW = "neurotac:window_us"
SYNC = "neurotac:sync"
HISTORY = "neurotac:history"
SOURCE = "neurotac:source"  # the camera file(s) `import` read: a dict, or a list of them

KINDS = ("events", "recordings", "frames", "predictions", "metrics")

EVENT_FIELDS = [("t", pa.int64()), ("x", pa.uint16()), ("y", pa.uint16()), ("p", pa.uint8())]
EVENT_STRUCT = pa.struct(EVENT_FIELDS)
FORCE_STRUCT = pa.struct([("t", pa.int64()), ("value", pa.float32())])

# Columns a kind must have, with their types; None = checked separately.
REQUIRED = {
    "events": dict(EVENT_FIELDS),
    "recordings": {"trial": pa.string(), "t0": pa.int64(), "events": pa.list_(EVENT_STRUCT), "force": pa.list_(FORCE_STRUCT)},
    "frames": {"trial": pa.string(), "frame": pa.int32(), "t": pa.int64(), "counts": None, "force": pa.float32(), "phase": pa.string()},
    "predictions": {"trial": pa.string()},
    "metrics": {"scope": pa.string(), "metric": pa.string(), "value": pa.float64()},
}
# Required columns that may hold nulls (a frame without a force reading or a phase).
NULLABLE = {"frames": ("force", "phase")}
# String columns that describe provenance rather than a label of the grasp.
NOT_LABELS = {"trial", "phase", "source_trial", "augment", "scope", "metric", "model"}


# ---------------------------------------------------------------- metadata


def camera_source(schema: pa.Schema) -> dict:
    """What `import` recorded of the one camera file behind a table (file, format, sensor_from);
    empty for a table from several files or none."""
    source = get_meta(schema, SOURCE)
    return source if isinstance(source, dict) else {}


def camera_sources(schema: pa.Schema) -> list[dict]:
    """What `import` recorded of every camera file behind a table (one or several)."""
    found = get_meta(schema, SOURCE)
    return found if isinstance(found, list) else [found] if found else []


def trial_recording(recordings: pa.Table, trial: str):
    """One trial of a recordings table: (t0, its events (t, x, y, p) relative to t0, its force (t,
    value)), or None when the table has no such trial."""
    import pyarrow.compute as pc

    row = recordings.filter(pc.equal(recordings.column("trial"), trial)).slice(0, 1)
    if row.num_rows == 0:
        return None
    events = row.column("events").combine_chunks().flatten()
    force = row.column("force").combine_chunks().flatten()
    columns = tuple(events.field(name).to_numpy(zero_copy_only=False) for name in ("t", "x", "y", "p"))
    return (int(row.column("t0")[0].as_py()), columns,
            (force.field("t").to_numpy(zero_copy_only=False), force.field("value").to_numpy(zero_copy_only=False)))


def get_meta(schema: pa.Schema, key: str, default=None):
    raw = (schema.metadata or {}).get(key.encode())
    if raw is None:
        return default
    try:
        return json.loads(raw)
    except ValueError:
        raise SchemaError(f"metadata {key} is not valid JSON (was the file written by another tool?)") from None


def set_meta(schema: pa.Schema, **entries) -> pa.Schema:
    """Return `schema` with `neurotac:<key>` entries set (JSON-encoded); a value of None removes the key."""
    metadata = dict(schema.metadata or {})
    for key, value in entries.items():
        name = f"neurotac:{key}".encode()
        if value is None:
            metadata.pop(name, None)
        else:
            metadata[name] = json.dumps(value, sort_keys=True, default=_json_default).encode()
    return schema.with_metadata(metadata)


def _json_default(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, (tuple, set, np.ndarray)):
        return list(value)
    return str(value)


def kind_of(schema: pa.Schema) -> str | None:
    kind = get_meta(schema, KIND)
    if kind is not None and not isinstance(kind, str):
        raise SchemaError(f"metadata {KIND} is {kind!r}, not a kind name ({', '.join(KINDS)}); was the file written by another tool?")
    return kind


def check_header(schema: pa.Schema) -> None:
    """Column names are unique and the neurotac metadata a command relies on has the shape it
    expects: a forged or damaged file is one clear error at the door, not a crash deep inside."""
    repeated = sorted({name for name in schema.names if schema.names.count(name) > 1})
    if repeated:
        raise SchemaError(f"the table has {len(repeated)} column name(s) twice ({', '.join(map(repr, repeated))}); rename or drop one of each")
    for key in schema.metadata or {}:  # every neurotac entry is JSON, read or not by this command
        if key.startswith(b"neurotac:"):
            get_meta(schema, key.decode(errors="replace"))
    kind_of(schema)
    sensor = get_meta(schema, SENSOR)
    if sensor is not None and not is_sensor(sensor):
        raise SchemaError(f"metadata {SENSOR} is {sensor!r}, not {{\"width\": W, \"height\": H}} in pixels; re-import the recording")
    window = get_meta(schema, WINDOW)
    if window is not None and not is_positive_count(window):
        raise SchemaError(f"metadata {WINDOW} is {window!r}, not a whole number of µs, 1 or more; frame the events again")
    history = get_meta(schema, HISTORY)
    if history is not None and not (isinstance(history, list) and all(isinstance(step, dict) for step in history)):
        raise SchemaError(f"metadata {HISTORY} is not a list of steps; was the file written by another tool?")


def is_sensor(value) -> bool:
    """A sensor as metadata and model headers hold it: {"width": W, "height": H} in whole pixels, each
    side within the 16-bit coordinates of an event."""
    return isinstance(value, dict) and all(is_positive_count(value.get(k)) and value[k] <= MAX_SIDE for k in ("width", "height"))


def is_positive_count(value) -> bool:
    """A whole number from 1 to 2^31 - 1 (a size, a window, a format number), not a bool."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 < value < 2**31


def sensor_of(schema: pa.Schema) -> tuple[int, int] | None:
    """(width, height) of the coordinate space the table is in, or None when unknown."""
    sensor = get_meta(schema, SENSOR)
    if not sensor:
        return None
    return int(sensor["width"]), int(sensor["height"])


def sensor_meta(width: int, height: int) -> dict:
    return {"width": int(width), "height": int(height)}


def with_given_sensor(schema: pa.Schema, given) -> pa.Schema:
    """`schema` with --sensor's size (`given`) where the table declares none, or only the extent of
    its events (`import` of a file that does not say: the events are checked against the size given
    when they are read). A table that declares another size is refused: its coordinates are in that
    size, and a size given over it would put events outside the sensor or frame them in one corner
    of a larger one."""
    if given is None:
        return schema
    declared, given = sensor_of(schema), (int(given[0]), int(given[1]))
    source = camera_source(schema)
    if declared is None or (declared != given and source.get("sensor_from") == "events"):
        if source.get("sensor_from") == "events":
            schema = set_meta(schema, source={**source, "sensor_from": "option"})
        return set_meta(schema, sensor=sensor_meta(*given))
    if declared != given:
        raise UsageError(f"--sensor {given[0]}x{given[1]}: the table declares its sensor as {declared[0]}x{declared[1]} "
                         "(--sensor is for tables that do not declare one; to change it, import the camera file again "
                         "with `neurotac import --sensor WxH`)")
    return schema


def label_columns(schema: pa.Schema) -> list[str]:
    """The label columns (material, object, size, ...): string columns that are not structural."""
    kind = kind_of(schema)
    required = REQUIRED.get(kind, {})
    return [
        f.name
        for f in schema
        if f.name not in required and f.name not in NOT_LABELS and pa.types.is_string(f.type)
    ]


# ---------------------------------------------------------------- builders


def events_schema(width: int | None = None, height: int | None = None) -> pa.Schema:
    schema = pa.schema(EVENT_FIELDS)
    entries = {"kind": "events"}
    if width and height:
        entries["sensor"] = sensor_meta(width, height)
    return set_meta(schema, **entries)


def events_batch(t, x, y, p, schema: pa.Schema | None = None) -> pa.RecordBatch:
    schema = schema or events_schema()
    return pa.RecordBatch.from_arrays(
        [
            pa.array(np.asarray(t, dtype=np.int64)),
            pa.array(np.asarray(x, dtype=np.uint16)),
            pa.array(np.asarray(y, dtype=np.uint16)),
            pa.array(np.asarray(p, dtype=np.uint8)),
        ],
        schema=schema,
    )


def events_table(t, x, y, p, width=None, height=None) -> pa.Table:
    return pa.Table.from_batches([events_batch(t, x, y, p, events_schema(width, height))])


def events_array(t, x, y, p) -> pa.StructArray:
    """One trial's events as the struct array a `recordings` row nests."""
    return pa.StructArray.from_arrays(
        [
            pa.array(np.asarray(t, dtype=np.int64)),
            pa.array(np.asarray(x, dtype=np.uint16)),
            pa.array(np.asarray(y, dtype=np.uint16)),
            pa.array(np.asarray(p, dtype=np.uint8)),
        ],
        fields=list(EVENT_STRUCT),
    )


def force_array(t, value) -> pa.StructArray:
    return pa.StructArray.from_arrays(
        [pa.array(np.asarray(t, dtype=np.int64)), pa.array(np.asarray(value, dtype=np.float32))],
        fields=list(FORCE_STRUCT),
    )


def check_label_names(labels) -> None:
    """A label is a column of its own beside the recordings' and frames' columns: it cannot take one's name."""
    taken = set(REQUIRED["recordings"]) | set(REQUIRED["frames"]) | (NOT_LABELS - {"model"})
    clash = [name for name in labels if name in taken or not str(name).strip()]
    if clash:
        raise SchemaError(f"label name {clash[0]!r} is {'empty' if not str(clash[0]).strip() else 'a column of the tables themselves'}; "
                          f"rename the label (names taken: {', '.join(sorted(taken))})")


def recordings_schema(labels=(), width=None, height=None, sync=None) -> pa.Schema:
    check_label_names(labels)
    fields = [(name, typ) for name, typ in REQUIRED["recordings"].items()]
    fields += [(name, pa.string()) for name in labels]
    entries = {"kind": "recordings"}
    if width and height:
        entries["sensor"] = sensor_meta(width, height)
    if sync is not None:
        entries["sync"] = sync
    return set_meta(pa.schema(fields), **entries)


def recordings_table(trials: list[dict], width=None, height=None, sync=None) -> pa.Table:
    """Build a recordings table from dicts with keys trial, t0, events=(t,x,y,p), force=(t,value), labels.

    Event and force times are relative to t0 (µs). `labels` is a dict of strings.
    """
    label_names = []
    for trial in trials:
        for name in trial.get("labels", {}):
            if name not in label_names:
                label_names.append(name)
    schema = recordings_schema(label_names, width, height, sync)
    if not trials:
        return schema.empty_table()
    events = [events_array(*trial["events"]) for trial in trials]
    forces = [force_array(*trial["force"]) for trial in trials]
    columns = {
        "trial": pa.array([str(trial["trial"]) for trial in trials], pa.string()),
        "t0": pa.array([int(trial["t0"]) for trial in trials], pa.int64()),
        "events": _list_of(events, pa.list_(EVENT_STRUCT)),
        "force": _list_of(forces, pa.list_(FORCE_STRUCT)),
    }
    for name in label_names:
        columns[name] = pa.array([trial.get("labels", {}).get(name) for trial in trials], pa.string())
    return pa.Table.from_pydict(columns, schema=schema)


def _list_of(arrays: list[pa.StructArray], list_type) -> pa.ListArray:
    offsets = np.zeros(len(arrays) + 1, dtype=np.int32)
    offsets[1:] = np.cumsum([len(a) for a in arrays])
    values = pa.concat_arrays(arrays) if arrays else pa.array([], list_type.value_type)
    return pa.ListArray.from_arrays(pa.array(offsets), values, type=list_type)


def counts_type(height: int, width: int, dtype=np.uint16) -> pa.DataType:
    if 2 * height * width > MAX_CELL_VALUES:
        raise SchemaError(f"frames of {width}x{height} pixels are too large for one table cell (at most "
                          f"{MAX_CELL_VALUES // 2:,} pixels): crop or pool the events first (`neurotac crop`)")
    return pa.fixed_shape_tensor(pa.from_numpy_dtype(np.dtype(dtype)), (2, height, width))


MAX_CELL_VALUES = 2**31 - 1  # Arrow's largest fixed-size list: one frame's two channels


def counts_array(counts: np.ndarray) -> pa.ExtensionArray:
    """(n, 2, H, W) numpy -> Arrow's canonical fixed_shape_tensor array."""
    counts = np.ascontiguousarray(counts)
    if counts.ndim != 4 or counts.shape[1] != 2:
        raise ValueError(f"counts must be (frames, 2, H, W), got {counts.shape}")
    # built from its storage without a copy: FixedShapeTensorArray.from_numpy_ndarray takes 20x as
    # long (measured 89 µs against 4.6 µs), and a live stream builds one per few frames
    _, _, height, width = counts.shape
    storage = pa.FixedSizeListArray.from_arrays(pa.array(counts.reshape(-1)), 2 * height * width)
    return pa.ExtensionArray.from_storage(counts_type(height, width, counts.dtype), storage)


def counts_numpy(column) -> np.ndarray:
    """A frames table's `counts` column (array or chunked) -> (n, 2, H, W) numpy, zero-copy when possible."""
    if isinstance(column, pa.ChunkedArray):
        typ = column.type
        if column.num_chunks == 1:
            column = column.chunk(0)
        elif column.num_chunks == 0:
            return np.zeros((0, *typ.shape), dtype=typ.value_type.to_pandas_dtype())
        else:
            return np.concatenate([counts_numpy(chunk) for chunk in column.chunks])
    return column.to_numpy_ndarray()


def frames_schema(height, width, labels=(), dtype=np.uint16, window_us=None, sensor=None, extra=()) -> pa.Schema:
    """`extra` = further (name, type) columns such as source_trial and augment."""
    fields = [
        ("trial", pa.string()),
        ("frame", pa.int32()),
        ("t", pa.int64()),
        ("counts", counts_type(height, width, dtype)),
        ("force", pa.float32()),
        ("phase", pa.string()),
    ]
    fields += list(extra)
    check_label_names(labels)
    fields += [(name, pa.string()) for name in labels]
    entries = {"kind": "frames", "sensor": sensor or sensor_meta(width, height)}
    if window_us is not None:
        entries["window_us"] = int(window_us)
    return set_meta(pa.schema(fields), **entries)


def frames_shape(schema: pa.Schema) -> tuple[int, int]:
    """(height, width) of a frames table's counts."""
    _, height, width = schema.field("counts").type.shape
    return int(height), int(width)


# ---------------------------------------------------------------- validators


def validate(schema: pa.Schema, kind) -> str:
    """Check a schema's kind and required columns; returns the kind. `kind` may be a tuple of accepted kinds."""
    accepted = (kind,) if isinstance(kind, str) else tuple(kind)
    found = kind_of(schema)
    if found is None:
        found = _guess_kind(schema)
        if found is None:
            raise SchemaError(
                f"input is not a neurotac table (no {KIND} in its metadata, and its columns "
                f"{', '.join(schema.names) or 'none'} match no kind); make it with `neurotac import` or `neurotac sync`"
            )
    if found not in accepted:
        raise SchemaError(f"expected {_a(' or '.join(accepted))} table, got {_a(found)} table{_hint(found, accepted)}")
    for name, typ in REQUIRED[found].items():
        if name not in schema.names:
            raise SchemaError(f"{found} table has no {name!r} column (columns: {', '.join(schema.names)})")
        actual = schema.field(name).type
        # whole-number trial ids (a numbering from another tool) are read as their text, as `frame` reads labels
        whole_ids = name == "trial" and pa.types.is_integer(actual)
        if typ is not None and not actual.equals(typ) and not _castable(actual, typ) and not whole_ids:
            advice = "; trial ids are text or whole numbers: cast the column to text" if name == "trial" else ""
            raise SchemaError(f"{found} column {name!r} has type {actual}, expected {typ}{advice}")
    if found == "frames":
        counts = schema.field("counts").type
        if not isinstance(counts, pa.FixedShapeTensorType) or len(counts.shape) != 3 or counts.shape[0] != 2:
            raise SchemaError(f"frames column 'counts' must be fixed_shape_tensor[2, H, W], got {counts}")
        _check_frames_sensor(schema, int(counts.shape[2]), int(counts.shape[1]))
    return found


def _check_frames_sensor(schema: pa.Schema, width: int, height: int):
    """A frames table's neurotac:sensor is the coordinate space its counts are in (`frame` sets it to
    the frame size, `crop` and its pooling to the cropped, pooled size: docs/formats.md), so a size
    other than the counts' is metadata edited or copied from another table, and the box, centre and
    pooling read from it would be another table's."""
    sensor = sensor_of(schema)
    if sensor is not None and sensor != (width, height):
        raise SchemaError(f"metadata {SENSOR} says {sensor[0]}x{sensor[1]}, but the frames' counts are {width}x{height} "
                          "(frame, crop and pool set it to the frames' size): metadata edited or taken from another table? "
                          "make the frames again")


def table_kind(schema: pa.Schema) -> str | None:
    """The table's kind: as its metadata says, else as its columns say (`_guess_kind`)."""
    return kind_of(schema) or _guess_kind(schema)


def unlike_windows(first: pa.Schema, other: pa.Schema) -> tuple | None:
    """(first's window, other's window) in µs where frames tables disagree, a window missing beside a
    known one included (read as one table, the unknown one would take the other's); None where alike."""
    a, b = get_meta(first, WINDOW), get_meta(other, WINDOW)
    if a == b or "frames" not in (table_kind(first), table_kind(other)):
        return None
    return a, b


def made_by(history: list) -> tuple:
    """(pooling (along the width, along the height) multiplied over the crops, whether `frame --dtype
    float32` scaled the counts) of frames made by these history steps; None where the history does
    not say, or where tables read together (a `concat` step) disagree."""
    pool, scaled = (1, 1), None
    for step in history:
        args = step.get("args") or {}
        if step.get("command") == "concat" and isinstance(args.get("inputs"), list):
            parts = {made_by(inner) if isinstance(inner, list) else (None, None) for inner in args["inputs"]}
            pool, scaled = (parts.pop() if len(parts) == 1 else (None, None))
            if pool is None:
                return None, scaled
            continue
        if step.get("command") == "crop":
            factor = args.get("pool")
            if factor is None:
                continue
            if not (isinstance(factor, list) and len(factor) == 2 and all(isinstance(v, int) for v in factor)):
                pool = None  # `--pool all` and older spellings: unknown here
            elif pool is not None:
                pool = (pool[0] * factor[0], pool[1] * factor[1])
        elif step.get("command") == "frame" and "dtype" in args:
            scaled = args["dtype"] == "float32"
    return pool if history else None, scaled


def made_unlike(name: str, schema: pa.Schema, other_name: str, other: pa.Schema) -> str | None:
    """How two frames tables were made unlike (pooled or scaled differently, where both histories
    say: one count would mean another amount of the sensor in each, though their shapes agree), or None."""
    (pool_a, scaled_a), (pool_b, scaled_b) = made_by(get_meta(schema, HISTORY, [])), made_by(get_meta(other, HISTORY, []))
    if None not in (pool_a, pool_b) and pool_a != pool_b:
        return (f"{other_name} was pooled {pool_b[0]}x{pool_b[1]}, {name} {pool_a[0]}x{pool_a[1]}: one count covers "
                "another area of the sensor in each")
    if None not in (scaled_a, scaled_b) and scaled_a != scaled_b:
        return (f"{other_name} holds counts {'scaled' if scaled_b else 'as counted'}, "
                f"{name} {'scaled' if scaled_a else 'as counted'} (`frame --dtype`)")
    return None


def _guess_kind(schema: pa.Schema) -> str | None:
    """Tables from other tools (DuckDB, Polars) lose our metadata: recognise them by their columns."""
    names = set(schema.names)
    for kind in ("recordings", "frames", "events", "metrics"):
        if set(REQUIRED[kind]) <= names:
            return kind
    return None


def _castable(actual: pa.DataType, expected: pa.DataType) -> bool:
    return (pa.types.is_integer(actual) and pa.types.is_integer(expected)) or (
        pa.types.is_floating(actual) and pa.types.is_floating(expected)
    ) or (pa.types.is_large_string(actual) and pa.types.is_string(expected))


def _a(words: str) -> str:
    return f"{'an' if words[0] in 'aeiou' else 'a'} {words}"


def _hint(found: str, accepted: tuple) -> str:
    if "frames" in accepted and found in ("events", "recordings"):
        return "; run `neurotac frame --window 10ms` first"
    if "recordings" in accepted and found == "events":
        return "; run `neurotac sync` first"
    if found in KINDS and all(kind in KINDS and KINDS.index(kind) < KINDS.index(found) for kind in accepted):
        return "; this command comes earlier in the pipeline (import, sync, frame, then crop, augment, train, eval)"
    return ""


def conform_schema(schema: pa.Schema, kind: str) -> pa.Schema:
    """The schema `conform` gives batches of this schema: the contract's types, the same metadata."""
    for name, typ in REQUIRED[kind].items():
        if typ is not None and name in schema.names and not schema.field(name).type.equals(typ):
            index = schema.get_field_index(name)
            schema = schema.set(index, pa.field(name, typ))
    return schema


def conform(batch, kind: str):
    """Cast lossless integer/float variants to the contract's types (tables from DuckDB or Polars),
    and refuse nulls where every row needs a value."""
    for name in REQUIRED[kind]:
        if name not in NULLABLE.get(kind, ()) and batch.column(batch.schema.get_field_index(name)).null_count:
            empty = batch.column(batch.schema.get_field_index(name)).null_count
            raise SchemaError(f"{empty} rows of the {kind} table have no {name!r} (null); every row needs one: fix or drop those rows")
    for name, typ in REQUIRED[kind].items():
        if typ is None:
            continue
        index = batch.schema.get_field_index(name)
        column = batch.column(index)
        if not column.type.equals(typ):
            try:
                column = column.cast(typ, safe=True)
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as error:
                if name == "p" and kind == "events" and pa.types.is_integer(column.type):
                    raise SchemaError("polarity (column 'p') must be 0 (OFF) or 1 (ON), found values outside 0..255 "
                                      f"({column.type})") from None
                raise SchemaError(f"{kind} column {name!r} cannot be read as {typ}: {error}") from None
            batch = batch.set_column(index, pa.field(name, typ), column)
    if kind == "frames":
        _check_counts(batch.column(batch.schema.get_field_index("counts")))
    return batch


def _check_counts(column):
    """Event counts are finite and not negative: a NaN or infinite count (a float table from another
    tool) would train a model to NaN or score it on fewer frames without a word, a negative one would
    be read as events of the other polarity."""
    if pa.types.is_unsigned_integer(column.type.value_type):  # finite and not negative by their type
        return
    counts = counts_numpy(column)
    finite = np.isfinite(counts)
    if not finite.all():
        frames = int((~finite.reshape(len(counts), -1)).any(axis=1).sum())
        raise SchemaError(f"{frames} frames carry NaN or infinite counts; event counts must be finite numbers")
    if (counts < 0).any():
        frames = int((counts.reshape(len(counts), -1) < 0).any(axis=1).sum())
        raise SchemaError(f"{frames} frames carry negative counts; event counts are never below zero")


def check_events(t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray, sensor, where: str = "", sorted_time=True):
    """Coordinates inside the sensor, polarity 0/1, time non-decreasing (when asked)."""
    place = f" in {where}" if where else ""
    if sensor is not None:
        check_inside(x, y, sensor, where)
    if len(p) and p.max(initial=0) > 1:
        raise SchemaError(f"polarity{place} must be 0 (OFF) or 1 (ON), found {int(p.max())}")
    if sorted_time and len(t) > 1:
        steps = np.diff(t)
        if steps.min() < 0:
            first = int(np.argmax(steps < 0)) + 1
            raise SchemaError(
                f"event time goes backwards{place} at row {first} ({int(t[first - 1])} -> {int(t[first])} µs); "
                "sort the events by time"
            )


def check_inside(x: np.ndarray, y: np.ndarray, sensor, where: str = "", advice: str = "check the sensor size (--sensor WxH)"):
    """Every event's coordinates inside the (width, height) sensor; `advice` ends the message."""
    width, height = sensor
    if len(x) and (x.max(initial=0) >= width or y.max(initial=0) >= height):
        bad = int(np.count_nonzero((x >= width) | (y >= height)))
        raise SchemaError(
            f"{bad} events{f' in {where}' if where else ''} lie outside the {width}x{height} sensor "
            f"(largest x={int(x.max())}, y={int(y.max())}); {advice}"
        )


def check_force(values: np.ndarray, where: str = ""):
    """Every force value finite (missing values are nulls in tables, never NaN or inf)."""
    bad = ~np.isfinite(np.asarray(values, dtype=np.float64))
    if len(values) and bad.any():
        place = f" in {where}" if where else ""
        raise SchemaError(f"{int(bad.sum())} force values{place} are NaN or infinite; clean the force log first")


MAX_FORCE_N = 10_000.0  # beyond any gripper's contact force: a value above it is a corrupt sample or another unit


def check_force_range(values: np.ndarray, what: str = "the training frames"):
    """Refuse a force beyond MAX_FORCE_N (nulls as NaN are skipped): `train` would not learn from it,
    and a score against it would be a figure of the corrupt sample, printed as if right."""
    values = np.abs(np.asarray(values, dtype=np.float64))
    values = values[~np.isnan(values)]
    if len(values) and values.max() > MAX_FORCE_N:
        raise SchemaError(f"{what} carry a force of {values.max():.3g} N, beyond any contact force (> {MAX_FORCE_N:g} N): "
                          "a corrupt sample or a log in another unit; clean the force log")


class UniqueRows:
    """Refuses a repeated trial (recordings) or (trial, frame) pair (frames) as batches flow past: the
    same table given twice, or two recordings synced under one name, would otherwise be trained on
    or scored twice. Memory: a byte per frame number from a trial's first to its last, or a set where
    those lie more than DENSE_SPAN apart."""

    KEYS = {"recordings": ("trial",), "frames": ("trial", "frame")}
    DENSE_SPAN = 1 << 24
    SMALL = 32  # batches of up to this many rows are checked row by row

    def __init__(self, kind: str | None):
        self.keys = self.KEYS.get(kind)
        self.seen: dict = {}  # trial -> (first frame number, flags from it) or (0, set of frame numbers)

    def check(self, batch) -> None:
        if self.keys is None or batch.num_rows == 0:
            return
        if batch.num_rows <= self.SMALL:  # `predict` streams a frame at a time: no numpy per batch
            trials = batch.column(batch.schema.get_field_index("trial")).to_pylist()
            numbers = [0] * len(trials) if self.keys == ("trial",) else batch.column(batch.schema.get_field_index("frame")).to_pylist()
            for trial, number in zip(trials, numbers):
                self._add_one(trial, number)
            return
        trials = batch.column(batch.schema.get_field_index("trial")).dictionary_encode()
        names = trials.dictionary.to_pylist()
        codes = trials.indices.to_numpy(zero_copy_only=False)
        if self.keys == ("trial",):
            frames = np.zeros(len(codes), dtype=np.int64)
        else:
            frames = batch.column(batch.schema.get_field_index("frame")).to_numpy(zero_copy_only=False).astype(np.int64)
        order = np.argsort(codes, kind="stable")
        bounds = np.flatnonzero(np.diff(codes[order])) + 1
        for rows in np.split(order, bounds):
            self._add(names[codes[rows[0]]], frames[rows])

    def _add(self, trial, frames: np.ndarray) -> None:
        low, high = int(frames.min()), int(frames.max())
        base, flags = self.seen.get(trial, (low, np.zeros(0, dtype=bool)))
        if isinstance(flags, set):
            repeated = np.fromiter((f in flags for f in frames.tolist()), bool, len(frames)) | _repeated_within(frames)
        else:
            if low < base or high - base >= len(flags):
                start, stop = min(base, low), max(high + 1, base + len(flags))
                if stop - start > self.DENSE_SPAN:  # frame numbers far apart (forged?): a set, not flags
                    self.seen[trial] = (0, set((np.flatnonzero(flags) + base).tolist()))
                    return self._add(trial, frames)
                # room to double, so a trial streamed a frame at a time is not copied once per frame
                grown = np.zeros(min(max(stop - start, 2 * len(flags)), self.DENSE_SPAN), dtype=bool)
                grown[base - start : base - start + len(flags)] = flags
                base, flags = start, grown
            repeated = flags[frames - base] | _repeated_within(frames)
        if repeated.any():
            raise SchemaError(self._message(trial, int(frames[np.argmax(repeated)])))
        if isinstance(flags, set):
            flags.update(frames.tolist())
        else:
            flags[frames - base] = True
        self.seen[trial] = (base, flags)

    def _add_one(self, trial, number: int) -> None:
        base, flags = self.seen.get(trial, (number, None))
        if isinstance(flags, set) or flags is None or not 0 <= number - base < len(flags):
            return self._add(trial, np.array([number], dtype=np.int64))
        if flags[number - base]:
            raise SchemaError(self._message(trial, number))
        flags[number - base] = True

    def _message(self, trial, frame: int) -> str:
        what = f"trial {trial!r}" if self.keys == ("trial",) else f"frame {frame} of trial {trial!r}"
        return (
            f"{what} appears twice in the input (the same table given twice, or two recordings under one name); "
            "give each its own trial name (neurotac sync --trial NAME, or a manifest row each) and pass each table once"
        )


def _repeated_within(index: np.ndarray) -> np.ndarray:
    """True at each value already seen earlier in `index`."""
    _, first = np.unique(index, return_index=True)
    repeated = np.ones(len(index), dtype=bool)
    repeated[first] = False
    return repeated
