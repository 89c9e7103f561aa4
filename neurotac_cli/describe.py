"""What a table holds, for a person: one core function that returns a dict, and a text formatter.

`describe(schema, batches)` reads the batches once (memory does not grow with an events table) and
works on every kind: events, recordings, frames, predictions, metrics, and tables of no known kind.
The description never names the container (stream, Arrow file, Parquet), so the same table
describes the same wherever it is stored.
"""

import os

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, cannot_open
from neurotac_cli.units import counted

TRIALS_SHOWN = 20
METRICS_SHOWN = 50  # metric rows in the text; METRICS_KEPT in --json (every one with --all)
METRICS_KEPT = 200


def describe(schema: pa.Schema, batches, camera: dict | None = None, everything: bool = False) -> dict:
    """A dict describing the table `schema` + `batches`. `camera` = {"format": ...} for a camera file
    decoded on the fly (not imported yet). `everything`: keep every metric row, not the first METRICS_KEPT."""
    kind = sch.table_kind(schema)
    sensor = sch.sensor_of(schema)
    info = {"kind": kind or "unknown", "rows": 0}
    if camera:
        info["camera_file"] = camera
    if sensor:
        info["sensor"] = {"width": sensor[0], "height": sensor[1]}
    source = sch.get_meta(schema, sch.SOURCE)
    if source:
        info["source"] = source
    triggers = sch.get_meta(schema, "neurotac:triggers")
    if isinstance(triggers, list):
        info["triggers"] = {"count": len(triggers), "types": sorted({str(t.get("type", "?")) if isinstance(t, dict) else "?" for t in triggers})}
    elif triggers is not None:
        info["triggers"] = {"unreadable": str(triggers)[:80]}  # another tool's metadata: shown, not trusted
    window = sch.get_meta(schema, sch.WINDOW)
    if window is not None:
        info["window_us"] = int(window)
    sync = sch.get_meta(schema, sch.SYNC)
    if sync is not None:
        info["sync"] = sync
    summary = {"events": _Events, "recordings": _Recordings, "frames": _Frames}.get(kind, _Rows)(schema)
    if everything and isinstance(summary, _Rows):
        summary.keep = None
    for batch in batches:
        info["rows"] += batch.num_rows
        summary.add(batch)
    info.update(summary.result())
    info["columns"] = {field.name: str(field.type) for field in schema}
    info["history"] = sch.get_meta(schema, sch.HISTORY, [])
    return info


class _Events:
    """Streaming statistics of an events table: time span, backward steps, ON share."""

    def __init__(self, schema):
        self.low = self.high = self.last = None
        self.count = self.on = self.backward = self.largest_back = 0

    def add(self, batch):
        if not batch.num_rows:
            return
        t = batch.column("t").to_numpy()
        p = batch.column("p").to_numpy()
        self.count += len(t)
        self.on += int(np.count_nonzero(p))
        steps = np.diff(t)
        across = 0 if self.last is None else self.last - int(t[0])  # the step back from the last batch, where positive
        self.backward += int(np.count_nonzero(steps < 0)) + int(across > 0)
        self.largest_back = max(self.largest_back, across, -int(steps.min(initial=0)))
        self.last = int(t[-1])
        low, high = int(t.min()), int(t.max())
        self.low = low if self.low is None else min(self.low, low)
        self.high = high if self.high is None else max(self.high, high)

    def result(self):
        if not self.count:
            return {"trials": 0, "events": 0}
        return {"trials": 1, "events": self.count, **_time_stats(self.low, self.high, self.count, self.on), "backward_steps": self.backward,
                "largest_backward_step_us": self.largest_back}


def _time_stats(low, high, events, on) -> dict:
    span = int(high - low)
    stats = {"t_first_us": int(low), "t_last_us": int(high), "span_us": span}
    stats["event_rate_per_s"] = float(events / (span / 1e6)) if span > 0 else None
    stats["on_share"] = float(on / events) if events else None
    return stats


class _Recordings:
    """Per-trial events, force samples and labels of a recordings table."""

    def __init__(self, schema):
        self.labels = sch.label_columns(schema)
        self.trials = []
        self.on = 0
        self.events = 0

    def add(self, batch):
        import pyarrow.compute as pc  # only recordings need it: its import costs every `info`

        names = batch.schema.names
        ids = batch.column("trial").to_pylist()
        t0 = batch.column("t0").to_numpy(zero_copy_only=False)
        events = batch.column("events")
        counts = pc.list_value_length(events).fill_null(0).to_numpy(zero_copy_only=False)
        flat = pc.list_flatten(events)
        p = pc.struct_field(flat, "p").to_numpy(zero_copy_only=False) if len(flat) else np.zeros(0)
        t = pc.struct_field(flat, "t").to_numpy(zero_copy_only=False) if len(flat) else np.zeros(0, np.int64)
        self.on += int(np.count_nonzero(p))
        self.events += int(len(p))
        ends = np.cumsum(counts)
        starts = ends - counts
        force = batch.column("force") if "force" in names else None
        force_counts = pc.list_value_length(force).fill_null(0).to_numpy(zero_copy_only=False) if force is not None else None
        force_values = pc.struct_field(pc.list_flatten(force), "value").to_numpy(zero_copy_only=False) if force is not None and len(pc.list_flatten(force)) else np.zeros(0)
        force_ends = np.cumsum(force_counts) if force_counts is not None else None
        label_values = {name: batch.column(name).to_pylist() for name in self.labels}
        for i, trial in enumerate(ids):
            segment = t[starts[i] : ends[i]]
            row = {"trial": trial, "t0_us": int(t0[i]), "events": int(counts[i])}
            if len(segment):
                row["span_us"] = int(segment.max() - segment.min())
                row["on_share"] = float(np.count_nonzero(p[starts[i] : ends[i]]) / len(segment))
            if force_counts is not None:
                values = force_values[force_ends[i] - force_counts[i] : force_ends[i]]
                row["force_samples"] = int(force_counts[i])
                if len(values):
                    row["force_max_n"] = float(np.nanmax(values))
            row["labels"] = {name: label_values[name][i] for name in self.labels}
            self.trials.append(row)

    def result(self):
        return {
            "trials": len(self.trials),
            "events": self.events,
            "on_share": float(self.on / self.events) if self.events else None,
            "labels": _label_values(self.trials),
            "per_trial": self.trials,
        }


class _Frames:
    """Frames per trial, ON share of the counts, phases and labels of a frames table."""

    def __init__(self, schema):
        self.labels = sch.label_columns(schema)
        self.shape = list(schema.field("counts").type.shape) if "counts" in schema.names and hasattr(schema.field("counts").type, "shape") else None
        self.trials = {}
        self.on = self.off = 0.0
        self.phases = {}
        self.force = [None, None]
        self.unique = sch.UniqueRows("frames") if "frame" in schema.names else None  # described, not refused
        self.repeated = None

    def add(self, batch):
        if not batch.num_rows:
            return
        ids = batch.column("trial").to_pylist()
        if self.unique is not None and self.repeated is None:
            try:
                self.unique.check(batch)
            except NeurotacError as repeated:  # the first one, as commands that train or score would name it
                self.repeated = str(repeated).split(" (")[0]
        counts = sch.counts_numpy(batch.column("counts")) if self.shape else None
        if counts is not None:
            sums = counts.reshape(len(counts), 2, -1).sum(axis=2, dtype=np.float64)
            self.off += float(sums[:, 0].sum())
            self.on += float(sums[:, 1].sum())
        if "phase" in batch.schema.names:
            for phase, n in zip(*np.unique(np.array(batch.column("phase").fill_null("none").to_pylist(), dtype=object).astype(str), return_counts=True)):
                self.phases[phase] = self.phases.get(phase, 0) + int(n)
        if "force" in batch.schema.names:
            force = batch.column("force").to_numpy(zero_copy_only=False).astype(np.float64)
            force = force[~np.isnan(force)]
            if len(force):
                low, high = float(force.min()), float(force.max())
                self.force = [low if self.force[0] is None else min(low, self.force[0]), high if self.force[1] is None else max(high, self.force[1])]
        label_values = {name: batch.column(name).to_pylist() for name in self.labels}
        for i, trial in enumerate(ids):
            row = self.trials.get(trial)
            if row is None:
                row = self.trials[trial] = {"trial": trial, "frames": 0, "labels": {name: label_values[name][i] for name in self.labels}}
            row["frames"] += 1

    def result(self):
        frames = [row["frames"] for row in self.trials.values()]
        total = self.on + self.off
        out = {
            "trials": len(self.trials),
            "frame_shape": self.shape,
            "frames_per_trial": {"min": min(frames), "max": max(frames), "mean": float(np.mean(frames))} if frames else None,
            "on_share": float(self.on / total) if total else None,
            "phases": dict(sorted(self.phases.items())),
            "force_range_n": self.force if self.force[0] is not None else None,
            "labels": _label_values(list(self.trials.values())),
            "per_trial": list(self.trials.values()),
        }
        if self.repeated:
            out["repeated_frame"] = self.repeated
        return out


class _Rows:
    """Predictions, metrics and tables of no known kind: trials and labels where there are, and metric values."""

    def __init__(self, schema):
        self.kind = sch.kind_of(schema)
        self.has_trial = "trial" in schema.names
        self.trials = set()
        self.metrics = []
        self.metric_rows = 0
        self.keep = METRICS_KEPT
        # predictions: force estimates against the measured force, classes against the true labels
        self.force = self.kind == "predictions" and {"force", "force_pred"} <= set(schema.names)
        self.squared = self.absolute = 0.0
        self.scored = 0
        self.classes = {name[: -len("_pred")]: [0, 0] for name in schema.names
                        if self.kind == "predictions" and name.endswith("_pred") and name != "force_pred"
                        and name[: -len("_pred")] in schema.names}

    def add(self, batch):
        if self.has_trial:
            self.trials.update(batch.column("trial").to_pylist())
        if self.kind == "metrics":
            self.metric_rows += batch.num_rows
            room = batch.num_rows if self.keep is None else max(self.keep - len(self.metrics), 0)
            self.metrics += batch.slice(0, room).to_pylist()
        if self.force:
            force = batch.column("force").to_numpy(zero_copy_only=False).astype(np.float64)
            error = batch.column("force_pred").to_numpy(zero_copy_only=False).astype(np.float64) - force
            known = np.isfinite(error)
            self.squared += float(np.sum(error[known] ** 2))
            self.absolute += float(np.sum(np.abs(error[known])))
            self.scored += int(known.sum())
        for name, counts in self.classes.items():
            truth, guess = batch.column(name).to_pylist(), batch.column(f"{name}_pred").to_pylist()
            known = [(t, g) for t, g in zip(truth, guess) if t is not None]
            counts[0] += sum(t == g for t, g in known)
            counts[1] += len(known)

    def result(self):
        out = {}
        if self.has_trial:
            out["trials"] = len(self.trials)
        if self.kind == "metrics":
            out["metrics"] = self.metrics
            out["metrics_rows"] = self.metric_rows
        if self.force and self.scored:
            out["force_error"] = {"frames": self.scored, "rmse_n": (self.squared / self.scored) ** 0.5,
                                  "mae_n": self.absolute / self.scored}
        scored = {name: {"correct": c, "trials": n} for name, (c, n) in self.classes.items() if n}
        if scored:
            out["accuracy"] = scored
        return out


def _label_values(rows) -> dict:
    values = {}
    for row in rows:
        for name, value in row.get("labels", {}).items():
            values.setdefault(name, set()).add(value)
    return {name: sorted(v for v in found if v is not None) for name, found in values.items()}


# ---------------------------------------------------------------- text


def format_text(info: dict, everything: bool = False) -> str:
    """The description as aligned `name  value` lines for a terminal; `everything`: every trial and
    metric row, not the first TRIALS_SHOWN and METRICS_SHOWN."""
    if info["kind"] == "model":
        return _aligned(_model_lines(info))
    if info["kind"] == "csv":
        pairs = [("file", f"{info['file']} (CSV text)"), ("rows", f"{info['rows']:,}"), ("columns", ", ".join(info["columns"]))]
        log = info.get("force_log")
        if log:
            from neurotac_cli.ops.forcelog import dated_note

            pairs.append(("force log", f"{counted(log['samples'], 'sample')} in {counted(log['trials'], 'trial')}, every "
                                       f"{log['period_ms']:g} ms over {log['span_s']:.3f} s; {log['force_n'][0]:.3g} .. "
                                       f"{log['force_n'][1]:.3g} N (as `sync --force` reads it)"
                                       + (dated_note(log["first_us"]) or "")))
        return _aligned(pairs)
    sync = info.get("sync") if isinstance(info.get("sync"), dict) else {}
    lines = _identity_pairs(info) + _content_pairs(info, sync)  # (name, value) pairs, aligned at the end
    lines += _trial_lines(info, sync, everything) + _metric_lines(info, everything) + _history_lines(info)
    return _aligned(lines)


def _aligned(lines: list) -> str:
    """(name, value) pairs with their values in one column; plain strings as they are."""
    width = max([13] + [len(line[0]) for line in lines if isinstance(line, tuple)])
    return "\n".join(f"{line[0]:<{width}} {line[1]}" if isinstance(line, tuple) else line for line in lines) + "\n"


def _identity_pairs(info: dict) -> list:
    """What the table is: file, kind, rows, trials, sensor, source, events."""
    pairs = []
    if "camera_file" in info:
        pairs.append(("file", f"camera file ({info['camera_file'].get('format_name', info['camera_file'].get('format'))}), decoded; not imported yet"))
    pairs += [("kind", info["kind"]), ("rows", f"{info['rows']:,}")]
    if "trials" in info:
        pairs.append(("trials", f"{info['trials']:,}"))
    if "sensor" in info:
        sensor = info["sensor"]
        origin = info.get("source", {}).get("sensor_from") if isinstance(info.get("source"), dict) else None
        if any(step.get("command") == "crop" for step in info.get("history") or []):
            origin = None  # the camera's size no longer: crop set this one
        note = {"file": " (from the file)", "option": " (from --sensor)", "events": " (extent of the events; the file does not say)"}.get(origin, "")
        pairs.append(("sensor", f"{sensor['width']}x{sensor['height']}{note}"))
    source = info.get("source")
    if isinstance(source, dict):
        text = f"{source.get('format', '?')} {source.get('file', '')}".strip()
        if source.get("camera"):
            text += f" ({source['camera']})"
        if source.get("cut_bytes"):
            text += f"; its last {source['cut_bytes']} bytes, a record cut short, were left out"
        if source.get("note"):
            text += f"; {source['note']}"
        pairs.append(("source", text))
    if info["kind"] == "recordings":
        pairs.append(("events", f"{info['events']:,}"))
    return pairs


def _content_pairs(info: dict, sync: dict) -> list:
    """What the table holds: time, rates, frames, phases, force, triggers, sync, scores, labels."""
    shown = [
        ("time", info.get("span_us") is not None, lambda: f"{_us(info['t_first_us'])} .. {_us(info['t_last_us'])} ({_duration(info['span_us'])})"),
        ("event rate", info.get("event_rate_per_s") is not None, lambda: f"{_rate(info['event_rate_per_s'])} events/s"),
        ("ON share", info.get("on_share") is not None, lambda: f"{info['on_share']:.3f}"),
        ("time order", info.get("backward_steps"), lambda: f"{info['backward_steps']:,} backward steps, the largest "
                                                              f"{_duration(info.get('largest_backward_step_us', 0))} (kept as the camera wrote them)"),
        ("window", "window_us" in info, lambda: _duration(info["window_us"])),
        ("frame shape", info.get("frame_shape"), lambda: "x".join(str(n) for n in info["frame_shape"]) + " (channels x rows x columns)"),
        ("frames/trial", info.get("frames_per_trial"), lambda: "{min}..{max} (mean {mean:.1f})".format(**info["frames_per_trial"])),
        ("repeated", info.get("repeated_frame"), lambda: f"{info['repeated_frame']} (one trial in two inputs? commands that "
         "train or score refuse it)"),
        ("phases", info.get("phases"), lambda: ", ".join(f"{k} {v:,}" for k, v in info["phases"].items())),
        ("force", info.get("force_range_n"), lambda: "{:.3f} .. {:.3f} N".format(*info["force_range_n"])),
        ("triggers", "triggers" in info, lambda: f"{info['triggers']['count']:,}"
         + (f" ({', '.join(info['triggers']['types'])})" if info["triggers"]["types"] else "")),
        # the sync settings; each trial's instant and score go on the trial's line
        ("sync", sync, lambda: _compact({key: value for key, value in sync.items() if key != "trials"})),
        ("force error", info.get("force_error"), lambda: "RMSE {rmse_n:.4g} N, MAE {mae_n:.4g} N over {frames:,} frames "
         "(force_pred - force)".format(**info["force_error"])),
    ]
    pairs = [(name, text()) for name, present, text in shown if present]
    for name, a in (info.get("accuracy") or {}).items():
        pairs.append((f"{name} accuracy", f"{100 * a['correct'] / a['trials']:.1f}% ({a['correct']} of {a['trials']} with a known {name})"))
    for name, values in (info.get("labels") or {}).items():
        pairs.append((f"label {name}", ", ".join(map(str, values)) if values else "(none)"))
    return pairs


def _trial_lines(info: dict, sync: dict, everything: bool = False) -> list:
    """One line per trial (the first TRIALS_SHOWN unless `everything`): frames, events, span, force,
    sync, labels."""
    if not info.get("per_trial"):
        return []
    synced = sync.get("trials") or {}
    lines = ["", "per trial:"]
    shown = info["per_trial"] if everything else info["per_trial"][:TRIALS_SHOWN]
    id_width = max(len(str(row["trial"])) for row in shown)
    for row in shown:
        parts = [str(row["trial"]).ljust(id_width)]
        if "frames" in row:
            parts.append(f"{row['frames']} frames")
        if "events" in row:
            parts.append(f"{row['events']:,} events")
        if "span_us" in row:
            parts.append(_duration(row["span_us"]))
        if "force_max_n" in row:
            parts.append(f"force max {row['force_max_n']:.3f} N")
        if isinstance(synced.get(row["trial"]), dict):
            parts.append(_sync_cell(synced[row["trial"]], sync.get("method")))
        parts += [f"{k}={v}" for k, v in row.get("labels", {}).items() if v is not None]
        lines.append("  " + "  ".join(parts))
    if len(info["per_trial"]) > len(shown):
        lines.append(f"  ... {len(shown)} of {len(info['per_trial'])} trials shown (all of them: --all)")
    return lines


def _metric_lines(info: dict, everything: bool = False) -> list:
    """The metric rows (the first METRICS_SHOWN unless `everything`), saying when some are left out."""
    if not info.get("metrics"):
        return []
    lines = ["", "metrics:"]
    rows = info["metrics"] if everything else info["metrics"][:METRICS_SHOWN]
    for row in rows:
        value = row.get("value")
        text = f"{value:.6g}" if isinstance(value, float) else str(value)
        lines.append(f"  {row.get('scope', '')}  {row.get('metric', '')}  {text}" + (f"  ({row['model']})" if row.get("model") else ""))
    total = info.get("metrics_rows", len(info["metrics"]))
    if total > len(rows):
        lines.append(f"  ... {len(rows)} of {total} rows shown (all of them: --all; as a file for a spreadsheet: "
                     "-o metrics.csv on the command that made them)")
    return lines


def _history_lines(info: dict) -> list:
    """The columns, then the history of commands that made the table."""
    lines = ["", ("columns:", ", ".join(f"{name}: {typ}" for name, typ in info["columns"].items()))]
    return lines + _steps_lines("history:", info.get("history") or [])


def _steps_lines(title: str, history: list) -> list:
    """A title, then one line per step of a history: the command, its settings, the version that ran it."""
    lines = [title if history else (title, "(none)")]
    for step in history:
        args = " ".join(f"{k}={_compact(v)}" for k, v in (step.get("args") or {}).items() if not _unset(v))
        lines.append(f"  {step.get('command', '?')} {args}".rstrip() + f"  (neurotac {step.get('version', '?')})")
    return lines


def _sync_cell(entry: dict, method) -> str:
    """A trial's sync quality: the LED spike's z-score, or xcorr's correlation and uncertainty."""
    score = entry.get("score")
    text = f"sync {method}"
    if isinstance(score, (int, float)):
        text += f" r {score:.3g}" if method == "xcorr" else f" z {score:.0f}"
    if entry.get("uncertainty_us") is not None:
        text += f" ±{entry['uncertainty_us'] / 1000:.1f} ms"
    return text


def _unset(value) -> bool:
    """A history setting left at nothing (None, off, empty); 0 is a value (`0 == False` in Python)."""
    return value is None or value is False or (isinstance(value, (list, dict)) and not value)


def _compact(value) -> str:
    import json

    text = value if isinstance(value, str) else json.dumps(value, sort_keys=True, separators=(",", ":"))
    return text if len(text) <= 100 else text[:97] + "..."


def _us(value: int) -> str:
    return f"{value:,} µs"


def _duration(us) -> str:
    us = int(us)
    if abs(us) >= 1_000_000:
        return f"{us / 1e6:.3f} s"
    if abs(us) >= 1_000:
        return f"{us / 1e3:.3f} ms"
    return f"{us} µs"


def _rate(rate: float) -> str:
    if rate >= 1e6:
        return f"{rate / 1e6:.2f} M"
    if rate >= 1e3:
        return f"{rate / 1e3:.1f} k"
    return f"{rate:.1f}"


def describe_paths(paths, sensor=None, everything: bool = False) -> dict:
    """Describe tables (read as one, as every command does) or one camera file (decoded on the fly)."""
    from neurotac_cli import tables
    from neurotac_cli.errors import InputError, UsageError
    from neurotac_cli.io import camera, events

    paths = list(paths) or ["-"]
    if len(paths) == 1 and _exists(paths[0]) and _is_model(paths[0]):
        return describe_model(paths[0])
    # a pipe or a missing path goes to the table reader (peeking at a pipe would lose its first bytes),
    # and so does a file named as a table, whose reader says what it is not
    named = lambda path: tables.SUFFIXES.get(os.path.splitext(path)[1].lower()) in ("parquet", "file", "stream")  # noqa: E731
    is_tables = [not _exists(path) or camera.is_table(path) or named(path) for path in paths]
    if all(is_tables):
        if sensor is not None:
            raise UsageError("--sensor is for camera files that do not say their sensor size; a table carries its own")
        opened = tables.open_input(paths, allow_empty=True)
        return describe(opened.schema, opened.batches, everything=everything)
    if len(paths) > 1:
        raise InputError("describe one camera file at a time, or import them into one table first")
    text = describe_csv(paths[0])
    if text is not None:
        return text
    schema, batches = events.read_events(paths[0], sensor)
    fmt = sch.camera_source(schema).get("format")
    return describe(schema, batches, camera={"format": fmt, "format_name": camera.FORMAT_NAMES.get(fmt, fmt)})


def describe_csv(path: str) -> dict | None:
    """A CSV file that holds no events (no x, y and p columns): a force log, a manifest, a table
    written as text. None for anything else (a camera file, events as CSV)."""
    import csv

    from neurotac_cli.errors import NeurotacError
    from neurotac_cli.io import camera, force, text
    from neurotac_cli.io.force import read_table

    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
    first = camera.first_data_line(head.removeprefix(camera.BOM))
    try:  # semicolons: a spreadsheet's CSV where the comma is the decimal mark, as `sync` reads force logs; never events
        fmt = camera.detect_format(path, head)
    except NeurotacError:
        return None
    if fmt not in ("csv", "text") or (fmt == "text" and ";" not in first):  # a camera format's bytes may hold a `;`
        return None
    names, _ = text.column_names(next(csv.reader([first]), []))
    if text.names_events(names):
        return None
    table = read_table(path, "CSV file")
    info = {"kind": "csv", "file": path, "rows": table.num_rows,
            "columns": [f"{field.name}: {field.type}" for field in table.schema]}
    try:
        logs = force.read_force_log(path)
    except NeurotacError:
        return info
    samples = [log for log in logs if len(log.t)]
    if samples:
        values = np.concatenate([log.value for log in samples])
        info["force_log"] = {
            "trials": len(samples), "samples": int(sum(len(log.t) for log in samples)),
            "period_ms": float(np.median([log.period_us for log in samples])) / 1000,
            "span_s": float(max(log.t[-1] - log.t[0] for log in samples)) / 1e6,
            "force_n": [float(values.min()), float(values.max())],
            "first_us": int(min(log.t[0] for log in samples)),
        }
    return info


def _is_model(path: str) -> bool:
    """A safetensors file (8 bytes of header length, then its JSON header): what `neurotac train` writes.
    A `.model` file is taken for one whatever it holds, so a damaged one is named as a damaged model,
    not as an unknown camera format, unless it begins as a table does (Arrow or Parquet: described
    as the table it is)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(10)
    except OSError as error:  # unreadable (permissions): said as every verb says it of an input
        raise cannot_open(path, error) from None
    if head.startswith((b"\xff\xff\xff\xff", b"ARROW1", b"PAR1")):
        return False
    return (len(head) == 10 and head[8:10] == b'{"') or str(path).endswith(".model")


def describe_model(path: str) -> dict:
    """What a model file holds, from its header alone (no torch): the network, its input, its
    classes, how it was trained and on what."""
    from neurotac_cli.model.curve import best_epoch
    from neurotac_cli.model.store import read_header

    header = read_header(path)
    spec, training = header["input"], header.get("training") or {}
    curve = training.get("curve") or []
    best = best_epoch(curve)
    validated = best is not None and best.get("val_loss") == best.get("val_loss")  # NaN: trained without validation trials
    trials = training.get("trials") or {}
    info = {
        "kind": "model", "file": path, "model": header["model"], "task": header["task"],
        "format_version": header.get("format_version"), "architecture": header["architecture"],
        "input": {key: spec.get(key) for key in ("width", "height", "window_us", "accumulated", "sensor")},
        "classes": header.get("classes"), "label": training.get("label"),
        "adapt_by": (spec.get("adapt") or {}).get("by"),
        "training": {"trials": len(trials.get("train") or []), "validation_trials": len(trials.get("validation") or []),
                     "seed": training.get("seed"), "fit": training.get("fit"), "epochs_run": len(curve),
                     "best_epoch": best.get("epoch") if best else None,
                     "best_val_loss": best.get("val_loss") if validated else None,
                     "best_train_loss": None if validated or best is None else best.get("train_loss"),
                     "member_best_epochs": training.get("member_best_epochs"),
                     "member_draws": _distinct_draws(trials)},
        "contacts": training.get("contacts"), "slip": spec.get("slip"),
        "force_scale_n": (spec.get("normalisation") or {}).get("force_scale"),
        "history": training.get("data_history") or [],
    }
    return info


def _distinct_draws(trials: dict) -> int | None:
    """How many different validation draws a model's members had (None for a model of one network;
    0 when none had validation trials, whose early stopping followed the training loss)."""
    others = trials.get("member_validation")
    if not isinstance(others, list):
        return None
    draws = [trials.get("validation") or [], *others]
    return len({tuple(sorted(map(str, draw))) for draw in draws if isinstance(draw, list) and draw})


def _model_lines(info: dict) -> list:
    """A model's description as (name, value) pairs, then the commands that made its training frames."""
    spec, fit, trained = info["input"], info["training"].get("fit") or {}, info["training"]
    window = f"{spec['window_us'] / 1000:g} ms" if spec.get("window_us") else "an unknown window"
    pairs = [("file", f"{info['file']} (a neurotac model, format {info['format_version']})"), ("model", f"{info['model']} ({info['task']})"),
             ("input", f"{spec['width']}x{spec['height']} {'accumulated ' if spec.get('accumulated') else ''}frames of {window}")]
    if isinstance(spec.get("sensor"), dict) and (spec["sensor"].get("width"), spec["sensor"].get("height")) != (spec["width"], spec["height"]):
        pairs.append(("sensor", f"{spec['sensor']['width']}x{spec['sensor']['height']}"))
    if info["classes"]:
        pairs.append(("classes", f"{', '.join(info['classes'])} (label {info['label'] or 'material'})"))
    if info["adapt_by"]:
        pairs.append(("adapt by", f"{info['adapt_by']} (features standardised within each of its values)"))
    if info["force_scale_n"]:
        pairs.append(("force scale", f"{info['force_scale_n']:.4g} N (the training's largest force)"))
    pairs.append(("architecture", " ".join(f"{k}={_compact(v)}" for k, v in info["architecture"].items())))
    unit = "contacts" if isinstance(info.get("contacts"), dict) else "trials"  # `train --contacts` trains on contacts
    text = f"{trained['trials']} {unit}, {trained['validation_trials']} for validation, seed {trained['seed']}"
    if trained["epochs_run"]:
        text += f"; {trained['epochs_run']} epochs"
        if trained["best_epoch"] is not None:
            text += (f", best {trained['best_epoch']} (validation loss {trained['best_val_loss']:.4g})" if trained["best_val_loss"] is not None
                     else f", best {trained['best_epoch']} by its training loss {trained['best_train_loss']:.4g} (no validation {unit})")
    members = trained.get("member_best_epochs")
    if isinstance(members, list) and members:  # the curve above is the first member's
        draws = trained.get("member_draws")
        # too few trials to draw from give the members the same validation trials: said, not hidden
        how = ("" if draws == 0 else ", each validating on a draw of its own" if draws in (None, len(members))
               else f", validating on {draws} distinct draw(s)")
        text += f"; {len(members)} members{how}, best epochs {', '.join(map(str, members))}"
    pairs.append(("training", text))
    if fit:
        pairs.append(("fit", " ".join(f"{k}={_compact(v)}" for k, v in fit.items())))
    contacts = info.get("contacts")
    pressed, released, either = _polarities(contacts.get("press_polarity") if isinstance(contacts, dict) else None)
    if isinstance(contacts, dict):
        pairs.append(("contacts", f"{contacts.get('contacts')} in {contacts.get('sessions')} session(s); median press "
                                  f"{_compact(contacts.get('press_off'))}{pressed}, release {_compact(contacts.get('release_on'))}"
                                  f"{released} events{either}"))
    if isinstance(info.get("slip"), dict):
        bars = f"{info['slip'].get('min_events')}{pressed} / {info['slip'].get('min_events_on')}{released} events"
        pairs.append(("slip bars", bars + (" (press / release polarity)" if either else "")))
    return pairs + [""] + _steps_lines("trained on frames made by:", info["history"])


def _polarities(press_polarity) -> tuple:
    """How a contacts model's lines name the polarity a press makes and a release makes (" OFF", " ON";
    none where each contact is read in its own, press_polarity "either"), and what to add then."""
    from neurotac_cli.ops.contact import polarity_names

    if press_polarity == "either":
        return "", "", " (each contact read in the polarity its press makes, ON or OFF)"
    return (*(f" {name}" for name in polarity_names(press_polarity)), "")


def _exists(path) -> bool:
    import os

    return os.path.isfile(path)
