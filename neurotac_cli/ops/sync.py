"""Find the shared instant of camera and force logger; cut and label trials (thesis 3.6.1).

Methods (each returns the sync instants t0 on the camera clock, one per force-log trial):

- `led`: the LED-off spike of OFF events (`ops.led`).
- `trigger`: external trigger events of an AEDAT 4.0 file (schema metadata `neurotac:triggers`).
- `offset`: a known clock offset: the force log's zero is camera time `offset_us`.
- `xcorr`: no LED: the event rate cross-correlated with the force log's |dF/dt| through a model of
  the force sensor and the membrane (`ops.xcorr`).

A long session (several force-log trials in one camera file) is cut into trials: trial i holds the
events up to the end of its force log (or the next instant, if sooner); the events after that are
the next trial's lead-in, as in a file of one grasp (the first trial holds all that came before).
Force is conditioned as in the thesis: a median filter (window `median_us`), in newtons.
"""

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from neurotac_cli import provenance, schema as sch
from neurotac_cli.errors import NeurotacError, SyncError, UsageError
from neurotac_cli.io.force import ForceLog
from neurotac_cli.ops import forcelog
from neurotac_cli.io.manifest import Source
from neurotac_cli.ops.instant import Instant
from neurotac_cli.ops.led import LED_LATENCY_US, MIXED_ON_PER_OFF, extra_spike, led_spikes
from neurotac_cli.ops.xcorr import (AGREE_MIN, XCORR_RESPONSE_US, XCORR_SATURATION, agreement, disagreement_warnings, edge_warnings,
                                   force_noise_share, uncertainty_warnings,
                                   unrelated_warnings, xcorr_instant)
from neurotac_cli.units import counted

METHODS = ("led", "trigger", "offset", "xcorr")


@dataclass(frozen=True)
class SyncMethod:
    """How to find the sync instant. Validated when built."""

    method: str = "led"
    offset_us: int | None = None
    region: tuple | None = None  # (x, y, w, h) where the LED is seen
    latency_us: int = LED_LATENCY_US
    response_us: int = XCORR_RESPONSE_US
    sensor_lag_us: tuple | None = None  # xcorr: the force sensor's (rise, fall) time constants; None = estimate
    saturation: float = XCORR_SATURATION
    min_z: float = 10.0
    min_coverage: float = 0.05
    trigger_type: str | None = None
    trigger_id: int | None = None  # the input (AEDAT 3.1) or channel (EVT 2.0/2.1/3.0) whose triggers count
    median_us: int = 10_000
    bin_us: int = 1_000
    keep_led: bool = False  # keep the blink's own events in the trial (they are a marker, not touch)

    def __post_init__(self):
        if self.method not in METHODS:
            raise NeurotacError(f"unknown sync method {self.method!r} (use one of {', '.join(METHODS)})")
        if self.method == "offset" and self.offset_us is None:
            raise UsageError("--method offset needs --offset DURATION (the camera time of the force log's zero)")
        if self.method != "offset" and self.offset_us is not None:
            raise UsageError(f"--offset sets the instant for --method offset; with --method {self.method} it would be ignored "
                             "(add --method offset, or leave --offset out)")
        if self.method != "trigger" and (self.trigger_type is not None or self.trigger_id is not None):
            raise UsageError(f"--trigger-type and --trigger-id choose triggers for --method trigger; with --method {self.method} "
                             "they would be ignored")
        if self.region is not None and (len(self.region) != 4 or self.region[2] <= 0 or self.region[3] <= 0):
            raise NeurotacError(f"region must be X,Y,W,H with positive W and H, got {self.region!r}")
        if self.method not in ("led", "xcorr") and self.region is not None:
            raise UsageError(f"--region is where led and xcorr look; with --method {self.method} it would be ignored")
        if self.method != "led" and self.keep_led:
            raise UsageError(f"--keep-led keeps the LED blink's burst of --method led; with --method {self.method} there is none")
        if self.median_us < 0:
            raise NeurotacError("the median filter window cannot be negative")
        if self.sensor_lag_us is not None and (len(self.sensor_lag_us) != 2 or min(self.sensor_lag_us) < 0):
            raise NeurotacError(f"the sensor lag is RISE[,FALL], two durations >= 0, got {self.sensor_lag_us!r}")
        if self.saturation < 0:
            raise NeurotacError("the membrane saturation share cannot be negative (0 = a linear membrane)")
        if not all(np.isfinite([self.saturation, self.min_z, self.min_coverage])):  # NaN passes every comparison
            raise NeurotacError("the saturation share, the spike's z-score and its coverage must be finite numbers")
        if self.min_coverage > 1:
            raise UsageError(f"--min-coverage is a share of the pixels, at most 1, got {self.min_coverage:g} (0.05 = 5%)")

    def args(self) -> dict:
        out = {"method": self.method, "median_us": self.median_us}
        if self.method == "offset":
            out["offset_us"] = self.offset_us
        if self.method == "led":
            out.update(latency_us=self.latency_us, min_z=self.min_z, min_coverage=self.min_coverage, keep_led=self.keep_led)
        if self.method == "xcorr":
            out["response_us"] = self.response_us
            out["sensor_lag_us"] = None if self.sensor_lag_us is None else list(self.sensor_lag_us)
            out["saturation"] = self.saturation
        if self.method == "trigger":
            out["trigger_type"] = self.trigger_type
            if self.trigger_id is not None:
                out["trigger_id"] = self.trigger_id
        if self.region is not None:
            out["region"] = list(self.region)
        return out


def sync_method(method: str = "led", latency_us: int | None = None, **settings) -> SyncMethod:
    """A SyncMethod whose `latency_us`, when given, is the camera's delay of the chosen method: from
    the LED's switch-off to the spike (led), or of the event rate behind the force (xcorr)."""
    if latency_us is not None and method not in ("led", "xcorr"):
        raise UsageError(f"--latency is the camera's delay for led and xcorr; with --method {method} it would be ignored")
    if latency_us is not None and latency_us < 0:
        raise UsageError(f"--latency is a delay, at least 0, got {latency_us / 1000:g} ms")
    return SyncMethod(method=method, latency_us=LED_LATENCY_US if latency_us is None else latency_us,
                      response_us=XCORR_RESPONSE_US if latency_us is None else latency_us, **settings)


def sync(sources, method: SyncMethod) -> tuple[pa.Table, list[str]]:
    """`neurotac sync`: every source (see `io.manifest.recording_sources`) synced into one recordings
    table, and the warnings for stderr."""
    recordings = sync_sources(sources, method)
    trials = sch.get_meta(recordings.schema, sch.SYNC)["trials"]
    warnings = [line for info in trials.values() for line in info.get("warnings", [])]
    # how the force log was read (a column without a unit read as newtons), once per log however many trials it feeds
    warnings += list(dict.fromkeys(note for info in trials.values() for note in info.get("notes", [])))
    if method.method == "xcorr":
        warnings += edge_warnings(trials) + uncertainty_warnings(trials) + unrelated_warnings(trials)
    else:
        warnings += disagreement_warnings(trials, {"led": "the LED blink", "trigger": "the trigger"}.get(method.method, "--offset"))
    return recordings, warnings


# ---------------------------------------------------------------- force conditioning


def condition_force(log: ForceLog, median_us: int) -> np.ndarray:
    """Median-filter the force (window `median_us`, as an odd number of samples; 0 = none)."""
    values = np.asarray(log.value, dtype=np.float64)
    if median_us <= 0 or len(values) < 3 or log.period_us <= 0:
        return values
    size = int(round(median_us / log.period_us))
    size = max(1, size if size % 2 else size + 1)
    if size <= 1:
        return values
    if size > len(values) // 2:  # the median of most of the log is its rest value: the grasp would be flattened away
        raise SyncError(f"the force median filter ({median_us / 1000:g} ms, {size} samples) is longer than half the force log "
                        f"({len(values)} samples, {(log.t[-1] - log.t[0]) / 1000:g} ms); give a shorter --median (0us = none)")
    from scipy.ndimage import median_filter

    return median_filter(values, size=size, mode="nearest")


# ---------------------------------------------------------------- trigger, offset


def find_triggers(schema: pa.Schema, method: SyncMethod, count: int) -> list[Instant]:
    triggers = sch.get_meta(schema, "neurotac:triggers", None)
    if not triggers:
        raise SyncError(
            "the recording has no external trigger events (AEDAT 3.1/4.0 and EVT 2.0/2.1/3.0 files carry them, kept by `neurotac import`); "
            "use --method led, xcorr or offset"
        )
    kinds = sorted({str(item.get("type")) for item in triggers})
    ids = sorted({int(item["id"]) for item in triggers if item.get("id") is not None})
    has = f"the file has {', '.join(kinds)}" + (f" on inputs {', '.join(map(str, ids))}" if ids else "")
    chosen = sorted((item for item in triggers if method.trigger_type in (None, item.get("type"))
                     and (method.trigger_id is None or item.get("id") == method.trigger_id)), key=lambda item: int(item["t"]))
    if not chosen:
        wanted = " ".join(filter(None, [f"of type {method.trigger_type!r}" if method.trigger_type is not None else "",
                                        f"on input {method.trigger_id}" if method.trigger_id is not None else ""]))
        raise SyncError(f"no trigger {wanted} ({has}); choose with --trigger-type / --trigger-id")
    kinds_chosen = sorted({(str(item.get("type")), item.get("id")) for item in chosen}, key=str)
    if count == 1 and len(kinds_chosen) > 1:  # which one marks the trial is not ours to guess
        listed = ", ".join(f"{kind}" + (f" on input {input_id}" if input_id is not None else "") for kind, input_id in kinds_chosen)
        raise SyncError(f"the recording has triggers of several kinds ({listed}); choose the one that marks the grasp with "
                        "--trigger-type and, where inputs differ, --trigger-id")
    if len(chosen) != count:  # one trial and several triggers too: the first is no likelier the grasp's than the last
        at = ", ".join(f"{int(item['t'])} µs" for item in chosen[:5]) + (", ..." if len(chosen) > 5 else "")
        raise SyncError(
            f"{len(chosen)} triggers (at {at}) but {count} trial(s) in the force log; pick triggers with --trigger-type or "
            f"--trigger-id ({has}), or cut the recording to one trigger per trial"
        )
    details = lambda item: {"type": item.get("type"), "triggers": len(chosen), **({"id": item["id"]} if "id" in item else {})}  # noqa: E731
    return [Instant(t0=int(item["t"]), details=details(item)) for item in chosen[:count]]


# ---------------------------------------------------------------- trials




def sync_source(source: Source, method: SyncMethod) -> tuple[list[dict], dict]:
    """Sync one recording: (trials for schema.recordings_table, sync info per trial)."""
    table = source.events
    t = _column(table, "t", np.int64)
    x = _column(table, "x", np.uint16)
    y = _column(table, "y", np.uint16)
    p = _column(table, "p", np.uint8)
    logs = source.force
    count = len(logs)
    forcelog.check_samples(logs, source.trial)
    try:
        forces = [condition_force(log, method.median_us) for log in logs]
        instants = _instants(table, t, x, y, p, logs, forces, method)
    except SyncError as error:  # the force log's own checks, around this, name the trial themselves
        raise SyncError(f"trial {source.trial}: {error}") from None
    forcelog.check_logs(t, instants, logs, source.trial)
    order, jump = _time_order(t, source.trial)
    if order is not None:
        t, x, y, p = t[order], x[order], y[order], p[order]
    # trial i ends where its force log ends (or at the next instant, if sooner); what follows, up
    # to the next instant, is the next trial's lead-in (its LED blink), as in one-grasp files
    bounds = []
    for instant, following, log in zip(instants, instants[1:], logs):
        end = instant.t0 + int(log.t[-1]) + max(int(log.period_us), 1)
        bounds.append(min(end, following.t0))
    cuts = [0] + [int(np.searchsorted(t, bound)) for bound in bounds] + [len(t)]
    trials, info = [], {}
    for i, (instant, log, values) in enumerate(zip(instants, logs, forces)):
        name = source.trial if count == 1 else (log.trial or f"{source.trial}-{i + 1:02d}")
        a, b = cuts[i], cuts[i + 1]
        led_end = instant.details.get("led_end_us")
        if led_end is not None and not method.keep_led:
            # the blink's switch-off burst marks the instant; it is not touch: leave it out of the trial
            a_led = max(a, int(np.searchsorted(t, led_end)))
            instant.details["led_events_removed"] = a_led - a
            a = a_led
        trials.append(
            {
                "trial": name,
                "t0": instant.t0,
                "events": (t[a:b] - instant.t0, x[a:b], y[a:b], p[a:b]),
                "force": (log.t, values.astype(np.float32)),
                "labels": dict(source.labels),
            }
        )
        entry = {"t0": instant.t0, "score": instant.score}
        entry.update(instant.details)
        if method.method != "xcorr" and "agreement" not in entry:  # xcorr reports its own; a spike chosen by it, too
            entry["agreement"] = agreement(t, log.t, values, instant.t0, sorted_time=True, raw=log.value)
        if method.method == "xcorr":  # a noisy log lowers xcorr's r by itself (`unrelated_warnings`)
            entry["force_noise_share"] = round(force_noise_share(log.value), 4)
        if log.notes:
            entry["notes"] = log.notes
        if jump and i == 0:  # said once per recording
            entry.setdefault("warnings", []).append(jump)
        info[name] = entry
    return trials, info


ORDERED_SHARE = 0.001  # a stream with steps back of over ORDERED_STEP_US between at most this share of its events ...
ORDERED_STEP_US = 1_000  # ... is in camera order (a camera reorders by microseconds)
CLOCK_JUMP_US = 1_000_000  # events that step back in time this far come from a clock that jumped (a camera's own
# reordering is microseconds: an HD EVT 3.0 file steps back by up to 11 µs)


def _time_order(t: np.ndarray, trial: str) -> tuple:
    """The order that sorts the events by time (None where they are in it), and the warning for a
    clock that jumped back (None): large steps back in a stream otherwise in camera order, whose own
    steps back are microseconds (a table written out of order, by pixel say, steps back by
    milliseconds everywhere: sorting it is all it needs)."""
    steps = np.diff(t)
    if len(t) < 2 or not np.any(steps < 0):
        return None, None
    ordered = np.count_nonzero(steps < -ORDERED_STEP_US) <= max(ORDERED_SHARE * len(steps), 1)
    back = -int(steps.min())
    return np.argsort(t, kind="stable"), (_clock_jump(trial, back, steps) if ordered and back >= CLOCK_JUMP_US else None)


def _clock_jump(trial: str, back: int, steps: np.ndarray) -> str:
    """The warning for a recording whose events step back in time by CLOCK_JUMP_US or more: sorted
    by time, events of different moments mix, and the trial is cut where the force log says."""
    jumps = int(np.count_nonzero(steps <= -CLOCK_JUMP_US))
    return (f"trial {trial}: the events step back in time by up to {back / 1e6:.3g} s ({counted(jumps, 'place')}): the camera's "
            "clock jumped (a time word lost, or a wrap the file cannot tell from a step back); sorted by time, events of different "
            "moments mix (`neurotac info` of the camera file counts the steps)")


SPARE_SPIKES = 4  # spikes beyond the log's trials weighed by how well the log then moves with the events
AGREE_MARGIN = 0.2  # the best placement's r must lead the next by this much to be taken


def _by_agreement(spikes: list, count: int, t, logs, forces) -> list:
    """One blink among several spikes (a fast press or a flicker can also darken a share of the
    membrane at once): the one where the force log, placed there, moves with the events, when it
    clearly does, or the one spike that leaves the log inside the recording (where the log, if it can
    be scored, moves with the events, or where it is the one spike of OFF events alone: `_mixed`);
    else the spikes are refused. A spike that leaves less than forcelog.SHORT_OVERLAP of the log
    inside the recording is no candidate: its r would be read on a few seconds of the log (a burst
    near a recording's end fitted a 40 s log's first 4 s at r 0.57). Among the candidates, those of
    OFF events alone are weighed where there are both kinds."""
    if count != 1:
        raise extra_spike(spikes, count)
    scored, figures = _placements(spikes, t, logs[0], forces[0])
    blinks = [item for item in scored if not _mixed(item[1])]
    kind = " of OFF events alone" if blinks and len(blinks) < len(scored) else ""
    scored = blinks if blinks else scored
    # a blink of OFF events alone among bursts of both polarities (a gripper's motor): taken whatever
    # its r, which the moves of a camera on an arm can drown
    alone = len(blinks) == 1 and all(_mixed(spike) for spike in spikes if spike is not blinks[0][1])
    ranked = sorted(scored, key=lambda item: -item[0] if item[0] is not None else np.inf)
    if len(scored) == 1 and (scored[0][0] is None or scored[0][0] >= AGREE_MIN or alone):
        # a short grasp's release can darken as much as the blink, but the log cannot start there; a
        # grasp too short to score is taken, one where the log does not move with the events is not
        (r, spike), why = scored[0], f"the only one{kind} that leaves the force log inside the recording"
    # else every placement that holds the log scored, the best at least AGREE_MIN and AGREE_MARGIN above the next
    elif (not ranked or any(r is None for r, _ in scored) or ranked[0][0] < AGREE_MIN
            or (len(ranked) > 1 and ranked[0][0] - ranked[1][0] < AGREE_MARGIN)):
        raise extra_spike(spikes, count, f" (the force log placed at each moves with the events: {figures})")
    else:
        (r, spike), why = ranked[0], "where the force log moves with the events"
    spike.details["agreement"] = r  # None for a grasp too short to score: not scored again
    mixed = [other for other in spikes if _mixed(other)] if not _mixed(spike) else []
    polarity = (f"; {counted(len(mixed), 'spike')} with {MIXED_ON_PER_OFF:g} ON events per OFF or more passed over (the membrane "
                "shaking or the scene moving, not a light switching off)" if mixed else "")
    spike.details.setdefault("warnings", []).append(f"{counted(len(spikes), 'LED-off spike')} stand out; the one at "
                                                    f"{spike.details['onset_us']} µs was taken, {why} ({figures}){polarity}")
    return [spike]


def _mixed(spike) -> bool:
    """A spike of about as many ON events as OFF (`led._OnTimes`): an LED switching off makes
    OFF events alone (an independent generator's blink: 20 ON against 80,838 OFF), a gripper's motor
    shaking the membrane both alike (0.8-1.4 ON per OFF). A flash of a millisecond or two can hold its
    switch-on's ON events too (up to 0.9 ON per OFF): the rule only weighs spikes that leave the log
    inside the recording."""
    return spike.details.get("on_share", 0.0) >= MIXED_ON_PER_OFF


FIGURES_LISTED = 8  # spikes whose figures a message lists; the rest are counted


def _placements(spikes: list, t, log, force) -> tuple[list, str]:
    """(r, spike) of each spike that leaves at least forcelog.SHORT_OVERLAP of the log inside the
    recording (r None where it cannot be scored, and for spikes of both polarities where such a
    spike of OFF alone exists: they are not weighed), and each spike's figure as the messages give it."""
    first, last = int(np.min(t)), int(np.max(t))
    ordered = bool(np.all(t[1:] >= t[:-1]))  # each placement's span by bisection, not by a pass over every event
    scored, figures = [], []
    shares = [forcelog.inside(spike.t0, log, first, last) for spike in spikes]
    shares = [inside_us / span for inside_us, span in shares]
    alone = any(share >= forcelog.SHORT_OVERLAP and not _mixed(spike) for spike, share in zip(spikes, shares))
    for spike, inside in zip(spikes, shares):
        held = inside >= forcelog.SHORT_OVERLAP
        weighed = held and not (alone and _mixed(spike))
        r = agreement(t, log.t, force, spike.t0, sorted_time=ordered, raw=log.value) if weighed else None
        scored += [(r, spike)] if held else []
        about = (f"r {r:.2f}" if r is not None else "no r" if weighed else "not weighed" if held
                 else f"{max(inside, 0.0):.0%} of the log inside the recording")
        on = f", {spike.details['on_share']:.2f} ON per OFF" if _mixed(spike) else ""
        figures.append(f"{about} at {spike.details['onset_us']} µs{on}")
    more = len(figures) - FIGURES_LISTED
    return scored, ", ".join(figures[:FIGURES_LISTED]) + (f" and {more} more" if more > 0 else "")


def _check_region(region, sensor) -> None:
    """A --region that reaches past the sensor is a box typed for another camera, or mistyped."""
    if region is not None and sensor is not None and (region[0] + region[2] > sensor[0] or region[1] + region[3] > sensor[1]):
        raise UsageError(f"--region {','.join(map(str, region))} reaches past the {sensor[0]}x{sensor[1]} sensor")


def _instants(table, t, x, y, p, logs, forces, method: SyncMethod) -> list:
    """The sync instant of each trial of the force log, found by the chosen method."""
    count = len(logs)
    try:
        _check_region(method.region, sch.sensor_of(table.schema))
        if method.method == "led":
            instants = led_spikes(t, x, y, p, method, count, sch.sensor_of(table.schema), spare=SPARE_SPIKES)
            if len(instants) > count:
                instants = _by_agreement(instants, count, t, logs, forces)
        elif method.method == "trigger":
            instants = find_triggers(table.schema, method, count)
        elif method.method == "offset":
            if count > 1:
                raise SyncError(f"--method offset gives one instant, but the force log holds {count} trials; use --method led or trigger")
            instants = [Instant(t0=int(method.offset_us), details={"offset_us": int(method.offset_us)})]
        else:
            if count > 1:
                raise SyncError(f"--method xcorr aligns one force trace, but the force log holds {count} trials; split the log")
            instants = [xcorr_instant(t, x, y, logs[0].t, forces[0], method, p)]
    except SyncError as error:
        if count > 1 and logs[0].trial is None:
            # the trials were told only from the log's time stepping back: a log of one grasp with a row
            # out of place reads as several, and the error about them would not say why
            raise SyncError(f"{error}; the force log was read as {count} trials because its time steps back (the first time "
                            f"at sample {len(logs[0].t)}, from {logs[0].t[-1] / 1000:g} to {logs[1].t[0] / 1000:g} ms): "
                            "if it is one trial, sort it by time") from None
        raise
    return instants


def _column(table: pa.Table, name: str, dtype) -> np.ndarray:
    return table.column(name).to_numpy().astype(dtype, copy=False)


def sync_sources(sources, method: SyncMethod) -> pa.Table:
    """Sync every source (an iterable, read one at a time) into one recordings table."""
    trials, info, sensor, inputs = [], {}, None, []
    for source in sources:
        inputs.append(source.events.schema)
        found = sch.sensor_of(source.events.schema)
        if sensor is None:
            sensor = found
        elif found is not None and found != sensor:
            raise NeurotacError(
                f"recording of trial {source.trial} is {found[0]}x{found[1]}, the others {sensor[0]}x{sensor[1]}; "
                "sync recordings of one sensor together"
            )
        made, details = sync_source(source, method)
        for trial in made:
            if trial["trial"] in info:
                raise NeurotacError(f"trial {trial['trial']!r} appears twice; give each trial its own name")
        trials += made
        info.update(details)
    sync = dict(method.args())
    sync["trials"] = info
    width, height = sensor if sensor else (None, None)
    return provenance.carry(sch.recordings_table(trials, width, height, sync=sync), inputs)
