"""Checks of force logs against the recording they are synced with: what a real rig gets wrong.

A log that does not reach the recording (a wrong offset, a log of another session, a time column
on the wall clock), a log of one sample, NaN or infinite values (one rule for both: refused), and
values no gripper on a membrane produces (negative throughout: a sign or tare error; beyond the
sensor's range: a wrong unit). Refusals raise; doubts become warning lines, kept in each trial's
sync metadata under `warnings` for the command to print.
"""

import numpy as np

from neurotac_cli.errors import SyncError
from neurotac_cli.io.force import ForceLog

MIN_SAMPLES = 10  # fewer cannot trace a grasp (20 ms at the thesis's 500 Hz), nor feed its median filter
SHORT_OVERLAP = 0.5  # warn when less than this share of a force log's span lies inside the recording
NEGATIVE_N = -0.1  # below the rest noise of the simulated Nano17 and FlexiForce (about ±0.02 N)
NEGATIVE_SHARE = 0.5  # warn when more than this share of the samples reads below NEGATIVE_N
RANGE_N = 450.0  # the largest FlexiForce A201 range (100 lbf); a log beyond it is read in the wrong unit
# a sensor at its full range reads a little past it (noise, over-range): a wrong unit is 10 to 1000 times off
RANGE_WARN_N = 1.1 * RANGE_N


def check_samples(logs: list[ForceLog], recording: str) -> None:
    """Refuse a log with too few samples, or with a NaN or infinite value."""
    for number, log in enumerate(logs, start=1):
        _check_samples(log, _where(recording, logs, log, number))


def _check_samples(log: ForceLog, where: str) -> None:
    if len(log.t) < MIN_SAMPLES:
        raise SyncError(
            f"{where}: the force log has {len(log.t)} sample(s), a grasp needs at least {MIN_SAMPLES}; "
            "check the log is the whole recording (at 500 Hz, 10 samples are 20 ms)"
        )
    bad = ~np.isfinite(np.asarray(log.value, dtype=np.float64))
    if bad.any():
        first = int(np.argmax(bad))
        raise SyncError(
            f"{where}: {int(bad.sum())} force values are NaN or infinite (the first at sample {first}, "
            f"{log.t[first] / 1e3:g} ms); clean the force log first (drop or interpolate those rows)"
        )


def plausibility_warnings(log: ForceLog, where: str) -> list[str]:
    """A log that reads negative through most of the grasp, one value throughout, or beyond any sensor's range."""
    values = np.asarray(log.value, dtype=np.float64)
    warnings = []
    negative = float(np.mean(values < NEGATIVE_N))
    if negative > NEGATIVE_SHARE:
        warnings.append(
            f"{where}: the force reads below {NEGATIVE_N:g} N on {100 * negative:.0f}% of the samples "
            f"(median {np.median(values):.3g} N); a squeeze is positive: check the sensor's sign and tare"
        )
    elif np.ptp(values) == 0:  # even a sensor at rest reads noise: one value throughout is no reading (a negative one is told above)
        warnings.append(
            f"{where}: the force is {values[0]:g} N in every one of the {len(values)} samples; every frame would be "
            "labelled with it: check the sensor was connected and the force column (--force-column)"
        )
    peak = float(np.max(np.abs(values)))
    if peak > RANGE_WARN_N:
        warnings.append(
            f"{where}: the force reaches {peak:.4g} N, beyond any sensor of the rig (largest range {RANGE_N:g} N); "
            "check the force unit (a header like force_mN, or --force-unit)"
        )
    return warnings


def inside(t0: int, log: ForceLog, first_us: int, last_us: int) -> tuple[int, int]:
    """(µs of the log inside the recording [first_us, last_us] once placed at t0, at most 0 where it
    misses it; the log's span in µs, at least 1)."""
    start, end = t0 + int(log.t[0]), t0 + int(log.t[-1])
    return min(end, last_us) - max(start, first_us), max(end - start, 1)


DATED_US = 10**14  # a log's first time this late (3 years) is a date on a wall clock, not a time from the sync instant


def dated_note(first_us: int) -> str | None:
    """What to do with a log whose times are dates (ISO timestamps, or seconds since 1970), else None."""
    if first_us < DATED_US:
        return None
    import datetime

    date = datetime.datetime.fromtimestamp(first_us / 1e6, datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    return (f"; its times are dates (from {date}), and `sync` reads a log's times from the sync instant: give them "
            "from the log's start (its first time subtracted)")


def overlap_warnings(t0: int, log: ForceLog, first_us: int, last_us: int, where: str) -> list[str]:
    """Refuse a log that does not overlap the recording [first_us, last_us] once placed at t0; warn
    when less than SHORT_OVERLAP of it does."""
    start, end = t0 + int(log.t[0]), t0 + int(log.t[-1])
    inside_us, span = inside(t0, log, first_us, last_us)
    if inside_us <= 0:
        late = f"; its time must start at the sync instant, not at {log.t[0] / 1e6:g} s" if abs(log.t[0]) > last_us - first_us else ""
        late = dated_note(int(log.t[0])) or late
        raise SyncError(
            f"{where}: the force log ({_seconds(start)}..{_seconds(end)} on the camera clock) does not overlap the "
            f"recording ({_seconds(first_us)}..{_seconds(last_us)}){late}; check --offset and that the log belongs to this recording"
        )
    if inside_us < SHORT_OVERLAP * span:
        return [
            f"{where}: only {100 * inside_us / span:.0f}% of the force log ({inside_us / 1e6:.3g} of {span / 1e6:.3g} s) "
            "lies inside the recording; check the sync instant (--offset, --method) and that the log belongs to this recording"
        ]
    return []


def coverage_warnings(t0: int, log: ForceLog, last_us: int, where: str) -> list[str]:
    """Warn when a recording's only force log covers less than SHORT_OVERLAP of the recording after
    its sync instant: frames end where the log ends, so the later events are left out."""
    after = last_us - t0
    covered = min(t0 + int(log.t[-1]), last_us) - max(t0 + int(log.t[0]), t0)
    if after > 0 and covered < SHORT_OVERLAP * after:
        return [f"{where}: the force log covers only {100 * max(covered, 0) / after:.0f}% of the recording after its sync "
                f"instant ({max(covered, 0) / 1e6:.3g} of {after / 1e6:.3g} s): frames end where it ends, and later events "
                "are left out; is it the whole log?"]
    return []


def check_logs(t: np.ndarray, instants: list, logs: list[ForceLog], recording: str) -> None:
    """Check each force log against the recording's events (times `t`, camera clock) at its sync
    instant: refusals raise SyncError, warnings are added to the instant's details."""
    if len(t) == 0:
        raise SyncError(f"{recording}: the recording has no events to sync a force log with")
    first_us, last_us = int(t.min()), int(t.max())
    for number, (instant, log) in enumerate(zip(instants, logs), start=1):
        where = _where(recording, logs, log, number)
        warnings = plausibility_warnings(log, where) + overlap_warnings(instant.t0, log, first_us, last_us, where)
        if len(logs) == 1:  # one log for the whole recording (a session): it should last as long
            warnings += coverage_warnings(instant.t0, log, last_us, where)
        if warnings:
            instant.details.setdefault("warnings", []).extend(warnings)


def _where(recording: str, logs: list, log: ForceLog, number: int) -> str:
    return recording if len(logs) == 1 else f"{recording}, trial {log.trial or number}"


def _seconds(t_us: int) -> str:
    return f"{t_us / 1e6:.3f} s"
