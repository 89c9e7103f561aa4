"""Models: force regression per frame and material classification per trial.

Public API (used by the train, eval, classify and predict commands, and by studies):

- `FORCE_MODELS`, `MATERIAL_MODELS`: the model names.
- `make_spec(name, **options) -> dict`: a validated model spec (architecture and fit options).
- `train(table, spec, *, val_trials=None, val_fraction=None, val_where=None, per="object", seed=0, progress=None) -> Model`
- `save(model, path)`, `load(path) -> Model` (safetensors + JSON header, no pickle).
- `predict_table(model, table) -> predictions`, `classify_table(model, table) -> predictions`,
  `stream(model, batches) -> iterator of predictions batches` (state carried per trial); `Outside`: what
  in a stream lies beyond the model's training data, counted as it passes.
- `check_input(model, schema)`: refuse frames whose window, crop or channels differ from training;
  `input_notes(input_spec, training_history, schema)`: warnings where the frames may differ from the
  training frames in what `check_input` cannot compare (a window not recorded, a box elsewhere);
  `training_input_notes`, `scoring_input_notes`: every warning `train` and `eval --model` give about
  their frames before they run, for the command's stderr and the library's warnings alike.

The names are loaded when first used, so a command can list the model names (`model.names`)
for its --help without importing torch.
"""

import importlib

_HOMES = {
    "FORCE_MODELS": "names", "MATERIAL_MODELS": "names",
    "Model": "core", "check_input": "core", "classify_table": "core", "make_spec": "core", "input_notes": "core",
    "training_input_notes": "session", "scoring_input_notes": "session",
    "Outside": "predict", "predict_table": "predict", "stream": "predict", "train": "core",
    "load": "store", "save": "store",
}


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)


def __dir__():
    return sorted(set(globals()) | set(_HOMES))
