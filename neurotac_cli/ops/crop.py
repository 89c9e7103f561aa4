"""Crop and sum-pool frames, recordings or events to the contact area (thesis 4.5.2, 5.4.1).

A box is `(x, y, w, h)` in the input's pixels (origin top-left). With a size and a centre, the box
is centred there; `center="auto"` finds the contact area's centre once from the whole input: the
activity of every pixel (frames' counts, or events after each trial's t0) less the median pixel's
(what the whole field saw: the LED flash at t0, background noise) is median-filtered 3x3 (hot pixels
are single pixels), smoothed (Gaussian, 2 px), thresholded at 20% of its peak, and the
centre of the bounding box of the largest connected region is taken (thesis: the largest contact
area). A box that would reach past the sensor is moved inside it when the centre was found
automatically, and refused when it was given.

Pooling sums K x L neighbouring pixels (K along x, L along y): 140x150 pooled 2x2 gives 70x75
(thesis 5.4.1). `pool="all"` keeps one pixel per channel (thesis ch. 3: no spatial information).
Pooled uint16 counts are never clipped: streamed (a fixed box) they are uint32, read whole they widen
to uint32 when a sum passes 65535 (recorded in history).

What lies outside the box is counted (events, or frame counts) in a `CropReport`.
"""

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, OutsideSensorError, PoolError, SchemaError, UsageError
from neurotac_cli.units import MAX_SIDE, is_whole

MAX_COUNT = int(np.iinfo(np.uint16).max)


@dataclass(frozen=True)
class CropSpec:
    """What to cut. Validated when built."""

    box: tuple | None = None
    size: tuple | None = None
    center: tuple | str | None = None
    pool: tuple | str | None = None

    def __post_init__(self):
        if self.box is not None and (self.size is not None or self.center is not None):
            raise UsageError("give either --box or --size with --center, not both")
        if self.size is not None and self.center is None:
            raise UsageError("--size needs --center X,Y or --center auto")
        if self.center is not None and self.size is None:
            raise UsageError("--center needs --size WxH")
        # the library passes these as it likes (lists, strings, floats): each is checked as the command line's types are
        if self.size is not None and (not _whole_numbers(self.size, 2) or min(self.size) <= 0 or max(self.size) > MAX_SIDE):
            raise UsageError(f"size must be (W, H) with whole W and H from 1 to {MAX_SIDE}, got {self.size!r}")
        if self.center is not None and self.center != "auto" and (not _whole_numbers(self.center, 2) or min(self.center) < 0):
            raise UsageError(f"center must be (x, y) with whole x, y >= 0, or auto, got {self.center!r}")
        if self.box is not None and (not _whole_numbers(self.box, 4) or self.box[2] <= 0 or self.box[3] <= 0 or min(self.box) < 0):
            raise UsageError(f"box must be X,Y,W,H with X,Y >= 0 and W,H > 0, got {self.box}")
        if isinstance(self.pool, tuple) and (not _whole_numbers(self.pool, 2) or min(self.pool) <= 0):
            raise UsageError(f"pool must be KxL with positive K and L, got {self.pool}")
        if self.pool is not None and not isinstance(self.pool, tuple) and self.pool != "all":
            raise UsageError(f"pool must be KxL or all, got {self.pool!r}")
        if self.box is None and self.size is None and self.pool is None:
            raise UsageError("nothing to do: give --box, --size with --center, or --pool")


def _whole_numbers(value, count: int) -> bool:
    """Whether `value` is a tuple or list of `count` whole numbers."""
    return (isinstance(value, (tuple, list)) and len(value) == count
            and all(is_whole(v) for v in value))


@dataclass
class CropReport:
    kept: int = 0
    cut: int = 0
    unit: str = "events"
    box: list | None = None
    center: list | None = None
    center_from: str | None = None
    pool: object = None
    widened: str | None = None
    streamed: bool = False  # an events stream: the counts are known only once it has been written

    @property
    def share_cut(self) -> float:
        total = self.kept + self.cut
        return self.cut / total if total else 0.0

    def as_dict(self) -> dict:
        out = {"kept": self.kept, "cut": self.cut, "counted": self.unit, "box": self.box, "pool": self.pool}
        if self.center is not None:
            out["center"] = self.center
            out["center_from"] = self.center_from
        if self.widened:
            out["widened_to"] = self.widened
        return out

    def history(self):
        """The report as the history records it: its figures; for a stream (its history is written before
        its first batch), what is known then, and a note that the cut count goes to stderr."""
        if not self.streamed:
            return self.as_dict()
        known = {key: value for key, value in self.as_dict().items() if key not in ("kept", "cut", "counted")}
        return {**known, "streamed": "the count of what was cut is written to stderr"}

    def messages(self, threshold: float) -> list[str]:
        """Lines for stderr once the output is written: a stream's cut count (when it cut anything: its
        history cannot hold it), then the warnings."""
        counted = [f"cut {self.cut:.15g} of {self.kept + self.cut:.15g} {self.unit}"] if self.streamed and self.cut else []
        if self.center_from == "auto" and self.box:  # the centre a live stream's fixed box needs (`sense`)
            x0, y0, w, h = self.box  # moved inside the sensor where the contact lies near its edge
            counted.insert(0, f"the contact's centre {self.center[0]},{self.center[1]} (box {','.join(map(str, self.box))}; "
                              f"a fixed box there: --center {x0 + w // 2},{y0 + h // 2})")
        return counted + [f"warning: {line}" for line in self.warnings(threshold)]

    def warnings(self, threshold: float) -> list[str]:
        lines = []
        if self.cut and self.share_cut > threshold:
            advice = ("the activity is spread wider than the box (a real scene, not a membrane?): give a larger --size, "
                      "or --box from `neurotac info`" if self.center_from == "auto"
                      else "check the box against `neurotac info`, or find the contact's centre with `neurotac crop --center auto` on a recording")
            lines.append(f"the crop cut away {self.cut} of {self.kept + self.cut} {self.unit} ({100 * self.share_cut:.1f}%); {advice}")
        return lines


# ---------------------------------------------------------------- where


def contact_center(activity: np.ndarray) -> tuple[int, int]:
    """(x, y) centre of the largest active region of an (H, W) activity map (see the module doc)."""
    from scipy import ndimage

    activity = np.asarray(activity, dtype=np.float64)
    if activity.max(initial=0) <= 0:
        raise NeurotacError("cannot find the contact area: the input has no events (give --center X,Y)")
    # what every pixel saw (the LED flash at t0, background noise) is not contact: take it away
    above = np.clip(activity - np.median(activity), 0, None)
    if above.max() <= 0:
        above = activity
    smooth = ndimage.gaussian_filter(ndimage.median_filter(above, size=3, mode="nearest"), 2.0)
    if smooth.max() <= 0:
        smooth = ndimage.gaussian_filter(above, 2.0)
    mask = smooth >= 0.2 * smooth.max()
    labels, count = ndimage.label(mask)
    sizes = ndimage.sum_labels(mask, labels, index=np.arange(1, count + 1))
    largest = int(np.argmax(sizes)) + 1
    ys, xs = np.nonzero(labels == largest)
    return int(round((xs.min() + xs.max()) / 2)), int(round((ys.min() + ys.max()) / 2))


def activity_map(table: pa.Table) -> np.ndarray:
    """(H, W) activity of a frames, recordings or events table (events of recordings from t0 on)."""
    kind = sch.kind_of(table.schema)
    if kind == "frames":
        height, width = sch.frames_shape(table.schema)
        total = np.zeros((height, width), dtype=np.float64)
        for batch in table.to_batches():
            counts = sch.counts_numpy(batch.column("counts"))
            total += counts.sum(axis=(0, 1), dtype=np.float64)
        return total
    width, height = sensor_size(table.schema)
    if kind == "recordings":
        values = pa.chunked_array([chunk.flatten() for chunk in table.column("events").chunks], type=sch.EVENT_STRUCT)
        t = np.concatenate([chunk.field("t").to_numpy(zero_copy_only=False) for chunk in values.chunks] or [np.zeros(0, np.int64)])
        x = np.concatenate([chunk.field("x").to_numpy(zero_copy_only=False) for chunk in values.chunks] or [np.zeros(0, np.uint16)])
        y = np.concatenate([chunk.field("y").to_numpy(zero_copy_only=False) for chunk in values.chunks] or [np.zeros(0, np.uint16)])
        keep = t >= 0
        x, y = x[keep], y[keep]
    else:
        x = table.column("x").to_numpy().astype(np.int64)
        y = table.column("y").to_numpy().astype(np.int64)
    sch.check_inside(x, y, (width, height))
    flat = np.bincount(y.astype(np.int64) * width + x, minlength=width * height)
    return flat.reshape(height, width).astype(np.float64)


def sensor_size(schema: pa.Schema) -> tuple[int, int]:
    """(W, H) of the input: its frames' shape, or its neurotac:sensor."""
    if sch.kind_of(schema) == "frames":
        height, width = sch.frames_shape(schema)
        return width, height
    sensor = sch.sensor_of(schema)
    if sensor is None:
        raise SchemaError("the table has no neurotac:sensor metadata (give the sensor size with --sensor WxH)")
    return sensor


def resolve_box(spec: CropSpec, sensor: tuple[int, int], activity=None, report: CropReport | None = None) -> tuple | None:
    """The (x, y, w, h) box of `spec` on a `sensor` = (W, H); None when only pooling."""
    width, height = sensor
    if spec.box is not None:
        box = tuple(int(v) for v in spec.box)
        if box[0] + box[2] > width or box[1] + box[3] > height:
            raise OutsideSensorError(f"box {','.join(map(str, box))} reaches past the {width}x{height} sensor")
        return box
    if spec.size is None:
        return None
    w, h = spec.size
    if w > width or h > height:
        raise OutsideSensorError(f"crop size {w}x{h} is larger than the {width}x{height} input")
    if spec.center == "auto":
        cx, cy = contact_center(activity)
        source = "auto"
    else:
        cx, cy = spec.center
        source = "given"
    x0, y0 = int(cx) - w // 2, int(cy) - h // 2
    if source == "given" and (x0 < 0 or y0 < 0 or x0 + w > width or y0 + h > height):
        raise OutsideSensorError(f"a {w}x{h} box centred at {cx},{cy} reaches past the {width}x{height} sensor; move the centre")
    x0 = min(max(x0, 0), width - w)
    y0 = min(max(y0, 0), height - h)
    if report is not None:
        report.center = [int(cx), int(cy)]
        report.center_from = source
    return (x0, y0, w, h)


def pooled_size(width: int, height: int, pool) -> tuple[int, int]:
    if pool is None:
        return width, height
    if pool == "all":
        return 1, 1
    k, l = pool
    if k > width or l > height:
        raise PoolError(f"cannot pool {width}x{height} by {k}x{l}: the pool is larger than the crop (`--pool all` sums it to one pixel)")
    if width % k or height % l:
        raise PoolError(f"cannot pool {width}x{height} by {k}x{l}: the size must divide evenly (choose a crop size that does)")
    return width // k, height // l


# ---------------------------------------------------------------- frames


def pool_counts(counts: np.ndarray, pool, report: CropReport | None = None) -> np.ndarray:
    """Sum-pool (n, 2, H, W) counts by (K, L) or `all`: int64 sums of integer counts, float64 of floats."""
    if pool is None:
        return counts
    n, c, height, width = counts.shape
    if pool == "all":
        k, l = width, height
    else:
        k, l = pool
    wide = np.float64 if counts.dtype.kind == "f" else np.int64
    return counts.reshape(n, c, height // l, l, width // k, k).sum(axis=(3, 5), dtype=wide)


def crop_frames(table: pa.Table, box, pool, report: CropReport) -> pa.Table:
    """Crop and pool a whole frames table. Pooled uint16 counts that pass 65535 widen the whole
    table's counts to uint32 (a whole-sensor sum of accumulated counts easily does): nothing is clipped."""
    dtype = np.dtype(table.schema.field("counts").type.value_type.to_pandas_dtype())
    _cropped_frames_schema(table.schema, box, pool, dtype)  # a pool that does not divide the box fails first
    pieces = [(batch, _crop_counts(batch, box, pool, report)) for batch in table.to_batches()]
    out_dtype = dtype
    if pool is not None and dtype == np.uint16 and any(len(c) and c.max() > MAX_COUNT for _, c in pieces):
        out_dtype = np.dtype(np.uint32)
        report.widened = "uint32"
    schema = _cropped_frames_schema(table.schema, box, pool, out_dtype)
    batches = [_frames_batch_like(batch, pooled, schema) for batch, pooled in pieces]
    return pa.Table.from_batches(batches, schema=schema)


def crop_frames_batches(schema: pa.Schema, batches, box, pool, report: CropReport):
    """Crop and pool a frames stream batch by batch; returns (schema, iterator), the report filling as
    it runs. The output's type is fixed before the first frame, so pooled uint16 counts are written
    as uint32 (a sum of K*L uint16 counts can pass 65535, and a stream cannot widen later)."""
    dtype = np.dtype(schema.field("counts").type.value_type.to_pandas_dtype())
    out_dtype = np.dtype(np.uint32) if pool is not None and dtype == np.uint16 else dtype
    if out_dtype != dtype:
        report.widened = "uint32"
    out_schema = _cropped_frames_schema(schema, box, pool, out_dtype)

    def generate():
        for batch in batches:
            yield _frames_batch_like(batch, _crop_counts(batch, box, pool, report), out_schema)

    return out_schema, generate()


def _crop_counts(batch: pa.RecordBatch, box, pool, report: CropReport) -> np.ndarray:
    """One batch's cropped and pooled counts; what the box cuts is counted in `report`."""
    counts = sch.counts_numpy(batch.column("counts"))
    height, width = counts.shape[2:]
    x0, y0, w, h = box if box is not None else (0, 0, width, height)
    inner = counts[:, :, y0:y0 + h, x0:x0 + w]
    total = float(counts.sum(dtype=np.float64))
    kept = float(inner.sum(dtype=np.float64))
    integer = counts.dtype.kind != "f"
    report.unit = "events (counted in frames)" if integer else "frame counts (scaled)"  # integer counts are events
    report.kept += int(kept) if integer else kept
    report.cut += int(total - kept) if integer else (total - kept)
    return pool_counts(np.ascontiguousarray(inner), pool)


def _cropped_frames_schema(schema: pa.Schema, box, pool, dtype) -> pa.Schema:
    height, width = sch.frames_shape(schema)
    _, _, w, h = box if box is not None else (0, 0, width, height)
    new_w, new_h = pooled_size(w, h, pool)
    return _frames_schema_like(schema, new_h, new_w, dtype)


def _frames_batch_like(batch: pa.RecordBatch, counts: np.ndarray, schema: pa.Schema) -> pa.RecordBatch:
    columns = list(batch.columns)
    dtype = schema.field("counts").type.value_type.to_pandas_dtype()
    columns[batch.schema.get_field_index("counts")] = sch.counts_array(counts.astype(dtype, copy=False))
    return pa.RecordBatch.from_arrays(columns, schema=schema)


def _frames_schema_like(schema: pa.Schema, height: int, width: int, dtype) -> pa.Schema:
    index = schema.get_field_index("counts")
    schema = schema.set(index, pa.field("counts", sch.counts_type(height, width, dtype)))
    return sch.set_meta(schema, sensor=sch.sensor_meta(width, height))


# ---------------------------------------------------------------- events and recordings


def crop_event_arrays(t, x, y, p, box, pool, sensor):
    """Keep events inside `box`, shift them to its origin, pool coordinates; returns arrays and the mask.
    Every event must lie on the `sensor` (W, H): one outside it is refused, not counted as cut."""
    sch.check_events(t, x, y, p, sensor, sorted_time=False)
    if box is None:
        inside = None
    else:
        x0, y0, w, h = box
        inside = (x >= x0) & (x < x0 + w) & (y >= y0) & (y < y0 + h)
        t, x, y, p = t[inside], (x[inside] - x0), (y[inside] - y0), p[inside]
    if pool == "all":
        x, y = np.zeros_like(x), np.zeros_like(y)
    elif pool is not None:
        x, y = x // pool[0], y // pool[1]
    return (t, x.astype(np.uint16), y.astype(np.uint16), p), inside


def _cropped_schema(schema: pa.Schema, box, pool) -> tuple[pa.Schema, tuple[int, int]]:
    """(the schema of what `box` and `pool` make of a stream of `schema`, the sensor's (W, H) before)."""
    width, height = sensor_size(schema)
    _, _, w, h = box if box is not None else (0, 0, width, height)
    return sch.set_meta(schema, sensor=sch.sensor_meta(*pooled_size(w, h, pool))), (width, height)


def crop_events_batches(schema: pa.Schema, batches, box, pool, report: CropReport):
    """Crop an events stream batch by batch; returns (schema, iterator). The report fills as it runs."""
    out_schema, (width, height) = _cropped_schema(schema, box, pool)

    def generate():
        for batch in batches:
            arrays = [batch.column(name).to_numpy(zero_copy_only=False) for name in ("t", "x", "y", "p")]
            (t, x, y, p), inside = crop_event_arrays(*arrays, box, pool, (width, height))
            report.kept += len(t)
            report.cut += batch.num_rows - len(t)
            if len(out_schema) == 4:
                yield sch.events_batch(t, x, y, p, out_schema)
                continue
            # columns beyond t, x, y, p (another tool's) travel with the events they belong to
            columns = dict(zip(("t", "x", "y", "p"), sch.events_batch(t, x, y, p).columns))
            for name in out_schema.names:
                if name not in columns:
                    columns[name] = batch.column(name) if inside is None else batch.column(name).filter(pa.array(inside))
            yield pa.RecordBatch.from_arrays([columns[name] for name in out_schema.names], schema=out_schema)

    return out_schema, generate()


def crop_recordings(table: pa.Table, box, pool, report: CropReport) -> pa.Table:
    schema, batches = crop_recordings_batches(table.schema, table.to_batches(), box, pool, report)
    return pa.Table.from_batches(list(batches), schema=schema)


def crop_recordings_batches(schema: pa.Schema, batches, box, pool, report: CropReport):
    """Crop a recordings stream trial batch by trial batch; returns (schema, iterator)."""
    out_schema, (width, height) = _cropped_schema(schema, box, pool)

    def generate():
        for batch in batches:
            yield _crop_recordings_batch(batch, box, pool, report, out_schema, (width, height))

    return out_schema, generate()


def _crop_recordings_batch(batch: pa.RecordBatch, box, pool, report: CropReport, schema: pa.Schema, sensor) -> pa.RecordBatch:
    events = batch.column("events")
    offsets = events.offsets.to_numpy() - events.offsets.to_numpy()[0]
    values = events.values.slice(events.offsets.to_numpy()[0], offsets[-1]) if len(offsets) else events.values
    arrays = [values.field(name).to_numpy(zero_copy_only=False) for name in ("t", "x", "y", "p")]
    (t, x, y, p), inside = crop_event_arrays(*arrays, box, pool, sensor)
    if inside is not None:
        kept_before = np.concatenate([[0], np.cumsum(inside)])
        new_offsets = kept_before[offsets].astype(np.int32)
    else:
        new_offsets = offsets.astype(np.int32)
    report.kept += len(t)
    report.cut += len(arrays[0]) - len(t)
    nested = pa.ListArray.from_arrays(pa.array(new_offsets), sch.events_array(t, x, y, p), type=pa.list_(sch.EVENT_STRUCT))
    columns = list(batch.columns)
    columns[batch.schema.get_field_index("events")] = nested
    return pa.RecordBatch.from_arrays(columns, schema=schema)


# ---------------------------------------------------------------- one call


def crop_table(table: pa.Table, spec: CropSpec, report: CropReport | None = None, sensor=None) -> pa.Table:
    """Crop a whole frames, recordings or events table (auto centre from the whole table)."""
    report = report if report is not None else CropReport()
    kind = sch.table_kind(table.schema)
    table = table.replace_schema_metadata(sch.with_given_sensor(table.schema, sensor).metadata)
    dims = sensor_size(table.schema)
    activity = activity_map(table) if spec.center == "auto" else None
    box = resolve_box(spec, dims, activity, report)
    report.box = list(box) if box is not None else None
    report.pool = list(spec.pool) if isinstance(spec.pool, tuple) else spec.pool
    if kind == "frames":
        return crop_frames(table, box, spec.pool, report)
    if kind == "recordings":
        return crop_recordings(table, box, spec.pool, report)
    schema, batches = crop_events_batches(table.schema, table.to_batches(), box, spec.pool, report)
    return pa.Table.from_batches(list(batches), schema=schema)


STREAMERS = {"frames": crop_frames_batches, "events": crop_events_batches, "recordings": crop_recordings_batches}


def crop(schema: pa.Schema, batches, spec: CropSpec, sensor=None) -> tuple[pa.Schema, object, CropReport]:
    """`neurotac crop`: (schema, batches or table, report) of a frames, recordings or events input.

    With a fixed box (--box, --size with --center X,Y, or only --pool) the input is cropped batch by
    batch as it arrives, so memory does not grow with it and a live stream flows through; the report
    fills as the batches are written. The automatic centre needs the whole input: it is read whole."""
    report = CropReport()
    kind = sch.table_kind(schema)
    schema = sch.with_given_sensor(schema, sensor)
    try:
        if spec.center != "auto" and kind in STREAMERS:
            box = resolve_box(spec, sensor_size(schema), report=report)
            report.box, report.streamed = (list(box) if box else None), True
            report.pool = list(spec.pool) if isinstance(spec.pool, tuple) else spec.pool
            out_schema, out = STREAMERS[kind](schema, batches, box, spec.pool, report)
            return out_schema, out, report
        table = crop_table(pa.Table.from_batches(list(batches), schema=schema), spec, report)
    except (OutsideSensorError, PoolError) as error:
        # a pool's error is about the sensor's size only where no box of the user's own was pooled
        hint = guessed_sensor_hint(schema) if isinstance(error, OutsideSensorError) or (spec.box, spec.size) == (None, None) else ""
        if hint:
            raise type(error)(f"{error}{hint}") from None
        raise
    return table.schema, table, report


def guessed_sensor_hint(schema: pa.Schema) -> str:
    """Where a table's sensor size is its events' extent (a camera file that does not state it: DAT,
    text), what to add to an error about sizes: the size is a guess, and how to give the true one."""
    if sch.camera_source(schema).get("sensor_from") != "events":
        return ""
    width, height = sensor_size(schema)
    return (f" ({width}x{height} is the extent of the events: the camera file does not give its sensor's size; "
            "give it with --sensor WxH)")
