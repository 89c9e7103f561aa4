"""Force models that run indefinitely: the contact detector cuts a stream into contacts.

Why: every force network here was trained on grasps that start from a membrane at rest and a state
of zeros. On a session of many grasps its accumulators (deform-gru's deformation map and counts,
the recurrent states) carry each grasp into the next and it drifts (docs/journal.md). The
event-driven contact detector (`ops.contact`) finds when a contact begins; the force model runs only
inside a contact, from a fresh state begun on the few frames before its onset, and reads zero
between contacts; the contact ends after a release burst once the model reads near zero (or the
membrane has been quiet for a while). So the state is bounded by one contact, and between contacts
it is the detector's handful of numbers.

Training on sessions follows: the contacts of the training frames (their phases; the detector's
where there are none), with a little rest before and more after, are the training sequences, each
starting from zeros exactly as at run time (truncated back-propagation at the contacts' ends loses
nothing: no state crosses them). A model file trained this way carries the detector's settings in
its input spec (`contact`, `slip`); `predict_table` and `stream` of `model.predict` hand such a model
to this module. A model trained on single grasps has no `contact` and runs as before.
"""

import collections
import dataclasses

import numpy as np
import pyarrow as pa

from neurotac_cli import metrics
from neurotac_cli import schema as sch
from neurotac_cli.errors import InputError, ModelError, SchemaError
from neurotac_cli.model import data as shaping
from neurotac_cli.ops import contact as detector
from neurotac_cli.units import counted

CONTACT_KEY = "contact"
SLIP_KEY = "slip"
SESSION_FIELDS = [("contact_pred", pa.bool_()), ("phase_pred", pa.string()), ("slip_pred", pa.bool_())]
PASSED_ON = ("grasp", "slip")  # truth columns of session frames, copied to the predictions
# ... each of a type that says what it is (a flag may be 0/1); elsewhere a column of that name may be a label
TRUTH_TYPES = {"grasp": ("an integer (the grasp index, -1 at rest)", pa.types.is_integer),
               "slip": ("a boolean or 0/1 integer (the slip flag)", lambda t: pa.types.is_boolean(t) or pa.types.is_integer(t))}
# deform-gru's leak when trained on contacts: 30 s at 10 ms frames, far longer than a hold (its sums
# lose 1.3% over a 40-frame ch4 grasp), so a contact that never ends keeps them bounded.
DEFAULT_MEMORY_FRAMES = 3000
MAX_CONTACT_FRAMES = 60_000  # a material model sees at most the last 10 min (at 10 ms) of a contact: bounded state
RELEASE_SHARE = 0.1  # a contact ends when the estimate falls under this share of the largest training force


def whole_trials_note(schema: pa.Schema, what: str) -> str | None:
    """A warning where frames of sessions (a `grasp` column: `frame --phases session`) meet a force
    model of whole trials (`what`: how it meets them), which reads a session of many grasps as one."""
    if "grasp" not in schema.names:
        return None
    return (f"the frames hold sessions of many grasps (a grasp column), and {what} takes each session as one trial: "
            "no rest, drift, contact or slip figures; a model for sessions is trained with `train --contacts`")


def one_contact_note(summary: dict) -> str | None:
    """A warning where `train --contacts` found one contact per stream covering nearly all of it: the
    frames' phases were not read per grasp (`frame --phases session`)."""
    if summary.get("contacts", 0) and summary["contacts"] <= summary["sessions"] and summary["frames_in_contacts"] > 0.9 * summary["frames"]:
        covering = (f"{counted(summary['contacts'], 'contact')} in {counted(summary['sessions'], 'stream')} covering "
                    f"{100 * summary['frames_in_contacts'] / summary['frames']:.0f}% of the frames")
        if summary.get("found", 0) > summary["contacts"]:  # the phases found the grasps; their rests are shorter than the margins
            return (f"{covering}: the {summary['found']} contacts found rest less than {summary['merge_frames']} frames apart, "
                    "so they train as one, with no rest to learn zero from; train on sessions with longer rests")
        return f"{covering}: were the sessions framed with --phases session? (--phases auto labels a whole trial as one grasp)"
    return None


DETECTION_WARN_F1 = 0.9  # the detector's F1 on its own training sessions under which `train --contacts` warns
ASSUMED_POLARITY_RATIO = 3.0  # without phases: releases this many times the presses' events say the presses may be the other polarity


def polarity_note(summary: dict) -> str | None:
    """A warning where training took the presses' polarity without measuring it (frames without
    phases: the contacts are the detector's, read as the default polarity) and the contacts' releases
    make several times the events of their presses, as a bright object's presses and releases do when
    read the other way round."""
    if summary.get("from") != "detector" or not summary.get("press_off") or not summary.get("release_on"):
        return None
    ratio = summary["release_on"] / summary["press_off"]
    if ratio < ASSUMED_POLARITY_RATIO:
        return None
    pressed, released = detector.polarity_names(summary.get("press_polarity", "off"))
    return (f"the frames have no phases, so the presses were taken to make {pressed} events, not measured, and the contacts "
            f"found so release {ratio:.0f} times the events they press ({summary['release_on']:g} {released} against "
            f"{summary['press_off']:g} {pressed} at their peaks): if pressing makes {released} events on this sensor (a bright "
            "object), these contacts run from release to press; frame the sessions with `--phases session` so that training "
            "measures it")


def detection_note(summary: dict) -> str | None:
    """A warning where the detector, run on the training sessions with their true force ending
    contacts (`detection_check`), finds their contacts or slips poorly: it will do no better at run time.
    Its contacts are not judged where the frames' phases read each stream as one contact
    (`one_contact_note`: grasps merged, or a whole trial labelled as one grasp): it is scored against
    that one contact there, however well it finds each grasp."""
    check = summary.get("detection")
    if not check:
        return None
    poor = []
    polarity = summary.get("press_polarity", "off")
    pressed, released = detector.polarity_names(polarity)
    reading = ("each contact's press of one polarity and its release of the other" if polarity == "either" else
               f"a press of {pressed} events, a release of {released}")
    if check["true"] and check["f1"] < DETECTION_WARN_F1 and one_contact_note(summary) is None:
        poor.append(f"finds {check['hits']:g} of their {counted(int(check['true']), 'contact')}, {check['found']:g} in all "
                    f"(F1 {check['f1']:.2f}; a contact that runs on through a rest merges grasps): this sensor's events do "
                    f"not show its presses and releases as the detector reads them ({reading})")
    if check.get("slip_true") and check["slip_f1"] < DETECTION_WARN_F1:
        poor.append(f"flags {counted(int(check['slip_found']), 'slip')} for their {check['slip_true']:g} ({check['slip_hits']:g} "
                    f"of them found, F1 {check['slip_f1']:.2f}): this sensor's holds do not show slips as the slip flag reads "
                    "them (both polarities at once on the pressed cells, above the bars set from the training presses)")
    if not poor:
        return None
    return ("the event detector, run on the training sessions with their true force ending contacts, " + "; and it ".join(poor)
            + " (docs/design.md); at run time it does no better")


def is_session_model(model) -> bool:
    return CONTACT_KEY in (model.input_spec or {})


def contact_config(model) -> detector.ContactConfig:
    return _settings(model, detector.ContactConfig, CONTACT_KEY)


def slip_config(model) -> detector.SlipConfig:
    return _settings(model, detector.SlipConfig, SLIP_KEY)


def _settings(model, kind, key):
    """The detector's settings kept in a model file; one this version does not know is refused, not dropped.
    A count of frames the file lacks (written before it was a setting) is its default at the file's
    window, as training would have scaled it (`detector.at_window`)."""
    given = model.input_spec.get(key, {})
    if not isinstance(given, dict):
        raise ModelError(f"model {model.name!r}: its detector settings ({key}) are not a mapping of names to values; train the model again")
    unknown = sorted(set(given) - {f.name for f in dataclasses.fields(kind)})
    if unknown:
        raise ModelError(f"model {model.name!r} carries detector settings this neurotac does not know ({', '.join(unknown)}): "
                         "it was written by a newer version; upgrade neurotac to run it")
    defaults = detector.at_window(kind(), model.input_spec.get("window_us"))
    missing = {name: getattr(defaults, name) for name in detector.FRAME_SETTINGS[kind.__name__] if name not in given}
    try:
        return detector.checked(kind(**given, **missing))
    except ValueError as error:
        raise ModelError(f"model {model.name!r}: its detector setting {error}; train the model again") from None


class Stream:
    """One stream's state (a session, or a trial): the detector's numbers and the force model's state
    inside the current contact (None between contacts)."""

    def __init__(self, model, material=None):
        self.model, self.material = model, material
        self.sums = collections.deque(maxlen=MAX_CONTACT_FRAMES)  # OFF and ON per frame of the current contact
        self.config = contact_config(model)
        self.slip = slip_config(model)
        self.contact = detector.ContactState.start(self.config)
        self.inner = None
        self.lead = collections.deque(maxlen=self.config.lead_frames)  # the last frames and their times, read before an onset
        self.last_frame = None  # the (frame number, time) read last: a stream's frames come one window after another

    def check_order(self, trial: str, frames: np.ndarray, t_us: np.ndarray):
        """Refuse frames that do not follow one another (a gap, a repeat, the wrong order, a time that
        does not move on with the frame number): the detector and the force model take each frame as
        the next window of the stream, and the estimates keep the frames' times."""
        given = np.concatenate([[self.last_frame[0]], frames]) if self.last_frame is not None else frames
        times = np.concatenate([[self.last_frame[1]], t_us]) if self.last_frame is not None else t_us
        bad = np.flatnonzero((np.diff(given) != 1) | (np.diff(times) <= 0))
        if len(bad):
            k = int(bad[0])
            what = (f"frame {int(given[k + 1])} follows frame {int(given[k])}" if given[k + 1] - given[k] != 1 else
                    f"frame {int(given[k + 1])} (t {int(times[k + 1])} µs) follows frame {int(given[k])} at t {int(times[k])} µs")
            raise InputError(f"trial {trial!r}: {what}; a model trained with --contacts reads each stream's frames one window "
                             "after another, as `frame` writes them (give whole sessions, in order)")
        if len(frames):
            self.last_frame = (int(frames[-1]), int(t_us[-1]))

    def step(self, counts: np.ndarray, t_us: np.ndarray):
        """(force, phase, slip flag, material) per frame of frames (T, 2, H, W) at times (T,) µs; the
        material (with a material model) on the frame where a contact ends, None elsewhere.

        Frame by frame the detector says whether the frame is in a contact; the force model runs on
        the frames of a contact, in one call per run of them until a release burst makes the end of
        the contact possible, then frame by frame until its estimate says the contact is over (with
        press_polarity "either", frame by frame throughout: `detector.may_end_by_force`)."""
        off, on, separation = detector.frame_stats(counts)
        self.distances = np.full(len(counts), np.nan)  # feature distances of the frames the network read (model.predict.Outside)
        force = np.zeros(len(counts), dtype=np.float32)
        phases = np.empty(len(counts), dtype=object)
        slips = np.zeros(len(counts), dtype=bool)
        materials = np.full(len(counts), None, dtype=object)
        pending = []  # frames of the current contact waiting for one call of the force model
        for k in range(len(counts)):
            touching = self.contact.phase != detector.NONE
            before = self.contact.onsets
            phase = detector.step(self.config, self.contact, off[k], on[k], by_force=True, frame=counts[k])
            if self.contact.onsets != before or phase == detector.NONE:
                self._run(pending, counts, t_us, force)
                self.inner = None
            if self.contact.onsets != before:
                self.sums.clear()
                self._lead_in()
            if phase != detector.NONE:
                pending.append(k)
                self.sums.append((off[k], on[k]))
                if detector.may_end_by_force(self.config, self.contact):
                    self._run(pending, counts, t_us, force)  # frame by frame: the estimate may end the contact here
                    if detector.end_by_force(self.config, self.contact, float(force[k])):
                        phase, force[k], self.inner = detector.NONE, 0.0, None
            if touching and phase == detector.NONE:
                materials[k] = self._material()
            phases[k] = phase
            slips[k] = detector.slip_step(self.slip, self.contact, off[k], on[k], separation[k])
            self.lead.append((counts[k], t_us[k]))
        self._run(pending, counts, t_us, force)
        return force, phases, slips, materials

    def bars_note(self, trial: str) -> str | None:
        """A line for stderr when the slip bars followed this stream's presses (None where they did not)."""
        gain, model = self.contact.gain, self.slip
        if gain.bars is None:
            return None
        presses = "its one press" if len(gain.presses) == 1 else f"the median of its last {len(gain.presses)} presses"
        pressed, released = detector.polarity_names(self.config.press_polarity)
        return (f"trial {trial}: slips flagged at {gain.bars.min_events:g} {pressed} / {gain.bars.on_events:g} {released} events, "
                f"from {presses} ({np.median(gain.presses):.0f} events); the model's bars {model.min_events:g} / {model.on_events:g}")

    def open_contact_note(self, trial: str) -> str | None:
        """With a material model, a line naming the material of a contact the stream ended inside (its
        rows are written by then, so its material can only go to stderr); None otherwise."""
        if self.material is None or self.contact.phase == detector.NONE or not self.sums:
            return None
        frames = len(self.sums)
        return (f"trial {trial}: the input ended inside a contact ({frames} frame{'s' if frames != 1 else ''} long, "
                f"not released): material {self._material()} from the frames seen")

    def _material(self):
        """The material model's class for the contact that just ended (its OFF and ON per frame)."""
        if self.material is None or not self.sums:
            return None
        sums = np.asarray(self.sums, dtype=np.float32).reshape(-1, 2, 1, 1)
        self.sums.clear()
        data = shaping.Sequences(trials=["contact"], counts=[sums], t=[np.zeros(len(sums), np.int64)],
                                 frame=[np.arange(len(sums), dtype=np.int32)], force=[np.full(len(sums), np.nan, np.float32)],
                                 phase=[np.full(len(sums), None, dtype=object)])
        return self.material.classes[int(self.material.proba(data)[0].argmax())]

    def _lead_in(self):
        """Start the force model's state on the frames just before an onset, as its training contacts
        start a few frames before the true one: the detector fires on the press's first large burst,
        and the deformation map misses the events before it (two frames short, a hold read 0.1 N low).
        Their estimates are not written: those frames were at rest when they were read."""
        if self.lead:
            counts, t_us = (np.stack(column)[None] for column in zip(*self.lead))
            self._step(counts, t_us, None)

    def _run(self, pending: list, counts, t_us, force):
        """The force model on the pending frames (consecutive), carrying its state; empties `pending`."""
        if pending:
            begin, end = pending[0], pending[-1] + 1
            estimate, distances = self._step(counts[None, begin:end], t_us[None, begin:end], self.inner)
            if distances is not None:
                self.distances[begin:end] = distances
            # a contact's normal force is never negative: a model's undershoot as a press begins or ends reads as none
            force[begin:end] = np.maximum(estimate[0], 0.0)
            self.contact.peak_force = max(self.contact.peak_force, float(estimate[0].max()))
            pending.clear()

    def _step(self, counts, t_us, state):
        """One call of the force model from `state`, which becomes the stream's: its estimate, and the
        frames' feature distances where a watcher asked the network for them (None otherwise)."""
        estimate, self.inner = self.model.step(counts, t_us, state)
        log = getattr(self.model.net, "distance_log", None)
        return estimate, (log.pop()[0] if log else None)


# ---------------------------------------------------------------- training


MARGIN_AFTER = 30  # 10 ms frames of rest kept after each true contact for training


def contacts_table(table: pa.Table, config: detector.ContactConfig) -> tuple[pa.Table, dict, list]:
    """The frames of every contact, one trial per contact (`STREAM@FRAME`), what was found:
    {"sessions", "contacts" (training sequences: a contact and the next one within its margin are one),
    "found" (contacts), "merge_frames" (that margin), "frames", "frames_in_contacts", "from", "press_polarity", "press_off",
    "release_on", "presses_on": [presses pressed ON, presses] (None without phases)}, and per stream
    what `detection_check` reads (None without phases).

    Where the frames have phases (the force's, `frame --phases session` or `auto`), a contact is a run
    of frames whose phase is not none, with the detector's `lead_frames` of rest before it (the
    frames the model reads before an onset at run time: the detector finds onsets within a frame or
    two) and MARGIN_AFTER after it (the model learns to read zero once released, which ends the
    contact at run time), and the polarity the presses make most of is measured
    (`detector.press_polarity`); without phases, the runs the detector finds, with the same lead."""
    sch.validate(table.schema, "frames")
    data = shaping.sequences(table)
    labelled = any(p not in (None, "none") for phases in data.phase for p in phases)
    row_of = {(t, int(f)): i for i, (t, f) in enumerate(zip(table.column("trial").to_pylist(), table.column("frame").to_numpy().tolist()))}
    polarity, streams = config.press_polarity, []
    for counts, phases in zip(data.counts, data.phase):
        off, on = detector.frame_sums(counts)
        touching = (metrics.runs(np.asarray([p not in (None, "none") for p in phases])) if labelled
                    else metrics.runs(detector.detect(config, off, on)[0] != detector.NONE))
        streams.append((off, on, touching))
    runs = [touching for _, _, touching in streams]
    presses_on = None
    if labelled:
        shares = detector.press_shares(streams, config.warmup_frames, config.press_frames)
        polarity = detector.press_polarity(streams, config.warmup_frames, shares=shares)
        presses_on = [sum(own == "on" for mine in detector.contact_polarities(shares) for own in mine), sum(map(len, shares))]
        streams = detector.oriented_streams(streams, polarity, shares)
    rows, names = [], []
    after = detector.frames_at(MARGIN_AFTER, sch.get_meta(table.schema, sch.WINDOW)) if labelled else 0
    for trial, frames, touching in zip(data.trials, data.frame, runs):
        for begin, end in _widened(touching, len(frames), config.lead_frames, after):
            rows += [row_of[(trial, int(f))] for f in frames[begin:end]]
            names += [f"{trial}@{int(frames[begin])}"] * (end - begin)
    if not rows:
        raise ModelError("found no contact in the training frames (no phase other than none, and no burst of OFF "
                         "events above the background); check the crop covers the contact, or train without --contacts")
    found = table.take(pa.array(rows, pa.int64()))
    found = found.set_column(found.schema.get_field_index("trial"), found.schema.field("trial"), pa.array(names, pa.string()))
    press_off, release_on = detector.rig_peaks(streams, config.warmup_frames)
    summary = {"sessions": len(data), "contacts": len(set(names)), "found": sum(map(len, runs)),
               "merge_frames": after + config.lead_frames, "frames": table.num_rows,
               "frames_in_contacts": len(rows), "from": "phases" if labelled else "detector",
               "press_polarity": polarity, "dominance": detector.dominance_for(config, streams) if labelled else config.dominance,
               "press_off": press_off, "release_on": release_on, "presses_on": presses_on}
    return found, summary, _truths(table, data, row_of) if labelled else None


def _truths(table: pa.Table, data, row_of: dict) -> list:
    """Per stream: its frames, true force (0 where unknown), touching and slip truth (None without a
    `slip` column), for `detection_check`."""
    slip = slip_truth(table)
    out = []
    for trial, counts, frames, force, phases in zip(data.trials, data.counts, data.frame, data.force, data.phase):
        truth = None if slip is None else slip[[row_of[(trial, int(f))] for f in frames]]
        out.append((counts, np.nan_to_num(force), np.asarray([p not in (None, "none") for p in phases]), truth))
    return out


def detection_check(config: detector.ContactConfig, slip: detector.SlipConfig, truths: list) -> dict:
    """The detector over the training streams, each frame's true force standing in for the model's
    estimate (the best a model can do): how many of their contacts, and of their slips where the
    frames say, it finds. A sensor whose events the rules do not read (presses and releases of both
    polarities, releases too faint to see) shows here, before a model runs on it."""
    found, slips = [], []
    for counts, force, _, _ in truths:
        off, on, separation = detector.frame_stats(counts)
        phases, _, flags, _ = detector.detect(config, off, on, separation=separation, slip=slip, force=force, counts=counts)
        found.append(phases != detector.NONE)
        slips.append(flags)
    figures = metrics.detection_figures([t[2] for t in truths], found, "contact")
    check = {name: figures[f"contact_{name}"] for name in ("f1", "true", "found", "hits")}
    if all(t[3] is not None for t in truths):
        figures = metrics.detection_figures([t[3] for t in truths], slips, "slip")
        check.update({f"slip_{name}": figures[f"slip_{name}"] for name in ("f1", "true", "found", "hits")})
    return check


def _widened(runs: list, length: int, before: int, after: int) -> list:
    """Runs grown by `before` and `after` frames, clipped to the stream, overlapping ones merged."""
    out = []
    for begin, end in runs:
        begin, end = max(0, begin - before), min(length, end + after)
        if out and begin <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], end))
        else:
            out.append((begin, end))
    return out


def train(table: pa.Table, spec: dict, config: detector.ContactConfig | None = None,
          slip: detector.SlipConfig | None = None, **options):
    """Train the force model of `spec` on the contacts found in `table` (sessions or trials); the model
    file then carries the detector's settings and runs on unbounded streams."""
    from neurotac_cli.model import core

    window = sch.get_meta(table.schema, sch.WINDOW)
    config = config or detector.at_window(detector.ContactConfig(release_force_n=release_force(table)), window)
    if spec["model"] == "deform-gru":
        spec = {"memory_frames": detector.frames_at(DEFAULT_MEMORY_FRAMES, window), **spec}
    found, summary, truths = contacts_table(table, config)
    if summary["frames_in_contacts"] >= summary["frames"]:  # nothing at rest: no zero to learn, no background to detect from
        raise ModelError(f"every one of the {summary['frames']:,} training frames lies inside a contact: --contacts learns from "
                         "sessions with rests between grasps (`frame --phases session`); trials of one grasp each train without --contacts")
    config = dataclasses.replace(config, press_polarity=summary["press_polarity"], dominance=summary["dominance"])
    slip = slip or detector.at_window(detector.slip_for(summary["press_off"], summary["release_on"]), window)
    if truths is not None:
        summary["detection"] = detection_check(config, slip, truths)
    progress = options.get("progress")
    if progress:
        pressed, released = detector.polarity_names(config.press_polarity)
        how = (f"pressed as OFF or ON events ({summary['presses_on'][0]} of {summary['presses_on'][1]} presses ON: each contact read by "
               f"its own), released where the other polarity outnumbers the press's {config.dominance:g} to 1"
               if config.press_polarity == "either" else
               f"pressed as {pressed} events{'' if truths is not None else ' (taken, not measured: no phases)'}, released where "
               f"{released} events outnumber {pressed} {config.dominance:g} to 1")
        merged = (f" (of {summary['found']} found: a contact ending within {summary['merge_frames']} frames of the next trains "
                  "with it)" if summary["found"] != summary["contacts"] else "")
        progress(f"contacts: {summary['contacts']}{merged} in {counted(summary['sessions'], 'stream')}, "
                 f"{summary['frames_in_contacts']} of {summary['frames']} frames, {how}; slips flagged at "
                 f"{slip.min_events:g} {pressed} and {slip.on_events:g} {released} events above the background")
    if options.get("val_trials"):
        options = dict(options, val_trials=_contacts_of(found, options["val_trials"]))
    model = core.train(found, spec, unit="contact", **options)
    model.input_spec = dict(model.input_spec, **{CONTACT_KEY: config.to_dict(), SLIP_KEY: slip.to_dict()})
    model.training = dict(model.training, contacts=summary)
    return model


def _contacts_of(found: pa.Table, chosen: list) -> list:
    """Validation ids given as sessions (the frames' trials) stand for every contact found in them
    (named STREAM@FRAME); a contact's own name stays as it is. Sessions that hold every contact leave
    none to train on: refused here, where the ids are still sessions."""
    names = list(dict.fromkeys(found.column("trial").to_pylist()))
    out = []
    for name in chosen:
        inside = [contact for contact in names if contact.split("@")[0] == name]
        out += inside if name not in names and inside else [name]  # an unknown id is left for training to refuse
    if set(out) == set(names):  # an unknown id among them is for training to name
        raise ModelError("every contact would be in validation, leaving none to train on (--val-trials names a session for "
                         "all of its contacts); choose fewer validation sessions or contacts")
    return out


def release_force(table: pa.Table) -> float:
    """A contact is over when the estimate falls under RELEASE_SHARE of the largest training force."""
    force = table.column("force").to_numpy(zero_copy_only=False)
    known = force[~np.isnan(force)] if len(force) else force
    return RELEASE_SHARE * float(np.abs(known).max()) if len(known) else detector.ContactConfig.release_force_n


# ---------------------------------------------------------------- running


def predictions_schema(table_schema: pa.Schema, model, material=None) -> pa.Schema:
    from neurotac_cli.model.core import FORCE_FIELDS, _predictions_schema

    extra = [(name, table_schema.field(name).type) for name in PASSED_ON if name in table_schema.names]
    named = [("material_pred", pa.string())] if material is not None else []
    schema, _ = _predictions_schema(table_schema, FORCE_FIELDS + SESSION_FIELDS + named + extra, model)
    return schema


def predict_table(model, table: pa.Table, material=None) -> pa.Table:
    """Force, contact and phase for every frame, each trial streamed from its start (same as `stream`)."""
    schema, batches = stream(model, table.schema, table.to_batches(), material)
    return pa.Table.from_batches(list(batches), schema=schema)


def stream(model, schema: pa.Schema, batches, material=None, notes: list | None = None, advice: str | None = None):
    """Predictions batch by batch; each trial's detector and force state carried from frame to frame.
    With `material` (a material model on frames pooled to one pixel, at the same window), each
    contact's material in `material_pred` on the frame where it ends. With `notes`, a line per trial
    whose slip bars followed its presses, and (with `material`) per trial that ended inside a contact,
    is appended once the batches are exhausted. `advice` as `core.check_input`'s.

    Frames of a trial must arrive in order (as `frame` writes them)."""
    from neurotac_cli.model.core import check_input, check_streams

    check_streams(model)
    if material is not None:
        check_material(model, material)
    check_input(model, schema, advice)
    for name, (what, fits) in TRUTH_TYPES.items():
        if name in schema.names and not fits(schema.field(name).type):
            raise SchemaError(f"frames column {name!r} has type {schema.field(name).type}, expected {what} for a model "
                              "trained with --contacts; cast it, or rename it if it is a label")
    out_schema = predictions_schema(schema, model, material)
    streams = {}

    def run():
        for batch in batches:
            if batch.num_rows == 0:
                continue
            yield _predict_batch(model, material, batch, out_schema, streams)
        if notes is not None:
            lines = [(one.bars_note(trial), one.open_contact_note(trial)) for trial, one in streams.items()]
            notes.extend(line for pair in lines for line in pair if line)

    return out_schema, run()


def check_material(model, material):
    """A material model for contacts: trained on frames pooled to one pixel, at the force model's window."""
    spec = material.input_spec
    if not is_session_model(model):
        raise ModelError(f"a material per contact needs a force model trained with --contacts (model {model.name!r} "
                         "was trained on whole trials); train it with `neurotac train --contacts`")
    if material.task != "material":
        raise ModelError(f"the material model {material.name!r} estimates force; give a classifier (material-timing, material-rises, material-curves, material-dnn)")
    if (spec.get("height"), spec.get("width")) != (1, 1) or spec.get("accumulated"):
        raise ModelError(f"the material model {material.name!r} was trained on {spec.get('width')}x{spec.get('height')} "
                         f"{'accumulated ' if spec.get('accumulated') else ''}frames; a contact's material needs one trained on "
                         "plain counts pooled to one pixel (`neurotac crop --pool all`)")
    if spec.get("adapt"):
        raise ModelError(f"the material model was trained with --adapt-by {spec['adapt']['by']}: it standardises a batch of "
                         "grasps together, and a contact is named alone as it ends; give one trained without --adapt-by")
    if spec.get("window_us") != model.input_spec.get("window_us"):
        raise ModelError(f"the material model was trained on {spec.get('window_us')} µs windows, the force model on "
                         f"{model.input_spec.get('window_us')} µs; frame both the same way")


def _predict_batch(model, material, batch, out_schema, streams) -> pa.RecordBatch:
    trials = batch.column("trial").to_pylist()
    counts = sch.counts_numpy(batch.column("counts"))
    t = batch.column("t").to_numpy().astype(np.int64)
    frame_numbers = batch.column("frame").to_numpy().astype(np.int64)
    force = np.empty(batch.num_rows, dtype=np.float32)
    phase = np.empty(batch.num_rows, dtype=object)
    slip = np.zeros(batch.num_rows, dtype=bool)
    named = np.full(batch.num_rows, None, dtype=object)
    distances = np.full(batch.num_rows, np.nan)
    edges = [0] + [i for i in range(1, len(trials)) if trials[i] != trials[i - 1]] + [len(trials)]
    for begin, end in zip(edges[:-1], edges[1:]):
        if trials[begin] not in streams:
            streams[trials[begin]] = Stream(model, material)
        one = streams[trials[begin]]
        one.check_order(trials[begin], frame_numbers[begin:end], t[begin:end])
        force[begin:end], phase[begin:end], slip[begin:end], named[begin:end] = one.step(counts[begin:end], t[begin:end])
        distances[begin:end] = one.distances
    log = getattr(model.net, "distance_log", None)
    if log is not None:  # row for row, NaN where no contact was read, for the watcher of this batch
        log.append(distances)
    columns = {
        "trial": batch.column("trial"), "frame": batch.column("frame").cast(pa.int32()), "t": batch.column("t"),
        "phase": batch.column("phase"), "force": batch.column("force").cast(pa.float32()), "force_pred": pa.array(force),
        "contact_pred": pa.array(phase != detector.NONE, pa.bool_()), "phase_pred": pa.array(phase.tolist(), pa.string()),
        "slip_pred": pa.array(slip, pa.bool_()), "material_pred": pa.array(named.tolist(), pa.string()),
    }
    for field in out_schema:
        if field.name not in columns:
            columns[field.name] = batch.column(field.name)
    return pa.RecordBatch.from_arrays([columns[f.name] for f in out_schema], schema=out_schema)


def slip_truth(table: pa.Table) -> np.ndarray | None:
    """The `slip` truth column as flags, unknown read as no slip; None without the column, or where it
    holds no value at all (nothing to score against)."""
    if "slip" not in table.schema.names or table.column("slip").null_count == table.num_rows:
        return None
    return table.column("slip").cast(pa.bool_()).fill_null(False).to_numpy(zero_copy_only=False)


def session_rows(predictions: pa.Table) -> list:
    """`metrics.session_rows` of a predictions table that has the detector's columns."""
    names = predictions.schema.names
    column = lambda name: predictions.column(name).to_numpy(zero_copy_only=False) if name in names else None  # noqa: E731
    grasp = predictions.column("grasp").cast(pa.float64()).fill_null(np.nan).to_numpy() if "grasp" in names else None
    slip = slip_truth(predictions)
    return metrics.session_rows(
        predictions.column("trial").to_pylist(), column("frame"), column("t"), predictions.column("phase").to_pylist(),
        column("force"), column("force_pred"), grasp=grasp, contact_pred=column("contact_pred"),
        slip=slip, slip_pred=column("slip_pred"),
    )


def summary_lines(figures: dict) -> list[str]:
    """`eval`'s stderr lines for the session figures (scope `all` of `metrics.session_rows`)."""
    get = lambda name: figures.get(name, float("nan"))  # noqa: E731
    # A figure without frames to measure it is left out of the line, not printed as nan.
    per_grasp = (f", per grasp {get('grasp_rmse_mean'):.3g} N (mean over {int(figures.get('grasps', 0))})"
                 if np.isfinite(get("grasp_rmse_mean")) else "")
    constant = f" (the best constant {get('contact_rmse_constant'):.3g} N)" if "contact_rmse_constant" in figures else ""
    contact = f"RMSE in contact {get('contact_rmse'):.3g} N{constant}{per_grasp}" if "contact_rmse" in figures else "no frame in contact"
    drift = f", drift {get('drift_n_per_min'):.3g} N/min" if np.isfinite(get("drift_n_per_min")) else ""
    rest = (f"at rest ({int(get('rest_frames'))} frames): mean |estimate| {get('rest_mean_abs'):.3g} N, max "
            f"{get('rest_max_abs'):.3g} N{drift}" if get("rest_frames") > 0 else "no frame at rest")
    lines = [f"{rest}; {contact}"]
    if get("contact_rmse") >= get("contact_rmse_constant"):
        lines.append(f"warning: in contact the model reads the force no better than a constant at its true mean "
                     f"({get('contact_rmse'):.3g} N against {get('contact_rmse_constant'):.3g} N): it has not learnt this "
                     "sensor's force (train on more of its sessions, or check the frames are the training's kind)")
    if get("rest_loaded_frames") > 0:
        lines.append(f"warning: {int(get('rest_loaded_frames'))} frames at rest by their phase carry a true force of up to "
                     f"{get('rest_loaded_max'):.3g} N above the log's rest level, so the figures at rest include contacts: frame sessions with "
                     "`neurotac frame --phases session`")
    if "contact_f1" in figures and not get("contact_true"):  # a session without a grasp: nothing to find
        lines.append(f"contacts: none in the frames, {counted(int(get('contact_found')), 'contact')} detected")
    elif "contact_f1" in figures:
        # medians: a contact run on into the next grasp moves a mean by its whole length
        lag = get("contact_onset_frames_median")
        end = get("contact_end_frames_median")
        onset = (f"median onset {abs(lag):g} frames {'late' if lag >= 0 else 'early'}, {100 * get('contact_within_2'):.0f}% "
                 f"within 2 frames, median end {abs(end):g} frames {'late' if end >= 0 else 'early'}; "
                 if get("contact_hits") > 0 else "")
        lines.append(f"contacts: F1 {get('contact_f1'):.3f} ({int(get('contact_hits'))} of {int(get('contact_true'))} found, "
                     f"{int(get('contact_found'))} detected), {onset}per frame F1 {get('contact_frame_f1'):.3f}")
    if "slip_f1" in figures and not get("slip_true"):
        lines.append(f"slips: none in the frames, {counted(int(get('slip_found')), 'slip')} flagged")
    elif "slip_f1" in figures:
        within = f", {100 * get('slip_within_20'):.0f}% within 20 ms" if get("slip_hits") > 0 else ""
        lines.append(f"slips: F1 {get('slip_f1'):.3f} ({int(get('slip_hits'))} of {int(get('slip_true'))} found, "
                     f"{int(get('slip_found'))} flagged){within}")
    elif "contact_f1" in figures:
        lines.append("slips: not scored (the frames have no `slip` truth: `neurotac frame --slips CSV` adds it)")
    return lines


def training_input_notes(table: pa.Table, force_model: bool, contacts: bool = False) -> list[str]:
    """The warnings about its frames that training gives before it starts (`train` on stderr, the
    library as NeurotacWarning), each starting `warning: `."""
    from neurotac_cli.model.core import gaps_note, missing_frames

    notes = []
    if not sch.get_meta(table.schema, sch.WINDOW):
        notes.append(f"warning: the frames do not record their window (metadata {sch.WINDOW}): the model cannot check the "
                     "window of the frames it reads later")
    if force_model and not contacts:
        whole = whole_trials_note(table.schema, "training without --contacts")
        notes += [whole and f"warning: {whole}", gaps_note(missing_frames(table), "runs")]
    return [note for note in notes if note]


def scoring_input_notes(input_spec: dict, training: dict | None, task: str, table: pa.Table) -> list[str]:
    """The warnings about frames scored by a trained model (`eval --model` on stderr, the library as
    NeurotacWarning), each starting `warning: `: frames unlike the training's, sessions given to a
    model of whole trials, frames missing inside its trials, frames without slip truth."""
    from neurotac_cli.model.core import gaps_note, input_notes, missing_frames

    notes = [f"warning: {note}" for note in input_notes(input_spec, (training or {}).get("data_history"), table.schema)]
    unknown = table.column("slip").null_count if "slip" in table.schema.names else 0
    if unknown and CONTACT_KEY in (input_spec or {}):
        notes.append(f"warning: {counted(unknown, 'frame')} of {table.num_rows:,} have no slip truth (null in column slip): "
                     "scored as no slip, which splits a slip they fall inside (`frame --slips CSV` writes every frame's)")
    if task != "material" and CONTACT_KEY not in (input_spec or {}):
        whole = whole_trials_note(table.schema, "a model trained without --contacts")
        notes += [whole and f"warning: {whole}", gaps_note(missing_frames(table), "runs")]
    return [note for note in notes if note]
