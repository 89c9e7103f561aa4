"""A training curve (one dict per epoch, as `fit` writes it), read without torch (`info` of a model)."""

import math


IMPROVEMENT = 1e-9  # a watched loss must fall by more than this to count as better (`fit`'s rule)


def best_epoch(curve: list) -> dict | None:
    """The curve's row whose weights `fit` restored: the first lowest loss early stopping watched
    (validation, or training without validation), by `fit`'s own rule. None for an empty curve."""
    best, kept = math.inf, None
    for row in curve:
        if watched(row) < best - IMPROVEMENT:
            best, kept = watched(row), row
    return kept


def watched(row: dict) -> float:
    """The loss early stopping watched in an epoch's row: validation, or training without validation."""
    return row["val_loss"] if math.isfinite(row["val_loss"]) else row["train_loss"]


def member_curves(training: dict) -> dict:
    """Each member's training curve by its label ("member 2/3"); {"": curve} for a model of one network."""
    curves = training.get("member_curves") or [training.get("curve") or []]
    if len(curves) == 1:
        return {"": curves[0]}
    return {f"member {i + 1}/{len(curves)}": curve for i, curve in enumerate(curves)}
