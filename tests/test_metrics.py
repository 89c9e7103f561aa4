import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from neurotac_cli import metrics


def naive_dtw(a, b):
    n, m = len(a), len(b)
    total = np.full((n + 1, m + 1), np.inf)
    total[0, 0] = 0
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            total[i, j] = abs(a[i - 1] - b[j - 1]) + min(total[i - 1, j - 1], total[i - 1, j], total[i, j - 1])
    return total[n, m]


series = st.lists(st.floats(-5, 5, allow_nan=False), min_size=1, max_size=12)


@settings(max_examples=60, deadline=None)
@given(series, series)
def test_dtw_equals_the_textbook_recurrence(a, b):
    assert np.isclose(metrics.dtw_distance(a, b), naive_dtw(a, b))


@settings(max_examples=40, deadline=None)
@given(series, st.integers(0, 3))
def test_dtw_of_a_stretched_copy_is_zero(a, repeat):
    stretched = np.repeat(a, repeat + 1)
    assert metrics.dtw_distance(a, stretched) == 0


def test_bhattacharyya_zero_for_same_and_symmetric():
    rng = np.random.default_rng(0)
    a, b = rng.normal(0, 1, 200), rng.normal(1, 2, 200)
    assert metrics.bhattacharyya(a, a) == 0
    assert np.isclose(metrics.bhattacharyya(a, b), metrics.bhattacharyya(b, a))
    # two unit normals one sigma apart: D_B = 1/8
    assert np.isclose(metrics.bhattacharyya(np.array([-1.0, 1.0]), np.array([0.0, 2.0])), 0.125)


def test_regression_figures():
    true = np.array([0.0, 1.0, 2.0, 3.0])
    pred = np.array([0.0, 1.0, 2.0, 5.0])
    figures = metrics.regression(true, pred)
    assert figures["mse"] == 1.0 and figures["rmse"] == 1.0 and figures["mae"] == 0.5
    assert np.isclose(figures["rmse_pct_range"], 100 / 3)
    assert np.isclose(figures["r2"], 1 - 4 / 5)
    assert np.isclose(figures["mse_sd"], np.std([0, 0, 0, 4.0]))


def test_phases_nonzero_and_trials():
    trial = ["a"] * 4 + ["b"] * 4
    phase = ["grasping", "grasping", "holding", "releasing"] * 2
    true = np.array([0, 1, 2, 0, 0, 1, 3, 0], dtype=float)
    pred = true + 0.5
    rows = metrics.force_rows(trial, phase, true, pred, nonzero=True)
    figures = {(s, m): v for s, m, v in rows}
    assert figures[("all", "n")] == 4 and figures[("all", "mae")] == 0.5
    assert ("phase:releasing", "mse") not in figures  # all zero force there
    assert figures[("trial:b", "n")] == 2


def test_confusion_and_recall():
    rows = metrics.classification_rows(["a", "a", "b", "b"], ["a", "b", "b", "b"], ["a", "b"])
    figures = {(s, m): v for s, m, v in rows}
    assert figures[("all", "accuracy")] == 0.75
    assert figures[("class:a", "recall")] == 0.5 and figures[("class:b", "recall")] == 1.0
    assert figures[("confusion:a", "pred:b")] == 1
    assert (metrics.confusion(["a", "b"], ["b", "b"], ["a", "b"]) == [[0, 1], [0, 1]]).all()


def test_repeated_predictions_of_a_trial_are_separate_series():
    """--repeats R predicts each trial R times: per-phase DTW and D_B average over the R series, they
    are not computed on the R copies strung together (which made DTW grow with R)."""
    true = np.array([0.0, 1.0, 2.0, 2.0, 1.0])
    pred = np.array([0.0, 0.5, 2.5, 1.5, 1.0])
    once = dict(((s, m), v) for s, m, v in metrics.force_rows(["a"] * 5, ["holding"] * 5, true, pred))
    trial, phase = ["a"] * 15, ["holding"] * 15
    thrice = metrics.force_rows(trial, phase, np.tile(true, 3), np.tile(pred, 3), series=[r for r in range(3) for _ in range(5)])
    thrice = dict(((s, m), v) for s, m, v in thrice)
    for metric in ("dtw", "bhattacharyya", "mse"):
        assert np.isclose(thrice[("phase:holding", metric)], once[("phase:holding", metric)]), metric
    strung = dict(((s, m), v) for s, m, v in metrics.force_rows(trial, phase, np.tile(true, 3), np.tile(pred, 3)))
    assert strung[("phase:holding", "dtw")] > 2 * once[("phase:holding", "dtw")]


def test_a_phase_whose_distances_are_all_undefined_gives_nan_without_a_numpy_warning():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rows = metrics.force_rows(["a"] * 3, ["holding"] * 3, [1.0, 2.0, 3.0], [np.nan] * 3)
    assert np.isnan(dict(((s, m), v) for s, m, v in rows)[("phase:holding", "dtw")])


def test_recall_over_folds_counts_a_fold_whose_model_never_learnt_the_class():
    """A fold whose model never trained on class c reads its c trials as something else: recall 0
    there, so c's mean recall over folds is 0.5, not the 1.0 of the one fold that knew it."""
    import pyarrow as pa

    from neurotac_cli import schema as sch
    from neurotac_cli.model.scoring import score_folds

    def fold(trials, true, pred, classes):
        columns = {"trial": pa.array(trials), "material": pa.array(true), "material_pred": pa.array(pred)}
        columns.update({f"prob_{c}": pa.array([float(p == c) for p in pred], pa.float32()) for c in classes})
        table = pa.table(columns)
        return table.replace_schema_metadata(sch.set_meta(table.schema, kind="predictions").metadata), {}

    results = [fold(["t1", "t2"], ["a", "c"], ["a", "a"], ["a", "b"]), fold(["t3", "t4"], ["c", "b"], ["c", "b"], ["a", "b", "c"])]
    figures = {(s, m): v for s, m, v in score_folds(results, 2)[1]}
    assert figures[("class:c", "recall")] == 0.5
    assert figures[("class:c", "recall_fold_mean")] == 0.5
    rows = metrics.classification_rows(["a", "c"], ["a", "a"], ["a", "b"])
    assert dict(((s, m), v) for s, m, v in rows)[("class:c", "recall")] == 0.0


def test_a_sessions_grasps_are_separate_series_for_dtw_and_bhattacharyya():
    """A session is one trial of many grasps: each grasp's phase is a series of its own, as each
    grasp is when cut into trials, not the holds of every grasp strung together."""
    import pyarrow as pa

    from neurotac_cli.model.scoring import score

    true = np.array([0.0, 1.0, 2.0, 2.0, 0.0, 0.0, 3.0, 4.0, 4.0, 0.0])
    pred = np.array([0.0, 1.5, 2.5, 1.5, 0.0, 0.0, 3.0, 4.5, 3.5, 0.0])
    phase = [None, "holding", "holding", "holding", None] * 2
    grasp = [-1, 0, 0, 0, -1, -1, 1, 1, 1, -1]
    table = pa.table({"trial": ["s"] * 10, "frame": pa.array(range(10), pa.int32()), "phase": phase,
                      "force": pa.array(true, pa.float32()), "force_pred": pa.array(pred, pa.float32()),
                      "grasp": pa.array(grasp, pa.int32())})
    figures = {(s, m): v for s, m, v in score(table)}
    grasps = [slice(1, 4), slice(6, 9)]
    assert np.isclose(figures[("phase:holding", "dtw")], np.mean([naive_dtw(true[g], pred[g]) for g in grasps]))
    assert np.isclose(figures[("phase:holding", "bhattacharyya")], np.mean([metrics.bhattacharyya(true[g], pred[g]) for g in grasps]))


def test_a_count_that_only_some_folds_report_is_averaged_over_every_fold():
    """`unknown_class` (like `unforced_frames`) is written only where it is not 0: its mean over two
    folds, one with a trial of an unknown class, is 0.5, not 1."""
    rows = [[("all", "accuracy", 0.5), ("all", "unknown_class", 1.0)], [("all", "accuracy", 1.0)]]
    figures = {(s, m): v for s, m, v in metrics.fold_summary(rows)}
    assert figures[("all", "unknown_class_fold_mean")] == 0.5 and figures[("all", "accuracy_fold_mean")] == 0.75
