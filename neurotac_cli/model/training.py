"""`neurotac train`: a model trained on frames as the command asks, and what it reports about it."""

from dataclasses import dataclass

import pyarrow as pa

from neurotac_cli.errors import UsageError
from neurotac_cli.metrics import metrics_table
from neurotac_cli.model.core import Model, make_spec, train
from neurotac_cli.model.curve import best_epoch, member_curves
from neurotac_cli.model.names import MATERIAL_MODELS

DEFAULT_VAL_FRACTION = 0.1  # validation share when the command is given no other choice


@dataclass(frozen=True)
class Trained:
    """A trained model, one summary line for stderr, and its training curve as a metrics table."""

    model: Model
    summary: str
    curve: pa.Table
    loss: str  # what the curve's loss is, for its plot


def train_model(frames: pa.Table, name: str, hyperparameters: dict, *, val_trials: str | None = None,
                val_fraction=None, val_where=None, per=None, seed=0, label="material", progress=None,
                contacts: bool = False) -> Trained:
    """Train model `name` with `hyperparameters` (None: the model's default). Validation trials:
    `val_trials` (comma-separated ids), `val_where` (LABEL=VALUE) or `val_fraction` per `per` value,
    DEFAULT_VAL_FRACTION when none is given. `contacts`: a force model trained on the contacts the
    event-driven detector finds, to run on unbounded streams (model.session)."""
    if val_trials is None and val_where is None and val_fraction is None:
        val_fraction = DEFAULT_VAL_FRACTION
    trials = [t.strip() for t in val_trials.split(",") if t.strip()] if val_trials else None
    if contacts and name in MATERIAL_MODELS:
        raise UsageError("--contacts trains force models; a material classifier takes whole trials")
    if contacts:
        from neurotac_cli.model import session

        fit = session.train
    else:
        fit = train
    model = fit(frames, make_spec(name, **hyperparameters), val_trials=trials, val_fraction=val_fraction,
                  val_where=val_where, per=per, seed=seed, progress=progress, label=label)
    curve = model.training.get("curve", [])
    best = best_epoch(curve)
    summary = ""
    held_out = "" if not best else f", validation {best['val_loss']:.4g}" if best["val_loss"] == best["val_loss"] else "; no validation trials"
    if best and not getattr(model.net, "trained_by_gradient", True):  # fitted in closed form: no epochs to speak of
        summary = f"{name}: fitted in closed form (train {best['train_loss']:.4g}{held_out})"
    elif best and getattr(model.config, "head", None) == "lda":  # the discriminant is closed-form; epochs fit its temperature only
        summary = (f"{name}: discriminant fitted in closed form, the scale of its probabilities in {len(curve)} epochs "
                   f"(train {best['train_loss']:.4g}{held_out})")
    elif best and best["val_loss"] == best["val_loss"]:
        summary = (f"{name}: {len(curve)} epochs, best epoch {best['epoch']} (train {best['train_loss']:.4g}, "
                   f"validation {best['val_loss']:.4g})")
    elif best:  # no validation trials (a NaN validation loss): the epoch was chosen by its training loss
        summary = f"{name}: {len(curve)} epochs, best epoch {best['epoch']} by its training loss {best['train_loss']:.4g} (no validation trials)"
    if "member_best_epochs" in model.training:  # the summary's epochs are the first member's
        epochs = ", ".join(map(str, model.training["member_best_epochs"]))
        summary += f"; {len(model.training['member_best_epochs'])} members, best epochs {epochs} (the epochs above are the first's)"
    loss = "cross-entropy" if model.task == "material" else "MSE of force / training max (dimensionless)"
    return Trained(model, summary, curve_table(model.training, name), loss)


def curve_table(training: dict, name: str) -> pa.Table:
    """The training curve as a metrics table: scope epoch:N; with several members, one block of rows
    per member, named in the model column ("deform-gru member 2/3")."""
    tables = [metrics_table([(f"epoch:{row['epoch']}", key, row[key]) for row in curve for key in ("train_loss", "val_loss")],
                            f"{name} {member}".strip())
              for member, curve in member_curves(training).items()]
    return pa.concat_tables(tables)
