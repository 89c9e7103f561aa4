"""Tables as text files for other tools: `-o x.csv`, `-o x.json` (one array of objects), `-o x.ndjson`
(one object per line).

For tables of plain columns: predictions, metrics, events. Text keeps no schema metadata (kind,
sensor, window, history): keep Parquet for tables that go back into neurotac. Tensors (frames'
counts) have no text form and are refused with what to do; nested lists (a recordings table's
events and force) go into JSON and NDJSON as arrays, and are refused by CSV. Float NaN, which JSON
cannot hold, is written as null.
"""

import json
import math

import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError

FORMATS = ("csv", "json", "ndjson")
FLAT = "write .parquet, .arrow or .arrows instead; CSV, JSON and NDJSON take predictions, metrics and events tables"


def check_writable(schema: pa.Schema, fmt: str) -> None:
    """Refuse columns that `fmt` cannot hold, naming the first one."""
    kind = sch.kind_of(schema) or "table"
    for field in schema:
        if isinstance(field.type, pa.BaseExtensionType) or pa.types.is_fixed_size_list(field.type):
            raise NeurotacError(f"cannot write a {kind} table as {fmt.upper()}: column {field.name!r} holds tensors "
                                f"({field.type}), which text cannot hold ({FLAT})")
        if fmt == "csv" and pa.types.is_nested(field.type):
            raise NeurotacError(f"cannot write a {kind} table as CSV: column {field.name!r} holds nested values "
                                f"({field.type}) (write .json or .ndjson for arrays, or {FLAT.split('; ')[0]})")


def write_text(path: str, fmt: str, schema: pa.Schema, batches) -> None:
    """Write batches of `schema` into `path` (a temporary file the caller renames) as `fmt`."""
    check_writable(schema, fmt)
    bare = schema.remove_metadata()
    if fmt == "csv":
        import pyarrow.csv as csv

        with csv.CSVWriter(path, bare) as writer:
            for batch in batches:
                writer.write_batch(pa.RecordBatch.from_arrays(batch.columns, schema=bare))
        return
    with open(path, "w", encoding="utf-8") as sink:
        first = True
        sink.write("[" if fmt == "json" else "")
        for batch in batches:
            for row in batch.to_pylist():
                text = json.dumps({key: jsonable(value) for key, value in row.items()}, ensure_ascii=False, allow_nan=False)
                if fmt == "json":
                    sink.write(("\n" if first else ",\n") + text)
                else:
                    sink.write(text + "\n")
                first = False
        sink.write("\n]\n" if fmt == "json" else "")


def jsonable(value):
    """`value` as strict JSON holds it: NaN and infinities as null (jq refuses a bare NaN), tuples as lists, bytes as text."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(item) for item in value]
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return value
