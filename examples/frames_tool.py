"""Two small table operations the chapter scripts need and the commands do not offer.

    python examples/frames_tool.py select IN OUT object=bolt12     # rows whose label has that value
    python examples/frames_tool.py concat OUT IN [IN ...]          # stack frames tables, augmented or not
    python examples/frames_tool.py box FRAMES                      # X,Y,W,H of its last `crop`

`select` keeps the schema and its metadata (kind, sensor, window, history). `concat` accepts original
frames beside augmented ones (which carry `source_trial` and `augment`): originals get
`source_trial` = their trial and `augment` = "", as `neurotac augment` writes them. Parquet in and out.
`box` reads the box `crop --center auto` chose from the table's history, so a second recording (the
still scene for `augment --noise`) can be cropped to the same pixels.
"""

import json

import sys

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq


def select(source, target, condition):
    name, _, value = condition.partition("=")
    table = pq.read_table(source)
    if name not in table.schema.names:
        sys.exit(f"frames_tool select: no column {name!r} in {source}")
    chosen = table.filter(pc.equal(table.column(name), value))
    if chosen.num_rows == 0:
        sys.exit(f"frames_tool select: no row of {source} has {name}={value}")
    pq.write_table(chosen, target, compression="zstd")


def concat(target, sources):
    tables = [pq.read_table(source) for source in sources]
    augmented = any("source_trial" in t.schema.names for t in tables)
    if augmented:
        tables = [_with_augment_columns(t) for t in tables]
    names = tables[0].schema.names
    first = tables[0]
    rest = [t.select(names).cast(first.schema) for t in tables[1:]]
    pq.write_table(pa.concat_tables([first, *rest]), target, compression="zstd")


def box(source):
    history = json.loads(pq.read_schema(source).metadata.get(b"neurotac:history", b"[]"))
    for entry in reversed(history):
        report = entry.get("args", {}).get("report", {}) if entry.get("command") == "crop" else {}
        if report.get("box"):
            print(",".join(str(v) for v in report["box"]))
            return
    sys.exit(f"frames_tool box: {source} has no crop box in its history")


def _with_augment_columns(table):
    if "source_trial" not in table.schema.names:
        table = table.append_column("source_trial", table.column("trial"))
    if "augment" not in table.schema.names:
        table = table.append_column("augment", pa.array([""] * table.num_rows, pa.string()))
    return table


if __name__ == "__main__":
    verb, *arguments = sys.argv[1:] or ["help"]
    if verb == "select" and len(arguments) == 3:
        select(*arguments)
    elif verb == "box" and len(arguments) == 1:
        box(arguments[0])
    elif verb == "concat" and len(arguments) >= 2:
        concat(arguments[0], arguments[1:])
    else:
        sys.exit(__doc__)
