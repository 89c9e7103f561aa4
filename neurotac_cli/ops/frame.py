"""Bin events into two-channel count frames (thesis eq. 4.1), label them with force and phase.

Windows are half-open, `[k·T, (k+1)·T)` from each trial's sync instant t0 (recordings) or from the
first event (plain events tables, unless a start is given). A trial covers `[0, E)`: E is one force
period past the last force sample where the trial has a force trace (the force log defines the
experiment's length), else one microsecond past its last event. Window k is complete when
(k+1)·T <= E; the last, partial window is kept (default) or dropped. Empty windows are zero frames.
A plain events stream follows tonic's `ToFrame` instead: window k is complete when it ends at or
before the last event's time, so its frames equal tonic's (see docs/commands/frame.md for the two
edge cases where tonic differs from its own description).

Counts are uint16 (channel 0 = OFF, 1 = ON); a pixel that would pass 65535 stays there and the
events it could not hold are counted as saturated. `dtype="float32"` divides each channel by a
scale: by default the channel's largest count over the whole output (thesis 4.5.2), recorded in
the `neurotac:scale` metadata and in history so the same scale can be given to new data.

Everything not framed is counted in a `FramingReport`: events before the start, after the end
(or past --pad-to N), late events (a stream's events that arrive, less than one window out of time
order, after their frame has left), saturated events. Nothing unbounded is written: more than
`max_frames` frames are refused before they are written, with where they come from (in a stream,
more than that many opened at once: a clock jump; a live stream runs on for as long as it lasts).
"""

import dataclasses
import sys
import tempfile
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa
import pyarrow.ipc as ipc

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, NoEventsError, SchemaError, UsageError
from neurotac_cli.io import kernels
from neurotac_cli.units import counted, first_few
from neurotac_cli.ops import phases as ph

MAX_COUNT = int(np.iinfo(np.uint16).max)
SMALLEST_SCALE = MAX_COUNT / float(np.finfo(np.float32).max)  # below it the largest count divided by it is inf in float32
LARGEST_SCALE = float(np.finfo(np.float32).max)  # a scale is stored as float32: beyond it, it is inf and every count 0
FORCE_AT = ("end", "mean", "median")
BUFFER_CELLS = 1 << 22  # uint16 cells of one streaming buffer: 8 MiB, whatever the recording's length
SCAN_EVENTS = 1 << 18  # events counted at a time, so the frames of a huge input batch leave as it is counted
MAX_FRAMES = 1_000_000  # frames written unless the user raises the limit: 2.8 hours of 10 ms windows
SORT_EVENTS = 20_000_000  # events `sort` holds in memory (about 0.5 GB with the sort's index)
LEAD_IN_SHARE = 0.5  # a synced trial's LED blink and lead-in are a minority of its events; more means a wrong t0
GAP_WINDOWS = 1_000  # a stream's step in time of this many windows or more is reported, with where it is


# ---------------------------------------------------------------- counting


def count_frames(t, x, y, p, window_us: int, n_frames: int, height: int, width: int, start: int = 0) -> np.ndarray:
    """The (n_frames, 2, H, W) uint16 counts of events in windows [start + k·T, start + (k+1)·T)."""
    out = np.zeros((n_frames, 2, height, width), dtype=np.uint16)
    kernels.count_events(t, x, y, p, start, window_us, 0, out)
    return out


def n_windows(end_us: int, window_us: int, partial: str = "keep") -> int:
    """Windows of a trial covering [0, end_us): complete ones, plus the partial last one when kept."""
    if end_us <= 0:
        return 0
    full = end_us // window_us
    return full + (1 if partial == "keep" and end_us % window_us else 0)


# ---------------------------------------------------------------- options and report


@dataclass(frozen=True)
class Framing:
    """How to frame. Validated when built; never changed afterwards."""

    window_us: int
    partial: str = "keep"
    pad_to: int | str | None = None
    force_at: str = "end"
    zero: str = "log"  # the frames' force from the log's zero, or from its rest level where they are (`rest_zeroed`)
    phases: str | tuple = "auto"
    accumulate: bool = False
    dtype: str = "uint16"
    scale: tuple | None = None
    start_us: int | None = None
    trial: str = "events"
    max_frames: int = MAX_FRAMES
    sort: bool = False
    slips: dict | None = None  # {trial: [(start µs, end µs), ...]} on the synced clock: a bool `slip` column
    frame_options: bool = True  # the errors may offer `frame`'s --max-frames and --sort (`sense` has neither)

    def __post_init__(self):
        if not isinstance(self.window_us, (int, np.integer)) or self.window_us <= 0:
            raise UsageError(f"window must be a positive duration, got {self.window_us} µs")
        if self.partial not in ("keep", "drop"):
            raise UsageError(f"partial must be keep or drop, got {self.partial!r}")
        if self.pad_to is not None and self.pad_to != "longest" and (not isinstance(self.pad_to, int) or self.pad_to <= 0):
            raise UsageError(f"cannot pad to {self.pad_to!r} (give a number of frames, e.g. 41, or `longest`)")
        if self.force_at not in FORCE_AT:
            raise UsageError(f"force-at must be one of {', '.join(FORCE_AT)}, got {self.force_at!r}")
        if self.zero not in ("log", "rest"):
            raise UsageError(f"zero must be log or rest, got {self.zero!r}")
        if not isinstance(self.max_frames, (int, np.integer)) or self.max_frames <= 0:
            raise UsageError(f"max-frames must be a positive number of frames, got {self.max_frames!r}")
        if not isinstance(self.trial, str) or not self.trial.strip():
            raise UsageError(f"a trial id cannot be empty, got {self.trial!r} (give --trial a name, e.g. g1)")
        if self.dtype not in ("uint16", "float32"):
            raise UsageError(f"dtype must be uint16 or float32, got {self.dtype!r}")
        if self.scale is not None:
            if self.dtype != "float32":
                raise UsageError("a scale only applies to --dtype float32")
            if len(self.scale) != 2 or not all(np.isfinite(s) and s > 0 for s in self.scale):
                raise UsageError(f"scale must be one or two positive counts (OFF,ON), got {self.scale!r}")
            if min(self.scale) < SMALLEST_SCALE:
                raise UsageError(f"scale {min(self.scale):g} is below {SMALLEST_SCALE:.3g}: counts divided by it "
                                 "overflow float32 (give counts such as 40,55)")
            if max(self.scale) > LARGEST_SCALE:
                raise UsageError(f"scale {max(self.scale):g} is beyond float32 (at most {LARGEST_SCALE:.3g}); give counts such as 40,55")
        if not (self.phases in ("auto", "none", "session") or (isinstance(self.phases, tuple) and len(self.phases) == 3)):
            raise UsageError(f"phases must be auto, session, none or three frame ranges, got {self.phases!r}")
        for trial, spans in (self.slips or {}).items():
            if any(not end > start for start, end in spans):
                raise NeurotacError(f"trial {trial}: a true slip must end after it starts")

    def args(self) -> dict:
        """The settings as history records them."""
        return {
            "window_us": int(self.window_us),
            "partial": self.partial,
            "pad_to": self.pad_to,
            "force_at": self.force_at,
            "zero": self.zero,
            "phases": self.phases if isinstance(self.phases, str) else [list(r) for r in self.phases],
            "accumulate": self.accumulate,
            "dtype": self.dtype,
            "scale": list(self.scale) if self.scale else None,
            "start_us": self.start_us,
            "max_frames": int(self.max_frames),
            "sort": self.sort,
            "slips": None if self.slips is None else sum(len(spans) for spans in self.slips.values()),
        }


@dataclass
class FramingReport:
    """What was framed and what was not, filled as frames are made."""

    events: int = 0
    framed: int = 0
    before_start: int = 0
    after_end: int = 0
    late: int = 0
    saturated_events: int = 0
    saturated_pixels: int = 0
    trials: int = 0
    frames: int = 0
    padded_frames: int = 0
    scale: list | None = None
    notes: list = field(default_factory=list)

    @property
    def dropped(self) -> int:
        return self.before_start + self.after_end + self.late

    def as_dict(self) -> dict:
        out = {
            "events": self.events,
            "framed": self.framed,
            "dropped": {"before_start": self.before_start, "after_end": self.after_end, "late": self.late},
            "saturated": {"events": self.saturated_events, "pixels": self.saturated_pixels},
            "trials": self.trials,
            "frames": self.frames,
            "padded_frames": self.padded_frames,
        }
        if self.scale is not None:
            out["scale"] = self.scale
        return out

    def messages(self, lead_in_expected: bool = False) -> list[str]:
        """Lines for stderr once the frames are written: warnings (with `warning: `), then, for an events
        stream whose drops stayed under the warning's threshold, their count all the same."""
        warned = self.warnings(lead_in_expected=lead_in_expected)
        lines = [f"warning: {line}" for line in warned + self.notes]
        if self.dropped and not warned and not lead_in_expected:
            lines.append(f"{self.dropped} of {self.events} events lie outside the frames (before start {self.before_start}, "
                         f"after end {self.after_end}, out of time order {self.late})")
        return lines

    def warnings(self, threshold: float = 0.01, lead_in_expected: bool = False) -> list[str]:
        """Lines for stderr: drops above `threshold` of the events, and any saturation.

        `lead_in_expected`: events before t0 of synced trials are their LED blink and lead-in, not
        part of the trial by design: counted in history, not warned about."""
        lines = []
        if lead_in_expected and self.events and self.before_start > LEAD_IN_SHARE * self.events:
            lines.append(
                f"{self.before_start} of {self.events} events ({100 * self.before_start / self.events:.1f}%) come before their "
                "trial's sync instant t0 and are not framed: more than a lead-in; check the trials' t0 (neurotac sync)"
            )
        unexpected = self.after_end + self.late + (0 if lead_in_expected else self.before_start)
        if self.events and unexpected > threshold * self.events:
            lines.append(
                f"{self.dropped} of {self.events} events ({100 * self.dropped / self.events:.1f}%) lie outside the frames "
                f"(before start {self.before_start}, after end {self.after_end}, out of time order {self.late})"
            )
        if self.saturated_events:
            lines.append(
                f"{self.saturated_pixels} pixel counts reached {MAX_COUNT} (uint16) and {self.saturated_events} events "
                "could not be counted; use a shorter --window or crop --pool later"
            )
        return lines


# ---------------------------------------------------------------- recordings


def frame_recordings(table: pa.Table, window_us: int, report: FramingReport | None = None, **options) -> pa.Table:
    """Frame every trial of a `recordings` table (see the module doc); returns a `frames` table."""
    framing = Framing(window_us=window_us, **options)
    report = report if report is not None else FramingReport()
    schema, batches = frame_recordings_batches(table, framing, report)
    return pa.Table.from_batches(list(batches), schema=schema)


def _trial_rows(table: pa.Table):
    """Yield (trial, events (t, x, y, p), force (t, value), labels) per row, without Python loops over events."""
    labels = sch.label_columns(table.schema)
    for batch in table.to_batches():
        events = batch.column("events")
        force = batch.column("force")
        ev_offsets = events.offsets.to_numpy()
        ev_values = events.flatten()  # the values this (possibly sliced) list array spans
        fields = {name: ev_values.field(name).to_numpy(zero_copy_only=False) for name in ("t", "x", "y", "p")}
        f_offsets = force.offsets.to_numpy()
        f_values = force.flatten()
        f_t = f_values.field("t").to_numpy(zero_copy_only=False)
        f_v = f_values.field("value").to_numpy(zero_copy_only=False)
        trials = batch.column("trial").to_pylist()
        label_values = {name: batch.column(name).to_pylist() for name in labels}
        for row in range(batch.num_rows):
            a, b = ev_offsets[row] - ev_offsets[0], ev_offsets[row + 1] - ev_offsets[0]
            c, d = f_offsets[row] - f_offsets[0], f_offsets[row + 1] - f_offsets[0]
            yield (
                trials[row],
                tuple(fields[name][a:b] for name in ("t", "x", "y", "p")),
                (f_t[c:d], f_v[c:d]),
                {name: label_values[name][row] for name in labels},
            )


def trial_end(event_t: np.ndarray, force_t: np.ndarray) -> int:
    """The end E of a trial's span [0, E): one force period past the last force sample where there
    is a force trace, else one microsecond past the last event."""
    if len(force_t):
        period = int(np.median(np.diff(force_t))) if len(force_t) > 1 else 1
        return int(force_t[-1]) + max(period, 1)
    if len(event_t):
        return int(event_t.max()) + 1
    return 0


def frame_recordings_batches(table: pa.Table, framing: Framing, report: FramingReport):
    """(frames schema, iterator of record batches, one per trial) for a recordings table."""
    sensor = sch.sensor_of(table.schema)
    if sensor is None:
        raise SchemaError("recordings table has no neurotac:sensor metadata (give the sensor size with --sensor WxH)")
    width, height = sensor
    labels = sch.label_columns(table.schema)
    plan = _plan_trials(table, framing, report, sensor)
    counter = _TrialCounter(framing, report, sensor)
    scale = None
    if framing.dtype == "float32":
        scale = [float(s) for s in framing.scale] if framing.scale is not None else counter.peaks(plan)
        report.scale = scale
    dtype = np.float32 if framing.dtype == "float32" else np.uint16
    extra = (("grasp", pa.int32()),) if framing.phases == "session" else ()
    if framing.slips is not None:
        extra += (("slip", pa.bool_()),)
        unknown = sorted(set(framing.slips) - {trial for trial, *_ in plan})
        if unknown:
            report.notes.append(f"the true slips name {len(unknown)} trial(s) not among the recordings "
                                f"({first_few(unknown)}): their slips label no frame")
        spans = {trial: n_total * framing.window_us for trial, *_, n_total in plan}
        beyond = sum(1 for trial, end_us in spans.items() for start, end in framing.slips.get(trial, ())
                     if end <= 0 or start >= end_us)
        if beyond:
            report.notes.append(f"{counted(beyond, 'true slip')} {'lies' if beyond == 1 else 'lie'} outside {'its' if beyond == 1 else 'their'} "
                                "trial's frames and label no frame (are the slip times from the trial's sync instant, in ms?)")
    out_schema = sch.frames_schema(height, width, labels, dtype=dtype, window_us=framing.window_us,
                                   sensor=sch.sensor_meta(width, height), extra=extra)
    if scale is not None:
        out_schema = sch.set_meta(out_schema, scale=scale)
    out_schema = _keep_meta(table.schema, out_schema)

    doubts = _LabelDoubts(framing)

    def batches():
        for trial, events, force_t, force_v, label_values, n_real, n_total in plan:
            logged = frame_force(force_t, force_v, framing.window_us, n_total, framing.force_at)
            force, phase, grasp = _force_labels(framing, doubts, trial, logged, len(force_t) > 0, n_real, n_total)
            slip = None if framing.slips is None else slip_column(framing.slips.get(trial, ()), framing.window_us, n_total)
            doubts.look_at_labels(trial, grasp, n_total)
            for first, counts in counter.chunks(events, n_real, n_total):
                end = first + len(counts)
                yield _frames_batch(out_schema, trial, counts, force[first:end], None if phase is None else phase[first:end],
                                    label_values, labels, framing.window_us, scale, first_frame=first,
                                    grasp=None if grasp is None else grasp[first:end], slip=None if slip is None else slip[first:end])
        report.notes.extend(doubts.notes())

    return out_schema, batches()


def _force_labels(framing: Framing, doubts: "_LabelDoubts", trial: str, logged: np.ndarray, has_log: bool,
                  n_real: int, n_total: int):
    """(force, phase, grasp) of a trial's frames from their force as logged (`frame_force`'s; `has_log`:
    whether the trial has a force log): zeroed at rest with `--zero rest`, labelled by `framing.phases`,
    what is doubtful told to `doubts`. Each labelling of the session's grasps is made once: those of
    the force the frames get, and the log's own where its zero is read from them."""
    block = ph.rest_block(framing.window_us)
    line = ph.rest_line(logged[:n_real], block) if has_log and framing.zero == "rest" else None
    force = rest_zeroed(logged, n_real, line, trial) if line is not None else logged
    grasp, slow = None, []
    if framing.phases == "session":
        spikes = []
        phase, grasp = ph.session_columns(force, n_real, n_total, framing.window_us, spikes, slow)
        doubts.look_at_spikes(trial, spikes, slow)
        if has_log and framing.zero != "rest":
            line = ph.rest_line(logged[:n_real], block, grasp[:n_real], slow[0][0] if slow else None)
    else:
        phase = _phases(force, n_real, n_total, framing.phases)
    doubts.look(trial, logged if has_log else None, n_real, line, slow[0][0] if slow else None)
    if line is not None and framing.zero == "rest":
        zeroed = grasp[:n_real] if grasp is not None else ph.label_session(force[:n_real], block=block)[1]
        doubts.look_at_zero(trial, held_level(logged, n_real, line, zeroed))
    elif line is not None and grasp is not None:  # the log's own zero: a session at rest far from it is one long hold
        doubts.look_at_zero(trial, held_level(logged, n_real, line, grasp[:n_real]))
    return force, phase, grasp


UNFORCED_LEAST, UNFORCED_SHARE = 5, 0.01  # frames without force named where more than both (a log's first sample a few ms late is not)


class _LabelDoubts:
    """Labels that are likely not what the user meant, gathered over the trials for one warning each:
    frames before a force log's first sample, a session framed as one grasp (`--phases auto`), true
    slips at rest outside every grasp, a log whose zero drifts or whose noise is slower than its
    samples, and what `--zero rest` could not do."""

    def __init__(self, framing: Framing):
        self.framing = framing
        self.several, self.resting, self.unforced, self.drifting, self.held, self.logless = [], 0, {}, {}, {}, []
        self.spikes, self.slow = {}, {}

    def look(self, trial: str, force, n_real: int, line=None, noise: float | None = None) -> None:
        """The trial's frames' force as the log gives it (`force`; None where it has no force log), its
        zero (`rest_line`) where framing reads it, and its noise σ where that is slower than its
        samples (`label_session`)."""
        unforced = 0 if force is None else int(np.isnan(force[:n_real]).sum())
        if unforced > max(UNFORCED_LEAST, UNFORCED_SHARE * n_real):  # a log that starts after the camera
            self.unforced[trial] = unforced
        if self.framing.phases == "auto" and force is not None and int(ph.session_columns(force, n_real, n_real, self.framing.window_us)[1].max()) >= 1:
            self.several.append(trial)
        if line is not None:
            moved = ph.rest_drift(force[:n_real], line, block=ph.rest_block(self.framing.window_us), noise=noise)
            if moved is not None:
                self.drifting[trial] = moved
        if self.framing.zero == "rest" and force is None:
            self.logless.append(trial)

    def look_at_zero(self, trial: str, held: float | None) -> None:
        """`held`: the rest level of a session in which no grasp was found, where that lies far from the
        log's zero (`held_level`; with `--zero rest`, the level taken off): a trial held from start to
        end reads as rest."""
        if held is not None:
            self.held[trial] = held

    def look_at_spikes(self, trial: str, spikes: list, slow: list) -> None:
        """`spikes`: the trial's runs of contact too short for a grasp; `slow`: its log's noise where
        that is slower than its samples (`label_session`)."""
        if spikes:
            self.spikes[trial] = spikes
        if slow:
            self.slow[trial] = slow[0]

    def look_at_labels(self, trial: str, grasp, n_total: int) -> None:
        if self.framing.slips is not None and grasp is not None:
            for span in self.framing.slips.get(trial, ()):
                inside = slip_column([span], self.framing.window_us, n_total)
                self.resting += bool(inside.any() and (grasp[inside] < 0).all())

    def notes(self) -> list[str]:
        notes = []
        if self.unforced:
            trial, count = max(self.unforced.items(), key=lambda item: item[1])
            notes.append(f"{counted(sum(self.unforced.values()), 'frame')} of {counted(len(self.unforced), 'trial')} come before "
                         f"the force log's first sample ({trial}: {count}) and have no force (NaN): training and scoring leave "
                         "them out; does the log start after the camera?")
        if self.resting:
            notes.append(f"{counted(self.resting, 'true slip')} {'lies' if self.resting == 1 else 'lie'} at rest, outside every "
                         "grasp the force shows: a slips file of another session, or slip times not from the sync instant?")
        if self.drifting:
            trial, moved = max(self.drifting.items(), key=lambda item: abs(item[1]))
            found = "grasps are found above the rest level where it is, and " if self.framing.phases == "session" else ""
            kept = ("the frames' force is taken from that level (--zero rest)" if self.framing.zero == "rest"
                    else "the frames' force keeps the drift (--zero rest takes it out)")
            notes.append(f"the force log's rest level moves over {counted(len(self.drifting), 'session')} ({trial}: by {moved:+.3g}, "
                         f"from its start to its end): a force sensor whose zero drifts or was re-tared; {found}{kept}")
        if self.held and self.framing.zero == "rest":
            trial, level = max(self.held.items(), key=lambda item: abs(item[1]))
            notes.append(f"--zero rest found no grasp in {counted(len(self.held), 'trial')} whose rest level lies far from the log's "
                         f"zero ({trial}: {level:+.3g}): a trial held from start to end reads as rest there, its force taken off; "
                         "frame such trials without --zero rest")
        elif self.held:
            trial, level = max(self.held.items(), key=lambda item: abs(item[1]))
            notes.append(f"--phases session found no grasp in {counted(len(self.held), 'trial')} whose force rests far from the "
                         f"log's zero ({trial}: {level:+.3g}), labelled at rest: a trial held from start to end, or a log whose zero "
                         "is off; frame a held trial with --phases auto (one grasp), an offset log with --zero rest")
        if self.spikes:
            trial, spikes = max(self.spikes.items(), key=lambda item: len(item[1]))
            first, frames, peak = max(spikes, key=lambda spike: spike[2])
            notes.append(f"the force log rises into contact for under {ph.MIN_GRASP_US / 1000:g} ms "
                         f"{counted(sum(map(len, self.spikes.values())), 'time')} in {counted(len(self.spikes), 'session')} "
                         f"({trial}: {len(spikes)}, the highest {peak:.3g} above rest at frame {first}): a force sensor's "
                         "glitches, or its noise where a slow press crosses the contact level, not grasps; those frames "
                         "are labelled at rest")
        if self.slow:
            trial, (sigma, steps) = max(self.slow.items(), key=lambda item: item[1][0])
            notes.append(f"the force log's noise is slower than its samples in {counted(len(self.slow), 'session')} ({trial}: "
                         f"σ {sigma:.3g} over lags of up to {ph.SLOW_NOISE_US / 1000:g} ms, its steps' {steps:.3g}): a filtered "
                         f"load cell; grasps are found above at least 5 of that σ and peaking 10 above rest ({10 * sigma:.3g} there), "
                         "weaker ones are labelled at rest")
        if self.logless:
            notes.append(f"--zero rest: {counted(len(self.logless), 'trial')} ({first_few(self.logless)}) {'has' if len(self.logless) == 1 else 'have'} "
                         "no force log, so no force to zero")
        if self.several:
            notes.append(f"the force comes back to rest between grasps in {counted(len(self.several), 'trial')} "
                         f"({first_few(self.several)}), labelled as one grasp "
                         "each (--phases auto); a session of many grasps needs --phases session")
        return notes


def _plan_trials(table: pa.Table, framing: Framing, report: FramingReport, sensor) -> list:
    """Per trial (trial, events, force t, force values, labels, real frames, frames with padding),
    its events checked and counted in the report; more frames than framing.max_frames refused."""
    window = framing.window_us
    rows = list(_trial_rows(table))
    ends = [trial_end(events[0], force[0]) for _, events, force, _ in rows]
    lengths = [n_windows(end, window, framing.partial) for end in ends]
    target = max(lengths, default=0) if framing.pad_to == "longest" else framing.pad_to
    totals = [n if target is None else target for n in lengths]
    if sum(totals):
        longest = int(np.argmax(totals))
        trial, (t, *_), (force_t, _), _ = rows[longest]
        # the trial's end is its force log's when it has one (see trial_end), else its last event's
        times, what = (force_t, "force sample") if len(force_t) else (np.sort(t), "event")
        check_frame_count(sum(totals), framing, lambda: f"trial {trial}: " + why_so_many(np.concatenate([[0], times]), 0, window, -1, what))
    _trial_notes(rows, totals, framing, report)
    plan = []
    for (trial, events, (force_t, force_v), label_values), n_real, n_total in zip(rows, lengths, totals):
        t, x, y, p = events
        sch.check_events(t, x, y, p, sensor, where=f"trial {trial}", sorted_time=False)
        sch.check_force(force_v, where=f"trial {trial}")
        backwards = int(np.count_nonzero(np.diff(force_t) < 0))
        if backwards:
            raise SchemaError(f"trial {trial}: force time runs backwards at {counted(backwards, 'sample')} of {len(force_t):,}; "
                              "a recording's force samples are in time order (as `neurotac sync` writes them)")
        n_real = min(n_real, n_total)
        before = int(np.count_nonzero(t < 0))
        after = int(np.count_nonzero(t >= n_real * window))
        report.events += len(t)
        report.before_start += before
        report.after_end += after
        report.framed += len(t) - before - after
        report.trials += 1
        report.frames += n_total
        report.padded_frames += n_total - n_real
        plan.append((trial, events, force_t, force_v, label_values, n_real, n_total))
    return plan


def _trial_notes(rows: list, totals: list, framing: Framing, report: FramingReport) -> None:
    """What the trials' force logs and the options leave doubtful, as notes: holes in a log, a log
    slower than the window for session phases, phase ranges past a trial's end, empty trials."""
    window = framing.window_us
    periods = [float(np.median(np.diff(force_t))) for _, _, (force_t, _), _ in rows if len(force_t) > 1]
    gaps = [(trial, *_force_gap(force_t)) for trial, _, (force_t, _), _ in rows if len(force_t) > 2]
    gaps = [gap for gap in gaps if gap[1] is not None]
    if gaps:
        trial, start, length = max(gaps, key=lambda gap: gap[2])
        report.notes.append(f"the force log of {counted(len(gaps), 'trial')} has no sample for a stretch many times its "
                            f"sampling period ({trial}: {length / 1e6:.3g} s from {start / 1e6:.3g} s): frames there hold "
                            "the last sample before it (a logger that dropped samples?)")
    if framing.phases == "session" and periods and max(periods) > window:
        report.notes.append(f"the force log is sampled every {max(periods) / 1000:g} ms, more slowly than the "
                            f"{window / 1000:g} ms window: frames repeat its samples, and phases read from it split grasps "
                            f"where it seems not to change; frame with a window of at least {max(periods) / 1000:g} ms for phases")
    if isinstance(framing.phases, tuple):
        short = [(trial, n) for (trial, *_), n in zip(rows, totals) if framing.phases[-1][0] >= n]
        if short:
            (trial, n), last = short[0], framing.phases[-1]
            report.notes.append(f"the phase ranges reach past the last frame of {counted(len(short), 'trial')} ({trial}: frames "
                                f"0-{n - 1}, releasing from {last[0]}): their later phases label no frame")
    empty = [trial for (trial, events, (force_t, _), _), n_total in zip(rows, totals)
             if not n_total and not len(events[0]) and not len(force_t)]
    if empty:
        report.notes.append(f"{counted(len(empty), 'trial')} ({first_few(empty)}) "
                            f"{'holds' if len(empty) == 1 else 'hold'} no event and no force sample: {'it makes' if len(empty) == 1 else 'they make'} no frame")


class _TrialCounter:
    """The count frames of one trial of a recording, in pieces of at most BUFFER_CELLS counts (memory
    stays flat however long the trial), accumulated when asked."""

    def __init__(self, framing: Framing, report: FramingReport, sensor):
        self.framing, self.report = framing, report
        self.width, self.height = sensor
        self.chunk = int(max(1, BUFFER_CELLS // (2 * self.height * self.width)))

    def chunks(self, events, n_real: int, n_total: int, count: bool = True):
        """(first frame, counts) pieces of the trial's n_total frames, of which the first n_real hold events."""
        t, x, y, p = events
        if len(t) > 1 and np.any(t[1:] < t[:-1]):  # a trial's events out of order are sorted once
            order = np.argsort(t, kind="stable")
            t, x, y, p = t[order], x[order], y[order], p[order]
        window = self.framing.window_us
        running = np.zeros((2, self.height, self.width), dtype=np.int64) if self.framing.accumulate else None
        over = 0
        for first in range(0, n_total, self.chunk):
            counts = np.zeros((min(self.chunk, n_total - first), 2, self.height, self.width), dtype=np.uint16)
            real = max(0, min(len(counts), n_real - first))
            lo, hi = np.searchsorted(t, [first * window, (first + real) * window])
            _, saturated, *_ = kernels.count_events(t[lo:hi], x[lo:hi], y[lo:hi], p[lo:hi], 0, window, first, counts[:real])
            if running is not None:  # padding frames add no events: they hold the trial's last accumulated counts
                total = running[None] + np.cumsum(counts, axis=0, dtype=np.int64)
                running = total[-1]
                over += int(np.count_nonzero(total[:real] > MAX_COUNT))
                counts[:] = np.minimum(total, MAX_COUNT)
            if count:
                self.report.saturated_events += saturated
                self.report.framed -= saturated
                self.report.saturated_pixels += int(np.count_nonzero(counts[:real] == MAX_COUNT))
            yield first, counts
        if over and count:
            self.report.notes.append(f"accumulated counts passed {MAX_COUNT} in {over} pixel-frames")

    def peaks(self, plan) -> list[float]:
        """Each channel's largest count over every trial (a first pass; frames are made again after)."""
        peaks = np.zeros(2, dtype=np.int64)
        for _, events, _, _, _, n_real, _ in plan:
            for _, counts in self.chunks(events, n_real, n_real, count=False):
                peaks = np.maximum(peaks, counts.max(axis=(0, 2, 3)))
        return [float(max(peak, 1)) for peak in peaks]


GAP_PERIODS, GAP_LEAST_US = 20, 100_000  # a force log's hole longer than both is named


def _force_gap(force_t: np.ndarray) -> tuple:
    """(start µs, length µs) of a force log's longest stretch without a sample, where it is longer than
    GAP_PERIODS sampling periods and GAP_LEAST_US; (None, 0) otherwise."""
    steps = np.diff(np.asarray(force_t, dtype=np.int64))
    longest = int(np.argmax(steps))
    if steps[longest] > max(GAP_PERIODS * float(np.median(steps)), GAP_LEAST_US):
        return int(force_t[longest]), int(steps[longest])
    return None, 0


def rest_zeroed(force: np.ndarray, n_real: int, line: np.ndarray, trial: str = "") -> np.ndarray:
    """`frame --zero rest`: the frames' force less the log's zero where each frame is (`line`, the
    `rest_line` of its first `n_real`). So a force sensor whose zero drifts (a strain gauge warming)
    gives a force of zero between grasps and a grasp's force above it. Padding frames (after
    `n_real`) lose the last frame's level; missing samples stay missing."""
    out = force.astype(np.float64)
    out[:n_real] -= line
    out[n_real:] -= line[-1]
    if np.nanmax(np.abs(out)) > np.finfo(np.float32).max:
        real = force[:n_real]
        raise SchemaError(f"trial {trial}: its force less its rest level passes float32's range (the log reads "
                          f"{np.nanmin(real):.3g} to {np.nanmax(real):.3g}): a corrupt log; clean it, or frame without --zero rest")
    return out.astype(force.dtype)


def held_level(force: np.ndarray, n_real: int, line: np.ndarray, grasp: np.ndarray) -> float | None:
    """The level `rest_zeroed` took off a trial whose zeroed force holds no grasp (`grasp`, its labels
    of the first `n_real` frames, all -1), where that lies over 10 noise σ of the log (`force`) from
    its zero; else None. A trial held from start to end reads as rest, its force taken off."""
    known = force[:n_real][~np.isnan(force[:n_real])].astype(np.float64)
    noise = ph.step_noise(np.diff(known)) if len(known) > 2 else 0.0
    level = float(np.median(line))
    return level if abs(level) > max(10 * noise, 1e-6) and grasp.max(initial=-1) < 0 else None


def frame_force(force_t: np.ndarray, force_v: np.ndarray, window_us: int, n_frames: int, how: str = "end") -> np.ndarray:
    """Force per frame (float32, NaN where the trace says nothing).

    end: the latest sample at or before the window's end (k+1)·T, as a logger read on the frame
    clock shows it (thesis 5.4.1: the 2 ms force read every 10 ms); past the trace's end it holds
    the last sample. mean / median: of the samples inside [k·T, (k+1)·T), the `end` value where a
    window holds none.
    """
    out = np.full(n_frames, np.nan, dtype=np.float32)
    if not len(force_t) or not n_frames:
        return out
    force_t = np.asarray(force_t, dtype=np.int64)
    force_v = np.asarray(force_v, dtype=np.float64)
    ends = (np.arange(n_frames, dtype=np.int64) + 1) * window_us
    index = np.searchsorted(force_t, ends, side="right") - 1
    known = index >= 0
    out[known] = force_v[index[known]]
    if how == "end":
        return out
    starts = ends - window_us
    lo = np.searchsorted(force_t, starts, side="left")
    hi = np.searchsorted(force_t, ends, side="left")
    if how == "mean":
        sums = np.concatenate([[0.0], np.cumsum(force_v)])
        filled = hi > lo
        out[filled] = ((sums[hi] - sums[lo])[filled] / (hi - lo)[filled]).astype(np.float32)
        return out
    for k in np.flatnonzero(hi > lo):  # one median per frame: frames, not events
        out[k] = np.median(force_v[lo[k]:hi[k]])
    return out


def _phases(force: np.ndarray, n_real: int, n_total: int, how):
    if how == "none":
        return None
    if isinstance(how, tuple):
        return ph.phases_from_ranges(n_total, list(how))
    if np.isnan(force).all():
        return None
    labels = np.full(n_total, ph.NONE, dtype=object)
    labels[:n_real] = ph.detect_phases(force[:n_real])
    return labels


def _keep_meta(source: pa.Schema, target: pa.Schema) -> pa.Schema:
    """Carry the input's history (and other foreign keys) over to the output schema."""
    metadata = dict(target.metadata or {})
    for key, value in (source.metadata or {}).items():
        if key not in metadata and key not in (sch.KIND.encode(), sch.SYNC.encode(), b"neurotac:triggers"):
            metadata[key] = value
    return target.with_metadata(metadata)


def slip_column(spans, window_us: int, n_frames: int) -> np.ndarray:
    """True where a frame's window ends inside a true slip (start, end]: the frame that first
    holds the slip's events is its first slipping frame."""
    ends = (np.arange(n_frames, dtype=np.int64) + 1) * window_us
    slip = np.zeros(n_frames, dtype=bool)
    for start, end in spans:
        slip |= (ends > start) & (ends <= end)
    return slip


def _frames_batch(schema, trial, counts, force, phase, label_values, labels, window_us, scale, first_frame=0, grasp=None,
                  slip=None) -> pa.RecordBatch:
    n = len(counts)
    if scale is not None:
        counts = counts.astype(np.float32) / np.asarray(scale, dtype=np.float32)[None, :, None, None]
    columns = [
        pa.array([trial] * n, pa.string()),
        pa.array(np.arange(first_frame, first_frame + n, dtype=np.int32)),
        pa.array((np.arange(first_frame, first_frame + n, dtype=np.int64)) * window_us),
        sch.counts_array(counts),
        pa.array(force, pa.float32(), from_pandas=True) if force is not None else pa.nulls(n, pa.float32()),
        pa.array(list(phase), pa.string()) if phase is not None else pa.nulls(n, pa.string()),
    ]
    if grasp is not None:
        columns.append(pa.array(grasp, pa.int32()))
    if slip is not None:
        columns.append(pa.array(slip, pa.bool_()))
    columns += [pa.array([label_values.get(name)] * n, pa.string()) for name in labels]
    names = schema.names
    for extra in names[len(columns):]:
        columns.append(pa.nulls(n, schema.field(extra).type))
    return pa.RecordBatch.from_arrays(columns, schema=schema)


# ---------------------------------------------------------------- plain events, streamed


def frame_events(schema: pa.Schema, batches, framing: Framing, report: FramingReport, sensor=None):
    """Frame a plain `events` stream as one unlabelled trial, batch by batch.

    Window k leaves as soon as it has closed: once an event at or after its end has arrived (or the
    input has ended), after the input batch that brought that event. Memory stays flat: frames are
    counted into a buffer of at most BUFFER_CELLS counts and leave it as views, without a copy.
    Events more than one window behind an earlier event, or before the first event, are refused
    (or sorted first, with `framing.sort`); events less late than that whose frame has already left
    are counted as late. Float32 output without a given scale spills the counts to a temporary file
    until the channels' maxima are known. Returns (frames schema, iterator of batches); the report
    is complete once the iterator is exhausted.
    """
    schema = sch.with_given_sensor(schema, sensor)
    sensor = sch.sensor_of(schema)
    if sensor is None:
        raise SchemaError("events table has no neurotac:sensor metadata (give the sensor size with --sensor WxH)")
    width, height = sensor
    dtype = np.float32 if framing.dtype == "float32" else np.uint16
    out_schema = sch.frames_schema(height, width, (), dtype=dtype, window_us=framing.window_us, sensor=sch.sensor_meta(width, height))
    if framing.scale is not None:
        out_schema = sch.set_meta(out_schema, scale=[float(s) for s in framing.scale])
    out_schema = _keep_meta(schema, out_schema)
    batches = _slices(_sorted(batches) if framing.sort else batches, SCAN_EVENTS)
    if framing.dtype == "float32" and framing.scale is None:
        return _scaled_from_spill(out_schema, batches, framing, report, sensor)
    return out_schema, _StreamFramer(out_schema, framing, report, sensor).frames(batches)


class _StreamFramer:
    """The frames of one events stream. Buffer frame i is window `base + i`; buffer frames
    [0, zeroed) hold counts, later ones garbage until an event reaches them (the kernel zeroes a
    frame just before its first count, while it is in the cache); windows [0, emitted) have left."""

    def __init__(self, out_schema: pa.Schema, framing: Framing, report: FramingReport, sensor):
        self.schema, self.framing, self.report = out_schema, framing, report
        self.width, self.height = sensor
        self.window = framing.window_us
        self.capacity = int(min(256, max(2, BUFFER_CELLS // (2 * self.height * self.width))))
        self.buffer = np.empty((self.capacity, 2, self.height, self.width), dtype=np.uint16)
        self.free_refs = sys.getrefcount(self.buffer)  # a buffer's count of references while only this framer holds it
        self.spare = None  # the buffer before this one, reused once no frame of it is held downstream
        self.zero_frames = None  # one block of zero frames, shared by every run of empty windows
        self.start = framing.start_us  # camera time of window 0: --start, else the first event's
        self.floor = None  # events before it are out of time order: the first event, when it sets the start
        self.latest = self.previous = None  # the largest event time so far, and before the current batch
        self.order = None  # [latest, slack, floor, gap, gap_at, gap_from] as the kernel reads and updates them
        self.gap = None  # (µs, event index, time before it) of the longest step in time of GAP_WINDOWS windows or more
        self.base = self.zeroed = self.emitted = 0
        self.cap = framing.pad_to if isinstance(framing.pad_to, int) else None
        self.running = np.zeros((2, self.height, self.width), dtype=np.int64) if framing.accumulate else None
        self.scale = [float(s) for s in framing.scale] if framing.scale is not None else None

    def frames(self, batches):
        """Frames batches, each as soon as the input batch that closed its windows has been counted."""
        batches = iter(batches)
        for batch in batches:
            if not batch.num_rows:
                continue
            t, x, y, p = (batch.column(name).to_numpy(zero_copy_only=False) for name in ("t", "x", "y", "p"))
            t = t.astype(np.int64, copy=False)
            sch.check_events(t, x, y, p, (self.width, self.height), sorted_time=False)
            if self.order is None:  # the first batch
                if self.start is None:
                    self.start = self.floor = int(t[0])
                floor = -(1 << 63) if self.floor is None else self.floor
                self.order = np.array([t[0], self.window, floor, GAP_WINDOWS * self.window - 1, -1, 0], dtype=np.int64)
            self.previous = int(self.order[0])
            self.report.events += len(t)
            yield from self._count(t, x, y, p, batches)
            yield from self._emit(self._closed())
        if self.latest is None:
            raise NoEventsError("input events table is empty: nothing to frame")
        yield from self._finish()

    def _count(self, t, x, y, p, rest):
        """Count a batch into the buffer, checking its time order (in the same pass, but with
        --pad-to N) and the frame limit; while events lie past the buffer's end, the windows before
        them leave and a fresh buffer starts at the first of them."""
        order = self.order
        if self.cap is not None:  # windows past --pad-to N are cut here, and counted
            back, first, order[0] = kernels.time_order(t, order[0], self.window, self.floor)
            self._refuse_disorder(back, first, t, rest)
            self.latest = int(order[0])
            past = (t - self.start) // self.window >= self.cap
            if past.any():
                self.report.after_end += int(past.sum())
                t, x, y, p = t[~past], x[~past], y[~past], p[~past]
            order = None
        while len(t):
            offset = self.emitted - self.base
            inside, saturated, before, late, beyond, _, zeroed, back, first = kernels.count_events(
                t, x, y, p, self.start, self.window, self.emitted, self.buffer[offset:], max(0, self.zeroed - offset), order
            )
            self.zeroed = max(self.zeroed, offset + zeroed)
            self.report.framed += inside - saturated
            self.report.saturated_events += saturated
            self.report.before_start += before
            self.report.late += late
            self.latest = int(self.order[0])
            if order is not None:
                self._refuse_disorder(back, first, t, rest)
                if order[4] >= 0:  # the longest run of empty windows so far, and where it is
                    self.gap = (int(order[3]), self.report.events - len(t) + int(order[4]), int(order[5]))
                    order[4] = -1
                if self.latest >= self.start:
                    # the frames this batch opens at once, not all so far: a live sensor runs for hours
                    # (a million 10 ms windows are 2.8 of them), a clock jump opens millions in one step
                    frames = (self.latest - self.start) // self.window + 1 - self.emitted
                    check_frame_count(frames, self.framing, lambda: self._why(t), streaming=True)
                order = None  # once per batch
            if not beyond:
                return
            windows = (t - self.start) // self.window
            rest_of_batch = windows >= self.base + self.capacity
            t, x, y, p = t[rest_of_batch], x[rest_of_batch], y[rest_of_batch], p[rest_of_batch]
            next_base = int(windows[rest_of_batch].min())
            yield from self._emit(next_base)
            self.buffer = self._next_buffer()
            self.base, self.zeroed = next_base, 0

    def _next_buffer(self) -> np.ndarray:
        """A buffer for the next windows. The frames that left are views of the current one, so it is
        kept aside; the one before it is reused if nothing downstream holds a view of it any more.
        Why not a fresh array each time: the first touch of a new 8 MiB array's pages (huge pages,
        which numpy asks for at that size) costs about 5 ms on one frame in twelve of a live stream."""
        spare = self.spare if self.spare is not None and sys.getrefcount(self.spare) <= self.free_refs else None
        self.spare = self.buffer
        return spare if spare is not None else np.empty_like(self.buffer)

    def _refuse_disorder(self, back: int, first: int, t: np.ndarray, rest):
        """Refuse events more than one window back in time, counting them over the rest of the input."""
        if not back:
            return
        ahead = int(max(self.previous, t[:first].max(initial=self.previous)))
        latest = int(self.order[0])
        for batch in rest:
            if batch.num_rows:
                more, _, latest = kernels.time_order(batch.column("t").to_numpy(zero_copy_only=False), latest, self.window, self.floor)
                back += more
        raise NeurotacError(
            f"{back:,} event{'s' if back > 1 else ''} more than one window out of time order (the first: event "
            f"{self.report.events - len(t) + first:,} at t = {int(t[first])} µs, after an event at {ahead} µs; "
            + ("sort them with --sort, or fix the recording)" if self.framing.frame_options else
               "fix the recording, or sort it: `neurotac import` it, then `neurotac frame --sort`)")
        )

    def _closed(self) -> int:
        """Windows before the latest event's window have closed."""
        closed = max(0, (self.latest - self.start) // self.window)
        return closed if self.cap is None else min(closed, self.cap)

    def _emit(self, end: int):
        """Batches of the windows [emitted, end): buffer frames, then zero frames past the buffer."""
        stop = min(end, self.base + self.capacity)
        if stop > self.emitted:
            a, b = self.emitted - self.base, stop - self.base
            if b > self.zeroed:
                self.buffer[self.zeroed:b] = 0  # windows no event reached
                self.zeroed = b
            yield self._batch(self.buffer[a:b])
        while end > self.emitted:
            if self.zero_frames is None:
                self.zero_frames = np.zeros_like(self.buffer)
            yield self._batch(self.zero_frames[: min(end - self.emitted, self.capacity)])

    def _batch(self, frames: np.ndarray) -> pa.RecordBatch:
        """Frames leave here, in order, numbered from `emitted`; never written again."""
        if self.running is not None:
            total = self.running[None] + np.cumsum(frames, axis=0, dtype=np.int64)
            self.running = total[-1].copy()
            frames = np.minimum(total, MAX_COUNT).astype(np.uint16)
        if self.report.saturated_events or self.running is not None:
            self.report.saturated_pixels += int(np.count_nonzero(frames == MAX_COUNT))
        first = self.emitted
        self.emitted += len(frames)
        self.report.frames += len(frames)
        phases = self.framing.phases
        phase = ph.phases_from_ranges(self.emitted, list(phases), start=first) if isinstance(phases, tuple) else None
        return _frames_batch(self.schema, self.framing.trial, frames, None, phase, {}, (), self.window, self.scale, first_frame=first)

    def _finish(self):
        """tonic's convention for a stream: window k is complete when it ends at or before the last
        event's time; the partial window kept is the one holding the last event."""
        span = self.latest - self.start
        n_real = 0 if span < 0 else span // self.window + (1 if self.framing.partial == "keep" else 0)
        n_total = n_real if self.cap is None else self.cap
        n_real = min(n_real, n_total)
        self.report.padded_frames = max(0, n_total - n_real)
        self.report.trials = 1
        keep = min(max(n_real, self.emitted), self.base + self.capacity) - self.base
        lost = int(self.buffer[keep:max(self.zeroed, keep)].sum(dtype=np.int64))  # the partial window, when dropped
        self.report.framed -= lost
        self.report.after_end += lost
        self.zeroed = min(self.zeroed, keep)
        if self.gap:
            length, at, since = self.gap
            self.report.notes.append(
                f"a gap of {_duration(length)} at event {at:,} (from t = {since} to {since + length} µs): "
                f"{length // self.window:,} empty frames in the middle of the stream"
            )
        yield from self._emit(n_total)

    def _why(self, t: np.ndarray) -> str:
        return why_so_many(np.concatenate([[self.previous], t]), self.start, self.window, self.report.events - len(t) - 1,
                           limit=self.framing.frame_options)


LARGE_OUTPUT_BYTES = 8 << 30  # frames beyond this are worth a word before they fill a disk


def size_note(schema: pa.Schema, frames: int) -> str | None:
    """A warning when `frames` frames of `schema` make a very large output (a recordings table's
    frames are counted before any is written)."""
    height, width = sch.frames_shape(schema)
    size = frames * 2 * height * width * schema.field("counts").type.value_type.byte_width
    if size <= LARGE_OUTPUT_BYTES:
        return None
    return (f"{frames:,} frames of 2x{height}x{width} counts make {size / 1e9:.3g} GB; pool the events first "
            "(`neurotac crop --pool`), crop them, or frame with a longer --window")


def check_frame_count(frames: int, framing: Framing, why, streaming: bool = False) -> None:
    """Refuse to write more than framing.max_frames frames; `why()` says where they come from. A
    stream's count is of the events so far: `streaming` says so."""
    if frames > framing.max_frames:
        at_least = "at least " if streaming else ""
        limit = f"--max-frames {framing.max_frames:,}" if framing.frame_options else f"the {framing.max_frames:,} a stream may open at once"
        raise NeurotacError(f"{at_least}{frames:,} frames to write, more than {limit} ({why()})")


def why_so_many(times: np.ndarray, start: int, window_us: int, first_index: int, what: str = "event", limit: bool = True) -> str:
    """The reason for a frame count: the largest gap in `times` (times of `what`, numbered from
    `first_index`) when it holds most of the span from `start`, else a window too small for it.
    `limit`: the advice may offer raising --max-frames."""
    raise_it = ", or raise --max-frames" if limit else ""
    reach = np.maximum.accumulate(np.asarray(times, dtype=np.int64))
    span = int(reach[-1]) - start
    steps = np.diff(reach)
    i = int(np.argmax(steps)) if len(steps) else 0
    if len(steps) and 2 * int(steps[i]) > span:
        return (
            f"a gap of {_duration(int(steps[i]))} at {what} {first_index + i + 1:,}, from t = {int(reach[i])} to {int(reach[i + 1])} µs, "
            f"a clock jump or a corrupt record; cut the input there{raise_it}"
        )
    return (
        f"the {what}s span {_duration(span)}: a window of {_duration(window_us)} is too small for it; "
        f"give a longer --window{raise_it}"
    )


def _duration(us: int) -> str:
    for unit, size in (("hours", 3_600_000_000), ("min", 60_000_000), ("s", 1_000_000), ("ms", 1_000)):
        if abs(us) >= size:
            return f"{us / size:.1f} {unit}"
    return f"{us} µs"


def _slices(batches, size: int):
    """Batches of at most `size` events: a huge input batch (a whole Parquet file) is cut up, so its
    frames leave as it is counted."""
    for batch in batches:
        if batch.num_rows <= size:
            yield batch
        else:
            for offset in range(0, batch.num_rows, size):
                yield batch.slice(offset, size)


def _sorted(batches):
    """The events in time order (a stable sort, held in memory: at most SORT_EVENTS of them)."""
    held, rows = [], 0
    for batch in batches:
        rows += batch.num_rows
        if rows > SORT_EVENTS:
            raise NeurotacError(
                f"more than {SORT_EVENTS:,} events to sort (--sort holds them in memory; "
                "sort the recording in pieces, or frame it without --sort)"
            )
        held.append(batch)
    if not held:
        return
    table = pa.Table.from_batches(held)
    del held
    order = np.argsort(table.column("t").to_numpy(), kind="stable")
    yield from table.take(order).to_batches(max_chunksize=SCAN_EVENTS)


def _scaled_from_spill(out_schema: pa.Schema, batches, framing: Framing, report: FramingReport, sensor):
    """Float32 frames divided by each channel's largest count: the uint16 frames are written to a
    temporary file while the maxima are found, then read back and divided, so memory stays flat
    whatever the stream's length (the disk holds its counts). Returns (schema with the scale, batches)."""
    width, height = sensor
    counting = dataclasses.replace(framing, dtype="uint16")
    counts_schema = sch.frames_schema(height, width, (), window_us=framing.window_us)
    spill = tempfile.TemporaryFile(prefix="neurotac-frame-")
    peaks = np.zeros(2, dtype=np.int64)
    with ipc.new_stream(spill, counts_schema) as writer:
        for batch in _StreamFramer(counts_schema, counting, report, sensor).frames(batches):
            counts = sch.counts_numpy(batch.column("counts"))
            peaks = np.maximum(peaks, counts.max(axis=(0, 2, 3)))
            writer.write_batch(batch)
    report.scale = [float(max(peak, 1)) for peak in peaks]
    out_schema = sch.set_meta(out_schema, scale=report.scale)
    divisor = np.asarray(report.scale, dtype=np.float32)[None, :, None, None]

    def scaled():
        with spill:
            spill.seek(0)
            for batch in ipc.open_stream(spill):
                columns = batch.columns
                columns[3] = sch.counts_array(sch.counts_numpy(columns[3]).astype(np.float32) / divisor)
                yield pa.RecordBatch.from_arrays(columns, schema=out_schema)

    return out_schema, scaled()


def frames_from_events_table(table: pa.Table, window_us: int, report: FramingReport | None = None, **options) -> pa.Table:
    """Frame a whole `events` table (tests and notebooks); the command streams with frame_events."""
    framing = Framing(window_us=window_us, **options)
    report = report if report is not None else FramingReport()
    schema, batches = frame_events(table.schema, table.to_batches(max_chunksize=1 << 16), framing, report)
    return pa.Table.from_batches(list(batches), schema=schema)


# ---------------------------------------------------------------- the verb


def _string_labels(table: pa.Table, report: FramingReport) -> pa.Table:
    """A recordings table's columns beyond the contract's that are not strings (another tool's
    `size_mm` of integers, Polars' large strings, dates): frames carry labels as strings, so they go
    on as their text. A nested column cannot be a label, and a column named as one of the frames'
    own cannot go on: each is named as left out."""
    structural = set(sch.REQUIRED["recordings"]) | sch.NOT_LABELS
    reserved = set(sch.REQUIRED["frames"]) | {"grasp", "slip", "source_trial", "augment"}
    cast, nested, named = [], [], []
    for column in list(table.schema):
        if column.name in structural or pa.types.is_string(column.type):
            continue
        kind = column.type.value_type if pa.types.is_dictionary(column.type) else column.type
        if column.name in reserved:
            named.append(f"{column.name} ({column.type})")
            table = table.drop([column.name])
        else:
            index = table.schema.get_field_index(column.name)
            try:
                text = None if pa.types.is_nested(kind) else table.column(index).cast(pa.string())
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError):  # bytes that are no text, types without one
                text = None
            if text is None:
                nested.append(f"{column.name} ({column.type})")
                continue
            table = table.set_column(index, pa.field(column.name, pa.string()), text)
            if not (pa.types.is_large_string(kind) or pa.types.is_string(kind)):  # text already: nothing to say
                cast.append(f"{column.name} ({column.type})")
    if cast:
        report.notes.append(f"{', '.join(cast)} carried into the frames as text: frames hold labels as strings")
    if nested:
        report.notes.append(f"{', '.join(nested)} left out of the frames: a label is one value per trial, as text")
    if named:
        report.notes.append(f"{', '.join(named)} left out of the frames: the frames have a column of that name")
    return table


def check_for_kind(kind: str, events_only: list[str], phases, zero: str = "log") -> None:
    """Refuse what a table of this kind cannot take: `events_only` (the options given, as their caller
    names them) are for plain events tables; `--phases session` and `--zero rest` read a force log,
    which they have not."""
    if kind == "recordings" and events_only:
        one = len(events_only) == 1
        raise UsageError(f"{', '.join(events_only)} {'is' if one else 'are'} for plain events tables (from `neurotac import`); "
                         "a recordings table's trials keep their ids and are framed from their sync instant t0: leave "
                         f"{'it' if one else 'them'} out")
    if kind == "events" and phases == "session":
        raise UsageError("--phases session reads each grasp from the force log, and a plain events table has none: "
                         "sync it with its log first (`neurotac sync`), or frame it without --phases session")
    if kind == "events" and zero == "rest":
        raise UsageError("--zero rest reads the force log's rest level, and a plain events table has no log: "
                         "sync it with its log first (`neurotac sync`), or frame it without --zero rest")


def frame(source, framing: Framing, sensor=None):
    """Frame an opened `recordings` or `events` input (tables.Input): (frames schema, batches, report,
    the settings as history records them). A recordings table is read whole and framed trial by
    trial; an events stream is framed as it arrives."""
    report = FramingReport()
    args = framing.args()
    if source.kind == "recordings":
        table = source.read_all()
        table = _string_labels(table.replace_schema_metadata(sch.with_given_sensor(table.schema, sensor).metadata), report)
        schema, batches = frame_recordings_batches(table, framing, report)
        args["report"] = report.as_dict()
    else:
        if framing.slips is not None:
            raise NeurotacError("true slips label synced recordings (from `neurotac sync`): a plain events stream has no synced clock")
        schema, batches = frame_events(source.schema, source.batches, framing, report, sensor=sensor)
        args["trial"] = framing.trial
        args["report"] = report.as_dict() if report.scale else "streamed: counts of dropped events are written to stderr"
    return schema, batches, report, args
