"""Rows of any table: select by an expression, concatenate with checks, split into training and test.

Expressions are SQL (DuckDB), evaluated over the table's plain columns (not counts, events or force
lists): `material = 'steel' AND frame < 30`, `phase IN ('holding', 'releasing')`,
`t BETWEEN 0 AND 200000` (µs), `trial LIKE 'steel-%'`. DuckDB only computes which rows to keep;
the rows themselves are taken with pyarrow, so tensors, nested lists and the metadata pass unchanged.
A row whose expression is NULL (a missing label) is not kept. DuckDB runs without file access.

Splits move whole trials, and an augmented copy goes with its source (`source_trial`), so no test
trial is seen in training under another name.
"""

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, SchemaError, UsageError


ROW_INDEX = "neurotac_row_index"  # a column the condition is evaluated beside, to keep the rows in order
# Functions of the clock: not volatile to DuckDB, but their answer depends on when the command runs.
# The last five are also written without parentheses, which DuckDB parses as column names.
CLOCK_FUNCTIONS = {"now", "today", "get_current_time", "get_current_timestamp", "transaction_timestamp", "current_localtime",
                   "current_localtimestamp", "current_date", "current_time", "current_timestamp", "localtime", "localtimestamp"}
PER_ROW = "an aggregate such as max() needs OVER (), e.g. frame = max(frame) OVER (PARTITION BY trial)"


def plain_columns(schema: pa.Schema) -> list[str]:
    return [f.name for f in schema if not (pa.types.is_nested(f.type) or isinstance(f.type, pa.BaseExtensionType))]


def where_mask(table: pa.Table, expression: str) -> np.ndarray:
    """Which rows of `table` the SQL `expression` keeps (NULL: not kept)."""
    import duckdb

    if not expression.strip():
        raise NeurotacError("the condition is empty (give one, e.g. frame < 30)")
    plain = table.select(plain_columns(table.schema)).replace_schema_metadata(None)
    # DuckDB may return rows in another order (a window function sorts them): each row carries its
    # index, and the answer is ordered by it (a name no column has, SQL's names being blind to case)
    index = ROW_INDEX
    while index.lower() in {name.lower() for name in plain.column_names}:
        index += "_"
    plain = plain.append_column(index, pa.array(np.arange(table.num_rows, dtype=np.int64)))
    connection = duckdb.connect()
    try:
        connection.execute("SET enable_external_access = false")
        nodes = _parsed_nodes(connection, expression)
        _refuse_changing_answers(connection, expression, nodes, plain.column_names)
        _refuse_names_sql_confuses(expression, nodes, plain.column_names)
        connection.register("input_rows", plain)
        # DuckDB casts a string to a truth value ('yes', 't', '1'), so `--where "'yes'"` would keep every row
        given = connection.execute(f"SELECT typeof(({expression})) FROM input_rows LIMIT 1").fetchall()
        if given and given[0][0] not in ("BOOLEAN", '"NULL"', "NULL"):
            raise NeurotacError(f"{expression!r} is not a condition (it gives {given[0][0]} values; compare, e.g. frame < 30)")
        keep = connection.execute(f"SELECT coalesce(({expression}), false) AS keep FROM input_rows "
                                  f'ORDER BY "{index}"').fetchnumpy()["keep"]
    except duckdb.Error as error:
        first = str(error).splitlines()[0]
        # the condition is set inside a query, so a comment or a `;` cuts the query, not the condition
        cut = next((f"; a condition cannot hold `{mark}`, which cuts the query it is set in" for mark in ("--", "/*", ";") if mark in expression), "")
        if index in first and index not in expression and "Candidate bindings" not in first and not cut:
            raise NeurotacError(f"{expression!r} is not a condition on each row ({PER_ROW})") from None
        raise NeurotacError(f"cannot evaluate {expression!r}: {first}{cut} (columns: {', '.join(plain.column_names[:-1])}; "
                            "write SQL, strings in single quotes, times in µs)") from None
    finally:
        connection.close()
    keep = np.asarray(keep)
    if len(keep) != table.num_rows:
        raise NeurotacError(f"{expression!r} is not a condition on each row ({len(keep):,} values for {table.num_rows:,} rows; {PER_ROW})")
    return keep


def _refuse_names_sql_confuses(expression: str, nodes: list[dict], columns: list[str]) -> None:
    """Columns whose names differ only in case are one name to SQL: DuckDB renamed the second
    (`Material` -> `Material_1`), so a condition on it read the other column and kept the wrong rows
    without a word. Refused where the condition names them (in DuckDB's own parse of it)."""
    groups = {}
    for name in columns:
        groups.setdefault(name.lower(), []).append(name)
    named = {node["column_names"][-1].lower() for node in nodes if node.get("class") == "COLUMN_REF" and node.get("column_names")}
    for lower, names in groups.items():
        if len(names) > 1 and lower in named:
            raise NeurotacError(f"the columns {', '.join(names)} differ only in case, which SQL does not tell apart, so "
                                f"--where {expression!r} could read either; rename one (e.g. with DuckDB or Polars) first")


def _refuse_changing_answers(connection, expression: str, nodes: list[dict], columns: list[str]) -> None:
    """A condition that draws random numbers or reads the clock keeps other rows on each run, so the
    same command would not write the same bytes. Found in DuckDB's own parse of the expression, so a
    string such as 'random()' is not mistaken for a call."""
    volatile = {name for (name,) in connection.execute(
        "SELECT DISTINCT function_name FROM duckdb_functions() WHERE stability = 'VOLATILE'").fetchall()} | CLOCK_FUNCTIONS
    for node in nodes:
        called, shown = None, None
        if node.get("class") == "FUNCTION":
            called = node.get("function_name")
            shown = f"{called}()"
        elif node.get("class") == "COLUMN_REF" and len(node.get("column_names", ())) == 1 and node["column_names"][0] not in columns:
            called = shown = node["column_names"][0]
        if called and called.lower() in volatile:
            raise UsageError(f"--where {expression!r} calls {shown}, whose answer changes from run to run, so the rows kept "
                             "would too; select by the table's values (for a random share of the trials, "
                             "`neurotac split --fraction F --seed N`)")
        if node.get("sample"):
            raise UsageError(f"--where {expression!r} samples rows, which keeps other rows on each run; "
                             "for a random share of the trials, `neurotac split --fraction F --seed N`")


def _parsed_nodes(connection, expression: str) -> list[dict]:
    """Every node (a dict) of DuckDB's own parse of the condition; none where it does not parse
    (evaluating it says what is wrong)."""
    import json

    parsed = json.loads(connection.execute("SELECT json_serialize_sql(?)", [f"SELECT ({expression})"]).fetchall()[0][0])
    found, nodes = [], [] if parsed.get("error") else [parsed]
    while nodes:
        node = nodes.pop()
        if isinstance(node, list):
            nodes.extend(node)
        elif isinstance(node, dict):
            found.append(node)
            nodes.extend(node.values())
    return found


def select(table: pa.Table, expression: str) -> tuple[pa.Table, dict]:
    """The rows the expression keeps; (table, {"kept": n, "dropped": m}). A condition that keeps no
    row is refused: the empty table would only fail in the next command, far from its cause."""
    keep = where_mask(table, expression)
    if not keep.any():
        raise NeurotacError(f"no row matches --where {expression!r} (of {table.num_rows:,} rows; `neurotac info` shows "
                            "the trials and label values)")
    return table.filter(pa.array(keep)), {"kept": int(keep.sum()), "dropped": int((~keep).sum())}


# ---------------------------------------------------------------- concat


def trial_ids(table: pa.Table) -> list[str]:
    return pc.unique(table.column("trial")).to_pylist() if "trial" in table.column_names else []


def concat(parts: list[tuple[str, pa.Table]], rename: bool = False) -> tuple[pa.Table, list[str]]:
    """One table of several (name, table) parts of one kind. Trials already seen in an earlier part
    are refused, or with `rename` get `~2`, `~3`, ... (returned as notes for a warning), and so do
    the `source_trial`s that name them."""
    seen, notes, tables = {}, [], []
    check_alike(parts)
    if len(parts) > 1 and "trial" not in parts[0][1].column_names and sch.table_kind(parts[0][1].schema) != "metrics":
        raise SchemaError(f"{parts[0][0]} has no trial column: an events table is one recording on one clock, and "
                          "recordings joined end to end would read as one; give the camera files to `neurotac import` "
                          "together (one trial per file), or sync each and concatenate the recordings tables")
    for name, table in parts:
        ids = trial_ids(table)
        clash = [trial for trial in ids if trial in seen]
        if clash and not rename:
            raise SchemaError(f"trial {clash[0]!r} is in both {seen[clash[0]]} and {name} ({len(clash)} trial(s) in both); "
                              "a trial twice would be trained on twice: drop one, or give --rename to suffix the later ones")
        if clash:
            _refuse_orphan_copies(name, table, clash, seen)
            taken = set(seen) | set(ids)  # nor a name the part itself holds (`a` beside `a~2`)
            mapping = {}
            for trial in clash:
                mapping[trial] = _free_name(trial, taken)
                taken.add(mapping[trial])
            notes.append(f"{name}: renamed {len(clash)} trial(s), e.g. {clash[0]} -> {mapping[clash[0]]}")
            # an augmented copy's source is renamed with it: it would name the other part's grasp
            for column in [c for c in ("trial", "source_trial") if c in table.column_names]:
                renamed = [mapping.get(trial, trial) for trial in table.column(column).to_pylist()]
                index = table.schema.get_field_index(column)
                table = table.set_column(index, table.schema.field(index), pa.array(renamed, pa.string()))
            ids = [mapping.get(trial, trial) for trial in ids]
        seen.update({trial: name for trial in ids})
        tables.append(table)
    first = tables[0].schema
    try:
        combined = pa.concat_tables([t.replace_schema_metadata(first.metadata) for t in tables], promote_options="none")
    except pa.ArrowInvalid as error:
        differences = [_difference(first, table.schema, name) for (name, _), table in zip(parts[1:], tables[1:])]
        detail = "; ".join(d for d in differences if d) or str(error).splitlines()[0]
        raise SchemaError(f"the tables have different columns or types ({detail}); "
                          "make them with the same steps and labels (DuckDB or Polars can drop or add a column)") from None
    return combined, notes


def _refuse_orphan_copies(name: str, table: pa.Table, clash: list, seen: dict) -> None:
    """An augmented copy renamed for a clash whose source is not in its own part (`augment
    --only-augmented`) names a trial of an earlier part, which may or may not be the grasp it was
    made from: renamed, it would point at the wrong one, or lose its source."""
    if "source_trial" not in table.column_names:
        return
    own = set(trial_ids(table))
    pairs = set(zip(table.column("trial").to_pylist(), table.column("source_trial").to_pylist()))
    orphans = [(trial, source) for trial, source in pairs if trial in clash and source and source != trial and source not in own]
    if orphans:
        trial, source = sorted(orphans)[0]
        raise SchemaError(f"{name}'s augmented copy {trial!r} clashes with a trial of {seen[trial]}, and its source {source!r} "
                          f"is not in {name}: renamed, it would name {seen.get(source, 'no')} trial's grasp, which may not be "
                          "its own; concatenate the copies with their originals first (or augment after concatenating)")


def _difference(first: pa.Schema, other: pa.Schema, name: str) -> str:
    """What `other` (the table `name`) has that differs from the first table: columns missing, added, or of another type or order."""
    missing = [n for n in first.names if n not in other.names]
    extra = [n for n in other.names if n not in first.names]
    typed = [f"{n} is {other.field(n).type}, not {first.field(n).type}" for n in first.names
             if n in other.names and not other.field(n).type.equals(first.field(n).type)]
    words = ([f"no {', '.join(missing)}"] if missing else []) + ([f"{', '.join(extra)}, which the first table has not"] if extra else []) + typed
    if not words and first.names != other.names:
        words = ["its columns in another order"]
    return f"{name} has {'; '.join(words)}" if words else ""


def check_alike(parts: list[tuple[str, pa.Table]]) -> None:
    """The parts are of one kind, sensor size and frame window."""
    first_name, first = parts[0]
    facts = lambda schema: {"kind": sch.table_kind(schema), "sensor size": sch.sensor_of(schema)}  # noqa: E731
    expected = facts(first.schema)
    for name, table in parts[1:]:
        for what, value in facts(table.schema).items():
            if value is not None and expected[what] is not None and value != expected[what]:
                raise SchemaError(f"{name} has {what} {_show(value)}, {first_name} {_show(expected[what])}; "
                                  "concatenate tables made alike (crop and frame them the same way)")
        windows = sch.unlike_windows(first.schema, table.schema)
        if windows and None not in windows:
            raise SchemaError(f"{name} has frame window (µs) {windows[1]}, {first_name} {windows[0]}; "
                              "concatenate tables made alike (crop and frame them the same way)")
        if windows:  # the output keeps one table's window: the other's frames would be labelled with it
            known, unknown = (first_name, name) if windows[0] is not None else (name, first_name)
            raise SchemaError(f"{unknown} does not record its frame window (metadata {sch.WINDOW}) and {known} has "
                              f"{windows[0] or windows[1]} µs; frame both with `neurotac frame --window` so that the window is known")
        _check_made_alike(first_name, first.schema, name, table.schema)


def _check_made_alike(first_name: str, first: pa.Schema, name: str, other: pa.Schema) -> None:
    """Frames pooled or scaled differently (`schema.made_unlike`) are not one table's."""
    unlike = sch.made_unlike(first_name, first, name, other)
    if unlike:
        raise SchemaError(f"{unlike}; concatenate tables made alike (crop and frame them the same way)")


def _show(value) -> str:
    return f"{value[0]}x{value[1]}" if isinstance(value, tuple) else str(value)


def _free_name(trial: str, seen) -> str:
    number = 2
    while f"{trial}~{number}" in seen:
        number += 1
    return f"{trial}~{number}"


# ---------------------------------------------------------------- split


def _groups(table: pa.Table) -> np.ndarray:
    """Each row's split group: its source trial (an augmented copy goes with its source), else its trial."""
    column = "source_trial" if "source_trial" in table.column_names else "trial"
    groups = table.column(column).to_numpy(zero_copy_only=False)
    if column == "source_trial":
        trials = table.column("trial").to_numpy(zero_copy_only=False)
        groups = np.where(pc.is_null(table.column(column)).to_numpy(zero_copy_only=False), trials, groups)
    return groups.astype(object)


def split(table: pa.Table, fraction: float | None = None, where: str | None = None, per: str | None = None,
          seed: int = 0) -> tuple[pa.Table, pa.Table, dict]:
    """(train, test, report): test = the trials `where` selects (any of its rows), or a seeded share
    `fraction` of the trials, drawn within each value of the label `per` when given."""
    if "trial" not in table.column_names:
        raise SchemaError("split moves whole trials: the table has no trial column (select rows with `neurotac select`)")
    if (fraction is None) == (where is None):
        raise UsageError("give either --fraction (a seeded share of the trials) or --where (the test trials by a condition)")
    if per is not None and where is not None:
        raise UsageError("--per draws --fraction's share within each label value; --where chooses the test trials itself")
    groups = _groups(table)
    if where is not None:
        test_groups = set(groups[where_mask(table, where)].tolist())
    else:
        if not 0 < fraction < 1:
            raise UsageError(f"--fraction must lie between 0 and 1, got {fraction}")
        test_groups = _draw(table, groups, fraction, per, np.random.default_rng(seed))
    in_test = np.isin(groups, list(test_groups))
    if in_test.all() or not in_test.any():
        lone = per is not None and where is None and all(len(members) == 1 for members in _strata(table, groups, per).values())
        advice = ("every --per group holds one trial, whose share rounds to none or all of it: split without --per, or per "
                  "a label of larger groups") if lone else "change --fraction or --where"
        raise NeurotacError(f"the split leaves the {'training' if in_test.all() else 'test'} table empty; {advice}")
    train, test = table.filter(pa.array(~in_test)), table.filter(pa.array(in_test))
    report = {"train_trials": len(set(groups[~in_test].tolist())), "test_trials": len(test_groups),
              "train_rows": train.num_rows, "test_rows": test.num_rows, "test": sorted(test_groups)}
    return train, test, report


def _strata(table: pa.Table, groups: np.ndarray, per: str | None) -> dict:
    """{label value: its trials} (one stratum of every trial without `per`)."""
    unique = list(dict.fromkeys(groups.tolist()))
    if per is None:
        return {"": unique}
    if per not in table.column_names:
        raise SchemaError(f"no label column {per!r} to split per (labels: {', '.join(sch.label_columns(table.schema))})")
    values = pa.table({"group": pa.array(groups.tolist(), pa.string()), "value": table.column(per)})
    counts = values.group_by("group").aggregate([("value", "count_distinct", pc.CountOptions(mode="all"))])
    mixed = pc.filter(counts.column("group"), pc.greater(counts.column("value_count_distinct"), 1))
    if len(mixed):  # a per-row column (force, phase, frame) would be read at each trial's last row
        raise UsageError(f"--per {per}: {per} differs within trial {mixed[0].as_py()!r}; split per a label each trial has "
                         f"once (labels: {', '.join(sch.label_columns(table.schema))})")
    labels = dict(zip(groups.tolist(), table.column(per).to_pylist()))
    strata = {}
    for group in unique:
        strata.setdefault(labels[group], []).append(group)
    return strata


def _draw(table: pa.Table, groups: np.ndarray, fraction: float, per: str | None, rng) -> set:
    chosen = set()
    for members in _strata(table, groups, per).values():
        count = int(round(fraction * len(members)))
        chosen.update(rng.choice(np.array(members, dtype=object), size=count, replace=False).tolist() if count else [])
    return chosen
