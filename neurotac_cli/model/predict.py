"""Force predictions of any force model: models trained on whole trials (`model.core`) or on the
contacts of sessions (`model.session`), chosen by the model file."""

import pyarrow as pa

from neurotac_cli.errors import ModelError
from neurotac_cli.model import core, session


def predict_table(model: core.Model, table: pa.Table) -> pa.Table:
    """Every frame's estimate, a whole table at once (as `eval` scores it)."""
    if session.is_session_model(model):  # trained on contacts: runs on unbounded streams
        return session.predict_table(model, table)
    return core.predict_trials(model, table)


def stream(model: core.Model, schema: pa.Schema, batches, material: core.Model | None = None):
    """(predictions schema, batches) as frames arrive (as `predict` writes them); `material`: a
    classifier naming each contact's material, for models trained on contacts."""
    if session.is_session_model(model):
        return session.stream(model, schema, batches, material=material)
    if material is not None:
        raise ModelError(f"--material-model names each contact's material: it needs a force model trained with --contacts, "
                         f"and {model.name!r} was trained on whole trials")
    return core.stream_trials(model, schema, batches)
