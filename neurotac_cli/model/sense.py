"""The sensor in one process: a camera's events in, each window's force (and, for models trained on
contacts, its contact state, phase, slip flag and material) out, as `import | frame | crop | predict`
writes it.

Why one process: in the four-process pipe each window crosses three pipes, and every stage must be
woken and given a core before the next can start; on a machine with fewer cores than stages that
waiting, not the computing (about 0.6 ms a frame), is most of the time from a window's close to its
force. Here the same core calls are chained as generators on one thread, so a window is framed,
cropped and estimated in the read that closed it. The numbers that chose this: docs/journal.md.
"""

from dataclasses import dataclass, field

import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import UsageError
from neurotac_cli.io import live
from neurotac_cli.model import core, predict
from neurotac_cli.ops import crop as cropping
from neurotac_cli.ops import frame as framing_ops


@dataclass
class SenseReport:
    """What framing and cropping left out, complete once the output has been written."""

    framing: framing_ops.FramingReport = field(default_factory=framing_ops.FramingReport)
    crop: cropping.CropReport = field(default_factory=cropping.CropReport)
    outside: predict.Outside | None = None
    notes: list = field(default_factory=list)  # the slip bars a model trained on contacts followed (`predict.stream`)

    def messages(self, warn_above: float = 0.9) -> list[str]:
        """Lines for stderr, as `frame`, `crop` and `predict` would write them."""
        outside = [f"warning: {line}" for line in self.outside.messages()] if self.outside else []
        return self.framing.messages() + self.crop.messages(warn_above) + outside + self.notes


def sense(stream: live.Stream, model: core.Model, framing: framing_ops.Framing, box: cropping.CropSpec | None,
          material: core.Model | None = None, sensor=None, say=None) -> tuple[pa.Schema, object, SenseReport]:
    """(predictions schema, batches, report) of an events `stream`: framed by `framing`, cropped to a
    fixed `box` (None: whole frames, for a model trained on them), estimated by `model`, each window
    as soon as it has closed; `say` is called with a
    line when a frame or an estimate first lies outside the model's training data (`predict.Outside`)."""
    if box is not None and box.center == "auto":
        raise UsageError("sense streams, and --center auto needs the whole input: give the centre as X,Y "
                         "(`neurotac crop --center auto` on a recording of the rig prints it)")
    report = SenseReport()
    schema, frames = framing_ops.frame_events(stream.schema, stream.batches, framing, report.framing, sensor=sensor)
    cropped = frames
    if box is not None:
        schema, cropped, report.crop = cropping.crop(schema, frames, box)
    # the steps as the pipe's history would record them, so the model's check of the input reads the
    # pooling as `predict` does (the shape alone agrees for a smaller box pooled less)
    steps = [{"command": "frame", "args": {"dtype": framing.dtype}}]
    if box is not None and box.pool is not None:
        steps.append({"command": "crop", "args": {"pool": list(box.pool) if isinstance(box.pool, tuple) else box.pool}})
    schema = sch.set_meta(schema, history=sch.get_meta(schema, sch.HISTORY, []) + steps)
    core.check_streams(model)  # a classifier given as the force model is named as such, before the watcher reads it
    report.outside = predict.Outside.of(model, say=say)
    advice = (f"give `sense` the training's --window ({(model.input_spec.get('window_us') or 10000) / 1000:g}ms), --size with "
              "--center (or --box) and --pool (`neurotac info` of the training frames shows them)")
    spec = model.input_spec
    if box is None and sch.frames_shape(schema) != (spec.get("height"), spec.get("width")):
        advice += cropping.guessed_sensor_hint(stream.schema)  # whole frames whose size is only the events' extent
    schema, batches = predict.stream(model, schema, cropped, material=material, outside=report.outside, notes=report.notes,
                                     advice=advice)
    return schema, batches, report
