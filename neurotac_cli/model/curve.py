"""A training curve (one dict per epoch, as `fit` writes it), read without torch (`info` of a model)."""


def best_epoch(curve: list) -> dict | None:
    """The curve's row with the lowest loss early stopping watched (validation, or training without
    validation): the epoch whose weights `fit` restored. None for an empty curve."""
    if not curve:
        return None
    return min(curve, key=lambda row: row["val_loss"] if row["val_loss"] == row["val_loss"] else row["train_loss"])
