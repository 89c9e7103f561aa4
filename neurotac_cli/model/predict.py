"""Force predictions of any force model: models trained on whole trials (`model.core`) or on the
contacts of sessions (`model.session`), chosen by the model file; and what in a stream lies
outside what the model was trained on (`Outside`)."""

import collections
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import ModelError
from neurotac_cli.model import core, session


def predict_table(model: core.Model, table: pa.Table) -> pa.Table:
    """Every frame's estimate, a whole table at once (as `eval` scores it)."""
    if session.is_session_model(model):  # trained on contacts: runs on unbounded streams
        return session.predict_table(model, table)
    return core.predict_trials(model, table)


def stream(model: core.Model, schema: pa.Schema, batches, material: core.Model | None = None, outside: "Outside | None" = None,
           notes: list | None = None, advice: str | None = None):
    """(predictions schema, batches) as frames arrive (as `predict` writes them); `material`: a
    classifier naming each contact's material, for models trained on contacts; `outside` counts the
    frames and estimates beyond the model's training data as they pass; `notes` gets the slip bars
    each stream of a model trained on contacts followed (`session.stream`), once the batches end;
    `advice`: how to make frames like the training's, where they differ (`core.check_input`)."""
    core.check_streams(model)  # a classifier given as the force model is named as such, whatever else is given
    if outside is not None:
        batches = outside.watch_frames(batches)
    if session.is_session_model(model):
        schema, out = session.stream(model, schema, batches, material=material, notes=notes, advice=advice)
    elif material is not None:
        raise ModelError(f"--material-model names each contact's material: it needs a force model trained with --contacts, "
                         f"and {model.name!r} was trained on whole trials")
    else:
        schema, out = core.stream_trials(model, schema, batches, advice=advice, notes=notes)
    return schema, (out if outside is None else outside.watch_estimates(out))


# A force model answers every frame, a scene it never saw too, and nothing in its output says so.
# A frame far busier than any training frame, or an estimate beyond the training forces, is named
# on stderr (the first at once, for a sensor that runs for hours; a count at the end). The margins
# keep a grasp a little harder than the hardest in training from being named.
EVENTS_MARGIN = 1.5  # a frame with more than this times the events of the busiest training frame
FORCE_MARGIN = 1.2  # an estimate beyond this times the largest training force (either sign)
# A scene of another kind can pass both at ordinary event rates (a rotating disk read as a steady
# press): a deform-gru also names frames whose features, averaged over about DISTANCE_FRAMES
# frames, have lain further from the training frames' than DISTANCE_MARGIN times the distance 99%
# of those frames keep to (Mahalanobis, in the standardised features) for DISTANCE_RUN frames in a
# row: a scene persists, a grasp's odd moment passes.
DISTANCE_MARGIN = 1.5
DISTANCE_FRAMES = 10
DISTANCE_RUN = 20


@dataclass
class Outside:
    """Frames and estimates beyond what a force model was trained on, counted as a stream passes."""

    max_events: float | None  # events in the busiest training frame (None in model files that predate it)
    max_force: float | None  # the largest |force| of the training frames
    say: Callable[[str], None] | None = None  # called with a line at the first frame of each kind
    net: object = None  # a network that logs its frames' feature distances (deform-gru)
    frames: int = 0
    busy: int = 0
    strong: int = 0
    unlike: int = 0
    busiest: float = 0.0
    strongest: float = 0.0
    farthest: float = 0.0
    _events: collections.deque = field(default_factory=collections.deque, repr=False)
    _trials: dict = field(default_factory=dict, repr=False)  # trial -> (mean distance, frames read, frames in a row over)

    @classmethod
    def of(cls, model: core.Model, say=None) -> "Outside":
        scale = (model.input_spec or {}).get("normalisation", {}).get("force_scale")
        net = model.net if hasattr(model.net, "distance_log") and float(model.net.distance_p99) > 0 else None
        return cls(max_events=(model.training or {}).get("events_per_frame_max"), max_force=scale, say=say, net=net)

    def watch_frames(self, batches):
        """The frames on their way to the model: each non-empty batch's events per frame are kept
        until its estimates come back (both stream functions answer each non-empty batch in order)."""
        try:
            for batch in batches:
                if self.max_events and batch.num_rows:
                    counts = sch.counts_numpy(batch.column("counts"))
                    self._events.append(counts.reshape(len(counts), -1).sum(axis=1, dtype=np.float64))
                self.frames += batch.num_rows
                if self.net is not None:  # what the network logs from here on is this batch's
                    self.net.distance_log = []
                yield batch
        finally:  # the network logs only while a stream is watched
            if self.net is not None:
                self.net.distance_log = None

    def _distances(self, batch) -> tuple | None:
        """The batch's feature distances as the network logged them, each averaged over about
        DISTANCE_FRAMES of the frames of its trial that the network read, and whether each frame
        ends DISTANCE_RUN of those in a row above the bar."""
        logged = [d.reshape(-1) for d in self.net.distance_log or []]
        distances = np.concatenate(logged) if logged else np.empty(0)
        if len(distances) != batch.num_rows:
            return None
        bar = DISTANCE_MARGIN * float(self.net.distance_p99)
        means, over = np.full(len(distances), np.nan), np.zeros(len(distances), dtype=bool)
        for k, (trial, value) in enumerate(zip(batch.column("trial").to_pylist(), distances.tolist())):
            if value != value:  # a frame the network did not read (a session model between contacts)
                continue
            mean, seen, run = self._trials.get(trial, (value, 0, 0))
            mean += (value - mean) / min(seen + 1, DISTANCE_FRAMES)
            run = run + 1 if mean > bar and seen + 1 >= DISTANCE_FRAMES // 2 else 0
            self._trials[trial] = (mean, seen + 1, run)
            means[k], over[k] = mean, run >= DISTANCE_RUN
        return means, over

    def watch_estimates(self, batches):
        """The estimates on their way out. A frame counts as busy only where the model read it: a
        model trained on contacts reads zero outside them (an LED blink before the first touch)."""
        for batch in batches:
            if not batch.num_rows:
                yield batch
                continue
            events = self._events.popleft() if self._events else None
            distances = self._distances(batch) if self.net is not None else None
            if events is not None and len(events) == batch.num_rows:
                over = events > EVENTS_MARGIN * self.max_events
                if "contact_pred" in batch.schema.names:
                    over &= batch.column("contact_pred").to_numpy(zero_copy_only=False)
                if over.any():
                    first = int(np.argmax(over))
                    self._first(self.busy, batch, first, f"{events[first] / self.max_events:.1f} times the events of the busiest "
                                "training frame; estimates of such frames lie outside what the model learnt")
                    self.busy += int(over.sum())
                    self.busiest = max(self.busiest, float(events[over].max()))
            if distances is not None:
                distances, over = distances
                if over.any():
                    first = int(np.argmax(over))
                    self._first(self.unlike, batch, first, f"its features lie {distances[first]:.1f} from the training frames' "
                                f"(99% of those within {float(self.net.distance_p99):.1f}): a scene unlike any the model learnt from")
                    self.unlike += int(over.sum())
                    self.farthest = max(self.farthest, float(np.nanmax(distances[over])))
            if self.max_force:
                force = np.abs(batch.column("force_pred").to_numpy(zero_copy_only=False))
                over = force > FORCE_MARGIN * self.max_force
                if over.any():
                    first = int(np.argmax(over))
                    self._first(self.strong, batch, first, f"estimate {force[first]:.3g} N, beyond the training forces "
                                f"(up to {self.max_force:.3g} N)")
                    self.strong += int(over.sum())
                    self.strongest = max(self.strongest, float(force.max()))
            yield batch

    def _first(self, seen_before: int, batch, row: int, what: str):
        if not seen_before and self.say is not None:
            self.say(f"trial {batch.column('trial')[row].as_py()!r} frame {batch.column('frame')[row].as_py()}: {what}")

    def messages(self) -> list[str]:
        """The counts, one line each kind that occurred."""
        lines = []
        if self.busy:
            lines.append(f"{self.busy} of {self.frames} frames held more than {EVENTS_MARGIN:g} times the events of the busiest "
                         f"training frame ({self.max_events:.0f}; up to {self.busiest:.0f}): their estimates are extrapolations")
        if self.unlike:
            lines.append(f"{self.unlike} of {self.frames} frames lay further from the training frames than {DISTANCE_MARGIN:g} times "
                         f"the distance 99% of those keep to ({float(self.net.distance_p99):.1f}; up to {self.farthest:.1f}, "
                         f"{DISTANCE_FRAMES}-frame mean, {DISTANCE_RUN} frames in a row): their estimates are readings of a scene "
                         "the model never saw")
        if self.strong:
            lines.append(f"{self.strong} of {self.frames} estimates went beyond {FORCE_MARGIN:g} times the largest training force "
                         f"({self.max_force:.3g} N; up to {self.strongest:.3g} N)")
        return lines
