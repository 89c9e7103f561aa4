"""A training curve (one dict per epoch, as `fit` writes it), read without torch (`info` of a model)."""


def best_epoch(curve: list) -> dict | None:
    """The curve's row with the lowest loss early stopping watched (validation, or training without
    validation): the epoch whose weights `fit` restored. None for an empty curve."""
    if not curve:
        return None
    return min(curve, key=lambda row: row["val_loss"] if row["val_loss"] == row["val_loss"] else row["train_loss"])


def member_curves(training: dict) -> dict:
    """Each member's training curve by its label ("member 2/3"); {"": curve} for a model of one network."""
    curves = training.get("member_curves") or [training.get("curve") or []]
    if len(curves) == 1:
        return {"": curves[0]}
    return {f"member {i + 1}/{len(curves)}": curve for i, curve in enumerate(curves)}
