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

from neurotac_cli.model.core import (  # noqa: F401
    FORCE_MODELS,
    MATERIAL_MODELS,
    Model,
    check_input,
    classify_table,
    make_spec,
    predict_table,
    stream,
    train,
)
from neurotac_cli.model.store import load, save  # noqa: F401
