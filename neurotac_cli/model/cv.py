"""Cross-validation: folds over source trials, one training per fold (and per repeat seed).

Folds hold whole source groups: a test trial's augmented copies never train its fold's model, and
only original trials are scored. Each fold is one task of `neurotac_cli.study.run_tasks`, so folds
and repeats run in parallel or on a Dask cluster, and cached folds are not run again.
"""

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from neurotac_cli.schema import check_force_range
from neurotac_cli.errors import ModelError, UsageError
from neurotac_cli.units import counted, first_few
from neurotac_cli.model.data import Sequences
from neurotac_cli.model.curve import best_epoch, member_curves


def _group(cv: str) -> tuple[str, str]:
    """The label and the value (empty: every value) of `group:LABEL[=VALUE]`."""
    label, equals, value = cv.partition(":")[2].partition("=")
    if equals and not value:
        raise UsageError(f"--cv {cv}: give the value to hold out after '=' (group:{label}=VALUE), or leave '=' out to hold out each value in turn")
    return label, value


def folds(data: Sequences, cv: str, rng: np.random.Generator) -> list:
    """Test trials (originals only) of each fold for `loo`, `kfold:K`, `group:LABEL` or `group:LABEL=VALUE`.
    k-folds are drawn over the source trials without regard to a classifier's classes: the published
    tables were made so (a fold that holds every trial of a class is named by `unseen_classes_note`)."""
    originals = [i for i in range(len(data)) if not data.augmented[i]]
    if not originals:
        raise ModelError("no original (non-augmented) trials to test on; keep the originals beside the augmented copies")
    sources = [data.source[i] for i in originals]
    kind, _, argument = cv.partition(":")
    if kind == "loo":
        groups = [[data.trials[i]] for i in originals]
    elif kind == "kfold":
        try:
            k = int(argument)
        except ValueError:
            raise UsageError(f"--cv kfold:K needs a whole number K, got {argument!r}") from None
        unique = sorted(set(sources))
        if not 2 <= k <= len(unique):
            raise (UsageError if k < 2 else ModelError)(f"--cv kfold:{k} needs 2 <= K <= {len(unique)} (the number of source trials)")
        order = rng.permutation(len(unique))
        fold_of = {unique[j]: n % k for n, j in enumerate(order)}
        groups = [[data.trials[i] for i, s in zip(originals, sources) if fold_of[s] == f] for f in range(k)]
    elif kind == "group":
        label, value = _group(cv)
        if label not in data.labels:
            raise ModelError(f"--cv group:{label}: no label column {label!r} (labels: {', '.join(data.labels) or 'none'})")
        values = [data.labels[label][i] for i in originals]
        unlabelled = [data.trials[i] for i, v in zip(originals, values) if v in (None, "")]
        if unlabelled and not value:
            raise ModelError(f"--cv group:{label}: {counted(len(unlabelled), 'trial')} with no {label} value ({first_few(unlabelled)})"
                             f" would be tested in no fold; label them, or leave them "
                             f"out with `neurotac select --where \"{label} <> ''\"`")
        wanted = [value] if value else sorted({v for v in values if v is not None})
        if value and value not in values:
            raise ModelError(f"--cv group:{label}={value}: no trial has {label}={value} (values: {', '.join(sorted(set(map(str, values))))})")
        groups = [[data.trials[i] for i, v in zip(originals, values) if v == w] for w in wanted]
    else:
        raise UsageError(f"--cv must be loo, kfold:K, group:LABEL or group:LABEL=VALUE, got {cv!r}")
    return [g for g in groups if g]


def unseen_classes_note(results: list, label: str) -> str | None:
    """A warning for trials scored by a fold's classifier that never trained on their class (results
    of `run_fold`; a class's probability columns are those the model knows)."""
    unseen = {}
    for predictions, _ in results:
        names = predictions.schema.names
        if label not in names or f"{label}_pred" not in names:
            continue
        known = {n[len("prob_"):] for n in names if n.startswith("prob_")}
        for trial, value in zip(predictions.column("trial").to_pylist(), predictions.column(label).to_pylist()):
            if value is not None and value not in known:
                unseen.setdefault(value, []).append(trial)
    if not unseen:
        return None
    trials = list(dict.fromkeys(t for group in unseen.values() for t in group))  # a trial once, however many repeats
    return (f"warning: {counted(len(trials), 'trial')} ({first_few(trials)}) scored by a fold whose model never trained on "
            f"their {label} ({first_few(sorted(unseen))}): each is scored wrong; use fewer folds or more trials of that {label}")


def _sources(table: pa.Table) -> pa.Array:
    trial = table.column("trial")
    if "source_trial" not in table.schema.names:
        return trial
    source = table.column("source_trial")
    return pc.if_else(pc.or_(pc.is_null(source), pc.equal(source, "")), trial, source)


def run_fold(frames: pa.Table, spec: dict, test_trials: list, seed: int, val_fraction: float, per: str | None,
             label: str = "material"):
    """Train on every trial outside the fold's source groups, predict the fold's test trials.

    Module-level and picklable (a task of `run_tasks`). Returns (predictions table, validation):
    `validation` is what the fold's early stopping saw, scored with the weights it restored (see
    `validation_figures`).
    """
    from neurotac_cli import model as models

    test_set = pa.array(test_trials, pa.string())
    is_test = pc.is_in(frames.column("trial"), value_set=test_set)
    sources = _sources(frames)
    test_sources = pa.array(sorted(set(sources.filter(is_test).to_pylist())), pa.string())
    train_table = frames.filter(pc.invert(pc.is_in(sources, value_set=test_sources)))
    test_table = frames.filter(is_test)
    if train_table.num_rows == 0:
        raise ModelError("a fold leaves no training trials; use more folds or a different --cv")
    model = models.train(train_table, spec, val_fraction=val_fraction, per=per, seed=seed, label=label)
    if model.task == "material":
        return models.classify_table(model, test_table), validation_figures(model, train_table)
    return models.predict_table(model, test_table), validation_figures(model, train_table)


def validation_figures(model, train_table: pa.Table) -> dict:
    """The fold's validation score: its early-stopping trials predicted by the trained model, i.e. at
    the restored best epoch. Force models: `val_mse` (N², every frame with a measured force, as the
    early stopping watched it: with deform-gru's members, each member's own estimate on its own draw,
    pooled); classifiers: `val_accuracy`; NaN without validation trials. Also
    `epochs` trained and `best_epoch`, from the training curve (the GP's one-row curve: 1 and 0);
    with deform-gru's members, the mean over the members' curves, since each stopped on its own draw.
    Thesis Tables 3.1 and 3.3, Fig. 4.4(a)."""
    from neurotac_cli import metrics
    from neurotac_cli import model as models

    curves = [curve for curve in member_curves(model.training).values() if curve]
    bests = [best["epoch"] for best in map(best_epoch, curves) if best]
    figures = {
        "epochs": float(np.mean([len(curve) for curve in curves])) if curves else float("nan"),
        "best_epoch": float(np.mean(bests)) if bests else float("nan"),
    }
    trials = model.training.get("trials", {}).get("validation") or []
    name = "val_accuracy" if model.task == "material" else "val_mse"
    if not trials:
        return {name: float("nan"), **figures}

    def held(draw):
        return train_table.filter(pc.is_in(train_table.column("trial"), value_set=pa.array(draw, pa.string())))

    if model.task == "material":
        predicted = models.classify_table(model, held(trials))
        label = model.training.get("label", "material")
        true, guess = predicted.column(label).to_pylist(), predicted.column(f"{label}_pred").to_pylist()
        return {name: float(np.mean([a == b for a, b in zip(true, guess)])), **figures}
    # each member of a model of several alone on its own draw: the others trained on those trials
    truth, estimate = [], []
    for member, draw in model.members():
        predicted = models.predict_table(member, held(draw))
        truth.append(predicted.column("force").to_numpy(zero_copy_only=False))
        estimate.append(predicted.column("force_pred").to_numpy(zero_copy_only=False))
    scores = metrics.regression(np.concatenate(truth), np.concatenate(estimate))
    return {name: scores.get("mse", float("nan")), **figures}


def fold_tasks(data: Sequences, spec: dict, cv: str, repeats: int, seed: int, val_fraction: float,
               per: str | None, label: str = "material"):
    """The (fold, repeat) tasks: fold assignment drawn once from `seed`; each repeat trains with its own seed."""
    from neurotac_cli.model.core import MATERIAL_MODELS, resolved_spec

    if spec["model"] in MATERIAL_MODELS and cv.startswith("group:") and _group(cv)[0] == label:
        raise UsageError(f"--cv {cv} holds out every trial of a {label} class from its training, so no test trial's class "
                         f"could be named; group by another label (e.g. group:object), or use kfold:K")
    if spec["model"] not in MATERIAL_MODELS:  # a held-out trial is scored, never trained on: its force is checked here
        check_force_range(np.concatenate(data.force), "the frames cross-validated")
    rng = np.random.default_rng(seed)
    groups = folds(data, cv, rng)
    spec = resolved_spec(spec)
    tasks = []
    for repeat in range(repeats):
        for fold, test_trials in enumerate(groups):
            tasks.append({
                "spec": spec, "test_trials": test_trials, "seed": int(seed * 100003 + repeat * 1009 + fold),
                "val_fraction": val_fraction, "per": per, "label": label,
            })
    return groups, tasks
