"""Tables from other tools, read as neurotac tables (liberal in what is read, canonical in what is written).

Frames whose `counts` are not Arrow's fixed_shape_tensor: DuckDB writes them back as list<uint16>
(`COPY ... TO`), other tools as fixed_size_list, flat or nested (Polars' Array(UInt16, (2, H, W))).
Nested fixed-size lists carry their shape; a flat list gets it from the table's neurotac:sensor
metadata, or from NEUROTAC_FRAME_SIZE=WxH (the root option `neurotac --frame-size WxH`), or, for a
square frame, from its length (2·S·S values). Otherwise the table is refused with what to give.

Events from evlib (Polars): `t` as a Duration (or a Timestamp) of any unit and `polarity` -1/1 (or
bool, or 0/1) become `t: int64` µs and `p: uint8` 0/1. Time is floored to the microsecond.
"""

import math
import os

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from neurotac_cli import schema as sch
from neurotac_cli.errors import SchemaError
from neurotac_cli.units import parse_size

FRAME_SIZE_ENV = "NEUROTAC_FRAME_SIZE"
_US_PER = {"s": 1_000_000, "ms": 1_000, "us": 1, "ns": 1e-3}


def accept(schema: pa.Schema, batches=None) -> tuple[pa.Schema, object]:
    """(the schema batches of `schema` have after `conform_batch`, the batches): counts as a tensor,
    evlib events as ours. Flat counts of variable-length lists are sized from the first batch,
    which is read ahead and put back in front of `batches`."""
    names = set(schema.names)
    if "counts" in names and {"trial", "frame"} <= names:
        first = None
        if _needs_a_look(schema) and batches is not None:
            batches = iter(batches)
            first = next(batches, None)
            batches = _chain(first, batches)
        return _frames_schema(schema, first), batches
    if {"t", "x", "y"} <= names and ("polarity" in names or "p" in names) and "trial" not in names:
        return _events_schema(schema), batches
    return schema, batches


def _needs_a_look(schema: pa.Schema) -> bool:
    counts = schema.field("counts").type
    return (pa.types.is_list(counts) or pa.types.is_large_list(counts)) and not os.environ.get(FRAME_SIZE_ENV) \
        and sch.sensor_of(schema) is None


def _chain(first, rest):
    if first is not None:
        yield first
    yield from rest


def conform_batch(batch: pa.RecordBatch, schema: pa.Schema, first_row: int = 0) -> pa.RecordBatch:
    """`batch` in the layout `accept` gave `schema` (a no-op for a batch already in it); `first_row`:
    the table's row number of the batch's first row, as errors name rows."""
    if "polarity" in batch.schema.names and "p" in schema.names and "polarity" not in schema.names:
        batch = _events_batch(batch)
    elif "t" in batch.schema.names and not pa.types.is_integer(batch.schema.field("t").type) and sch.kind_of(schema) == "events":
        batch = _events_batch(batch)
    if "counts" in schema.names and isinstance(schema.field("counts").type, pa.FixedShapeTensorType):
        index = batch.schema.get_field_index("counts")
        if index >= 0 and not isinstance(batch.column(index).type, pa.FixedShapeTensorType):
            tensor = _tensor(batch.column(index), schema.field("counts").type, first_row)
            batch = batch.set_column(index, pa.field("counts", tensor.type), tensor)
    return batch


# ---------------------------------------------------------------- frames


def _frames_schema(schema: pa.Schema, first: pa.RecordBatch | None = None) -> pa.Schema:
    counts = schema.field("counts").type
    if isinstance(counts, pa.FixedShapeTensorType):
        return schema
    if not (pa.types.is_list(counts) or pa.types.is_large_list(counts) or pa.types.is_fixed_size_list(counts)):
        raise SchemaError(f"frames column 'counts' must be a tensor or a list of counts (2 x H x W per frame), got {counts}")
    shape, value = _nested_shape(counts)
    if shape is None:
        shape = (2, *_frame_size(schema, first))
    if not (pa.types.is_integer(value) or pa.types.is_floating(value)):
        raise SchemaError(f"frames column 'counts' holds {value}, not numbers")
    target = pa.uint16() if pa.types.is_integer(value) and value.bit_width <= 16 else pa.uint32() if pa.types.is_integer(value) else pa.float32()
    index = schema.get_field_index("counts")
    schema = schema.set(index, pa.field("counts", pa.fixed_shape_tensor(target, shape)))
    if sch.kind_of(schema) is None:
        schema = sch.set_meta(schema, kind="frames")
    if sch.sensor_of(schema) is None:
        schema = sch.set_meta(schema, sensor=sch.sensor_meta(shape[2], shape[1]))
    return schema


def _nested_shape(counts: pa.DataType) -> tuple[tuple | None, pa.DataType]:
    """(shape, value type) of nested fixed-size lists (2, H, W); (None, value type) of a flat list."""
    sizes, typ = [], counts
    while pa.types.is_list(typ) or pa.types.is_large_list(typ) or pa.types.is_fixed_size_list(typ):
        sizes.append(typ.list_size if pa.types.is_fixed_size_list(typ) else None)
        typ = typ.value_type
    if len(sizes) == 3 and None not in sizes and sizes[0] == 2:
        return tuple(sizes), typ
    if len(sizes) != 1:
        raise SchemaError(f"frames column 'counts' is a {len(sizes)}-deep list ({counts}); give it as a flat list of "
                          "2 x H x W values, or nested fixed-size lists of shape (2, H, W)")
    return None, typ


def _frame_size(schema: pa.Schema, first: pa.RecordBatch | None) -> tuple[int, int]:
    """(H, W) of flat counts: from the environment, the metadata, or a square frame's length."""
    counts = schema.field("counts").type
    length = counts.list_size if pa.types.is_fixed_size_list(counts) else None
    if length is None and first is not None and first.num_rows:
        length = int(pc.list_value_length(first.column("counts"))[0].as_py() or 0)
    sensor = sch.sensor_of(schema)
    given = os.environ.get(FRAME_SIZE_ENV)
    if given:
        width, height = parse_size(given)
        if sensor and sensor != (width, height):  # the table's own word on its size, against a guess made for tables without one
            raise SchemaError(f"--frame-size {width}x{height} ({FRAME_SIZE_ENV}) contradicts the table's own frame size "
                              f"{sensor[0]}x{sensor[1]} (its neurotac:sensor metadata); leave --frame-size out")
        return height, width
    if sensor:
        return sensor[1], sensor[0]
    if length is not None and length % 2 == 0 and math.isqrt(length // 2) ** 2 == length // 2:
        side = math.isqrt(length // 2)
        return side, side
    raise SchemaError(f"frames 'counts' are flat lists of {length or 'an unknown number of'} values and the table does not say the frame size "
                      f"(its neurotac:sensor metadata was lost on the way); give it: neurotac --frame-size WxH ...")


def _wrong_length(row: int, held: int, target: pa.FixedShapeTensorType) -> SchemaError:
    expected = f"{int(np.prod(target.shape))} (2x{target.shape[1]}x{target.shape[2]})"
    if row:  # the rows before it held the size: the table mixes frame sizes, which no frame size given can mend
        return SchemaError(f"frames 'counts' of row {row} hold {held} values where the rows before it hold {expected}: the table "
                           "mixes frame sizes; crop every part to one size before joining them")
    return SchemaError(f"frames 'counts' of row 0 hold {held} values, expected {expected}; give the frame size: "
                       "neurotac --frame-size WxH ...")


def _tensor(column: pa.Array, target: pa.FixedShapeTensorType, first_row: int = 0) -> pa.ExtensionArray:
    """A list column of counts as `target`, every row checked to hold 2·H·W values (rows named from `first_row`)."""
    size = int(np.prod(target.shape))
    values = column
    while not (pa.types.is_integer(values.type) or pa.types.is_floating(values.type)):
        if values.null_count:
            raise SchemaError("frames column 'counts' has empty (null) frames; drop those rows or fill them with zeros")
        flat_fixed = values is column and pa.types.is_fixed_size_list(values.type) and not pa.types.is_nested(values.type.value_type)
        if flat_fixed and values.type.list_size != size:  # one length for every row: a frame size that does not fit them
            raise _wrong_length(first_row, values.type.list_size, target)
        if not pa.types.is_fixed_size_list(values.type):
            lengths = pc.list_value_length(values).to_numpy(zero_copy_only=False)
            if len(lengths) and (lengths.min() != lengths.max() or (values is column and lengths[0] != size)):
                bad = int(np.flatnonzero(lengths != (size if values is column else lengths[0]))[0]) if len(lengths) else 0
                raise _wrong_length(first_row + bad, lengths[bad], target)
        values = pc.list_flatten(values)
    try:
        values = values.cast(target.value_type, safe=True)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as error:
        raise SchemaError(f"frames 'counts' cannot be read as {target.value_type} counts ({error})") from None
    storage = pa.FixedSizeListArray.from_arrays(values, size)
    return pa.ExtensionArray.from_storage(target, storage)


# ---------------------------------------------------------------- events


def _events_schema(schema: pa.Schema) -> pa.Schema:
    if "polarity" not in schema.names and pa.types.is_integer(schema.field("t").type):
        return schema
    fields = [pa.field("t", pa.int64()), pa.field("x", pa.uint16()), pa.field("y", pa.uint16()), pa.field("p", pa.uint8())]
    others = [field for field in schema if field.name not in ("t", "x", "y", "p", "polarity")]
    out = pa.schema(fields + others, metadata=schema.metadata)
    return out if sch.kind_of(out) else sch.set_meta(out, kind="events")


def _events_batch(batch: pa.RecordBatch) -> pa.RecordBatch:
    t = batch.column("t")
    if pa.types.is_duration(t.type) or pa.types.is_timestamp(t.type):
        per = _US_PER[t.type.unit]
        raw = t.cast(pa.int64()).to_numpy(zero_copy_only=False)
        t = pa.array(raw // 1000 if per < 1 else raw * int(per), pa.int64())
    p = batch.column("polarity" if "polarity" in batch.schema.names else "p")
    p = pc.cast(pc.greater(p.cast(pa.int8()) if pa.types.is_boolean(p.type) else p, 0), pa.uint8())
    columns = {"t": t, "x": batch.column("x"), "y": batch.column("y"), "p": p}
    others = [name for name in batch.schema.names if name not in ("t", "x", "y", "p", "polarity")]
    return pa.RecordBatch.from_arrays([*columns.values(), *(batch.column(name) for name in others)],
                                      names=[*columns, *others])
