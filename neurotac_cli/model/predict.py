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


def stream(model: core.Model, schema: pa.Schema, batches, material: core.Model | None = None, outside: "Outside | None" = None):
    """(predictions schema, batches) as frames arrive (as `predict` writes them); `material`: a
    classifier naming each contact's material, for models trained on contacts; `outside` counts the
    frames and estimates beyond the model's training data as they pass."""
    if outside is not None:
        batches = outside.watch_frames(batches)
    if session.is_session_model(model):
        schema, out = session.stream(model, schema, batches, material=material)
    elif material is not None:
        raise ModelError(f"--material-model names each contact's material: it needs a force model trained with --contacts, "
                         f"and {model.name!r} was trained on whole trials")
    else:
        schema, out = core.stream_trials(model, schema, batches)
    return schema, (out if outside is None else outside.watch_estimates(out))


# A force model answers every frame, a scene it never saw too, and nothing in its output says so.
# A frame far busier than any training frame, or an estimate beyond the training forces, is named
# on stderr (the first at once, for a sensor that runs for hours; a count at the end). The margins
# keep a grasp a little harder than the hardest in training from being named.
EVENTS_MARGIN = 1.5  # a frame with more than this times the events of the busiest training frame
FORCE_MARGIN = 1.2  # an estimate beyond this times the largest training force (either sign)


@dataclass
class Outside:
    """Frames and estimates beyond what a force model was trained on, counted as a stream passes."""

    max_events: float | None  # events in the busiest training frame (None in model files that predate it)
    max_force: float | None  # the largest |force| of the training frames
    say: Callable[[str], None] | None = None  # called with a line at the first frame of each kind
    frames: int = 0
    busy: int = 0
    strong: int = 0
    busiest: float = 0.0
    strongest: float = 0.0
    _events: collections.deque = field(default_factory=collections.deque, repr=False)

    @classmethod
    def of(cls, model: core.Model, say=None) -> "Outside":
        scale = (model.input_spec or {}).get("normalisation", {}).get("force_scale")
        return cls(max_events=(model.training or {}).get("events_per_frame_max"), max_force=scale, say=say)

    def watch_frames(self, batches):
        """The frames on their way to the model: each non-empty batch's events per frame are kept
        until its estimates come back (both stream functions answer each non-empty batch in order)."""
        for batch in batches:
            if self.max_events and batch.num_rows:
                counts = sch.counts_numpy(batch.column("counts"))
                self._events.append(counts.reshape(len(counts), -1).sum(axis=1, dtype=np.float64))
            self.frames += batch.num_rows
            yield batch

    def watch_estimates(self, batches):
        """The estimates on their way out. A frame counts as busy only where the model read it: a
        model trained on contacts reads zero outside them (an LED blink before the first touch)."""
        for batch in batches:
            if not batch.num_rows:
                yield batch
                continue
            events = self._events.popleft() if self._events else None
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
        if self.strong:
            lines.append(f"{self.strong} of {self.frames} estimates went beyond {FORCE_MARGIN:g} times the largest training force "
                         f"({self.max_force:.3g} N; up to {self.strongest:.3g} N)")
        return lines
