"""Models: force regression per frame and material classification per trial.

Public API (used by the train, eval, classify and predict commands, and by studies):

- `FORCE_MODELS`, `MATERIAL_MODELS`: the model names.
- `make_spec(name, **options) -> dict`: a validated model spec (architecture and fit options).
- `train(table, spec, *, val_trials=None, val_fraction=None, val_where=None, per="object", seed=0, progress=None) -> Model`
- `save(model, path)`, `load(path) -> Model` (safetensors + JSON header, no pickle).
- `predict_table(model, table) -> predictions`, `classify_table(model, table) -> predictions`,
  `stream(model, batches) -> iterator of predictions batches` (state carried per trial).
- `check_input(model, schema)`: refuse frames whose window, crop or channels differ from training.
"""

import importlib

# Loaded on first use: `neurotac_cli.model.store.read_header` and the package itself cost no torch
# import, so a verb can check a model file and its input before paying for torch.
_EXPORTS = {
    **dict.fromkeys(
        ("FORCE_MODELS", "MATERIAL_MODELS", "Model", "check_input", "classify_table", "make_spec", "predict_table", "stream", "train"),
        "core",
    ),
    "load": "store",
    "save": "store",
}


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"neurotac_cli.model.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
