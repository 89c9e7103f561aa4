"""neurotac_cli.ops.augment: the invariants of thesis 5.3, as property tests."""

import numpy as np
import pyarrow as pa
import pytest
from hypothesis import example, given, settings, strategies as st

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, SchemaError
from neurotac_cli.ops import augment as aug

SETTINGS = settings(max_examples=25, deadline=None)
seeds = st.integers(0, 2**32 - 1)


def random_counts(seed, frames=8, height=12, width=10, scale=3.0, dtype=np.uint16):
    """A blob of events that grows then fades, like a grasp, on a (frames, 2, H, W) grid."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width]
    cy, cx = rng.uniform(0.3, 0.7) * height, rng.uniform(0.3, 0.7) * width
    blob = np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / (0.1 * height * width))
    level = scale * np.sin(np.linspace(0.2, 3.0, frames))
    rates = level[:, None, None, None] * blob[None, None] * np.array([1.0, 0.6])[None, :, None, None]
    return rng.poisson(rates).astype(dtype)


def make_frames(trials=3, frames=8, height=12, width=10, seed=0, dtype=np.uint16, window_us=10_000, shuffle=False):
    """A frames table as `neurotac frame | neurotac crop` writes it, with labels, force and phase."""
    rows = {"trial": [], "frame": [], "t": [], "force": [], "phase": [], "material": [], "size_mm": []}
    counts = []
    for index in range(trials):
        counts.append(random_counts(seed * 100 + index, frames, height, width, dtype=dtype))
        for frame in range(frames):
            rows["trial"].append(f"bolt{index}")
            rows["frame"].append(frame)
            rows["t"].append(frame * window_us)
            rows["force"].append(float(np.sin(frame / frames * np.pi) * (index + 1)))
            rows["phase"].append("grasping" if frame < 2 else "releasing" if frame >= frames - 2 else "holding")
            rows["material"].append("steel")
            rows["size_mm"].append(str(12 + 3 * index))
    counts = np.concatenate(counts)
    order = np.random.default_rng(seed).permutation(len(counts)) if shuffle else np.arange(len(counts))
    schema = sch.frames_schema(height, width, labels=("material", "size_mm"), dtype=dtype, window_us=window_us)
    columns = {name: [values[i] for i in order] for name, values in rows.items()}
    columns["counts"] = sch.counts_array(counts[order])
    return pa.Table.from_pydict(
        {name: columns[name] for name in schema.names},
        schema=schema,
    )


def trial_counts(table, trial):
    """The counts of one trial in frame order."""
    rows = [i for i, name in enumerate(table["trial"].to_pylist()) if name == trial]
    frames = table["frame"].to_numpy()[rows]
    return sch.counts_numpy(table["counts"])[np.array(rows)[np.argsort(frames)]]


def copies_of(table, source):
    names = table["trial"].to_pylist()
    sources = table["source_trial"].to_pylist()
    return sorted({n for n, s in zip(names, sources) if s == source and n != source})


# ---------------------------------------------------------------- identities


@SETTINGS
@given(seed=seeds, turns=st.integers(-2, 2))
def test_rotation_by_whole_turns_and_resize_by_one_are_the_identity(seed, turns):
    counts = random_counts(seed)
    rng = np.random.default_rng(seed)
    assert np.array_equal(aug.Rotate(360.0 * turns)(counts, rng)[0], counts)
    assert np.array_equal(aug.Resize(1.0)(counts, rng)[0], counts)
    assert np.array_equal(aug.Resize(1.0, preserve_total=True)(counts, rng)[0], counts)


def test_identity_through_the_warp_itself_is_exact():
    """Not only the short cut: the sampling operator of the identity copies integer counts exactly."""
    counts = random_counts(5)
    result, lost, gained = aug.warp(counts, np.eye(2), np.random.default_rng(0))
    assert np.array_equal(result, counts) and lost == gained == 0


def test_augment_frames_with_identity_methods_copies_every_trial_unchanged():
    table = make_frames()
    out, _ = aug.augment_frames(table, [aug.Rotate(0.0), aug.Resize(1.0)], copies=2)
    for trial in ("bolt0", "bolt1", "bolt2"):
        for copy in copies_of(out, trial):
            assert np.array_equal(trial_counts(out, copy), trial_counts(table, trial))


# ---------------------------------------------------------------- rotation and resize


def test_rotation_samples_like_scipy_bilinear_with_zero_outside():
    from scipy import ndimage

    counts = random_counts(3, frames=4, height=15, width=13).astype(np.float32)
    centre = aug.contact_centre(counts)
    angle = 27.0
    result, _, _ = aug.warp(counts, aug.rotation_matrix(angle), np.random.default_rng(0))
    matrix = aug.rotation_matrix(angle)
    yy, xx = np.mgrid[0:15, 0:13].astype(float)
    sy = centre[0] + matrix[0, 0] * (yy - centre[0]) + matrix[0, 1] * (xx - centre[1])
    sx = centre[1] + matrix[1, 0] * (yy - centre[0]) + matrix[1, 1] * (xx - centre[1])
    for frame in range(4):
        for channel in range(2):
            expected = ndimage.map_coordinates(counts[frame, channel].astype(float), [sy, sx], order=1, mode="grid-constant", cval=0)
            np.testing.assert_allclose(result[frame, channel], expected, atol=1e-4)


def test_positive_angle_turns_the_picture_clockwise_on_screen():
    counts = np.zeros((1, 2, 21, 21), np.uint16)
    counts[0, :, 10, 10] = 50  # keeps the contact centre on the middle pixel
    counts[0, 1, 5, 10] = 1  # a single event above the centre
    result, _, _ = aug.Rotate(90.0)(counts, np.random.default_rng(0))
    assert result[0, 1, 10, 15] == 1 and result[0, 1, 5, 10] == 0  # now right of the centre


def test_resize_scales_about_the_contact_centre_with_zero_margin():
    counts = np.zeros((1, 2, 31, 31), np.uint16)
    counts[0, :, 12:19, 12:19] = 4  # a 7x7 square around (15, 15)
    bigger, _, _ = aug.Resize(2.0)(counts, np.random.default_rng(0))
    smaller, _, _ = aug.Resize(0.5)(counts, np.random.default_rng(0))
    assert aug.contact_centre(bigger) == pytest.approx((15, 15), abs=0.3)
    assert np.count_nonzero(bigger[0, 0]) > 3 * np.count_nonzero(counts[0, 0])
    assert np.count_nonzero(smaller[0, 0]) < np.count_nonzero(counts[0, 0])
    assert bigger[0, :, :5].sum() == 0 and bigger[0, :, :, -5:].sum() == 0


@pytest.mark.parametrize("method, label", [(aug.Resize(1e-9), "resize(1e-09)"), (aug.Resize(0.8333), "resize(0.83)"),
                                           (aug.Rotate(0.001), "rotate(0.001)"), (aug.EventShift(-2, 0.004), "tes(-2,0.004)")])
def test_copies_are_named_by_a_figure_that_tells_them_from_no_change(method, label):
    counts = np.zeros((3, 2, 9, 9), np.uint16)
    counts[1, :, 3:6, 3:6] = 2
    assert method(counts, np.random.default_rng(0))[1] == label


@SETTINGS
@given(seed=seeds, beta=st.sampled_from([0.83, 1.25, 0.5, 1.7]), angle=st.floats(-90, 90))
@example(seed=300000, beta=1.7, angle=0.0)  # a frame whose two OFF events are all scaled past the edge
def test_preserve_total_keeps_every_frame_and_channel_count_that_stays_in_the_frame(seed, beta, angle):
    counts = random_counts(seed)
    rng = np.random.default_rng(seed)
    for method in (aug.Resize(beta, preserve_total=True), aug.Rotate(angle, preserve_total=True)):
        result, _, counted = method(counts, rng)
        assert result.dtype == np.uint16
        after, before = result.sum(axis=(2, 3)), counts.sum(axis=(2, 3))
        # A frame and channel whose every event left the frame has nothing to rescale: those are counted lost.
        emptied = (after == 0) & (before > 0)
        assert np.array_equal(after[~emptied], before[~emptied])
        assert counted.get("events_lost", 0) == before[emptied].sum() and not counted.get("events_added")


@SETTINGS
@given(seed=seeds)
def test_systematic_rounding_is_floor_or_ceil_and_hits_given_totals(seed):
    rng = np.random.default_rng(seed)
    values = rng.gamma(0.5, 2.0, size=(6, 40))
    totals = np.rint(values.sum(axis=1) * rng.uniform(0.5, 1.5, 6))
    scaled = values * (totals / values.sum(axis=1))[:, None]
    rounded = aug.systematic_round(scaled, rng, totals)
    assert np.all((rounded == np.floor(scaled)) | (rounded == np.ceil(scaled)) | np.isclose(rounded, scaled))
    assert np.array_equal(rounded.sum(axis=1), totals)
    free = aug.systematic_round(values, rng)
    assert np.all(np.abs(free.sum(axis=1) - values.sum(axis=1)) < 1)


def test_systematic_rounding_is_unbiased():
    rng = np.random.default_rng(1)
    values = np.full((20000, 3), [0.25, 0.5, 0.1])
    mean = aug.systematic_round(values, rng).mean(axis=0)
    np.testing.assert_allclose(mean, [0.25, 0.5, 0.1], atol=0.015)


def test_float_counts_stay_float_and_unrounded():
    counts = random_counts(2).astype(np.float32) * 0.5
    result, _, _ = aug.Resize(1.25)(counts, np.random.default_rng(0))
    assert result.dtype == np.float32 and not np.array_equal(result, np.round(result))


# ---------------------------------------------------------------- frame shifting


@SETTINGS
@given(seed=seeds, shift=st.integers(-10, 10))
def test_frame_shift_is_an_exact_shift_with_zero_fill(seed, shift):
    counts = random_counts(seed)
    frames = len(counts)
    shifted = aug.FrameShift(shift)(counts, None)[0]
    for t in range(frames):
        source = t - shift
        expected = counts[source] if 0 <= source < frames else np.zeros_like(counts[0])
        assert np.array_equal(shifted[t], expected)


# ---------------------------------------------------------------- temporal event shifting


@SETTINGS
@given(seed=seeds, shift=st.integers(-4, 4), zeta=st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0]))
def test_tes_conserves_events_inside_the_sequence_and_moves_round_zeta_n(seed, shift, zeta):
    counts = random_counts(seed, scale=6.0)
    result, moved, lost = aug.temporal_event_shift(counts, shift, zeta, np.random.default_rng(seed))
    take = np.array([[round(zeta * int(n)) for n in frame] for frame in counts.sum(axis=(2, 3))])
    assert moved == take.sum()
    inside = [t for t in range(len(counts)) if not 0 <= t + shift < len(counts)]
    assert lost == sum(take[t].sum() for t in inside)
    assert int(result.sum()) == int(counts.sum()) - lost
    # replay the same draw: X' = X - Z + Z shifted, Z <= X, exactly round(zeta n) per frame and channel
    flat = counts.astype(np.int64).reshape(len(counts) * 2, -1)
    drawn = aug.draw_events(flat, take.ravel(), np.random.default_rng(seed)).reshape(counts.shape)
    assert np.all(drawn <= counts) and np.array_equal(drawn.sum(axis=(2, 3)), take)
    assert np.array_equal(result.astype(np.int64), counts - drawn + aug.frame_shift(drawn, shift))


@SETTINGS
@given(seed=seeds, shift=st.sampled_from([-3, -2, -1, 1, 2, 3]), zeta=st.sampled_from([0.25, 0.5, 0.75]))
def test_tes_of_a_single_frame_moves_exactly_its_share_to_the_same_pixels(seed, shift, zeta):
    counts = np.zeros((10, 2, 6, 7), np.uint16)
    counts[5] = random_counts(seed, frames=1, height=6, width=7, scale=8.0)[0]
    result, _, lost = aug.temporal_event_shift(counts, shift, zeta, np.random.default_rng(seed))
    assert lost == 0
    for channel in range(2):
        n = int(counts[5, channel].sum())
        arrived = result[5 + shift, channel].astype(int)
        stayed = result[5, channel].astype(int)
        assert arrived.sum() == round(zeta * n) and stayed.sum() == n - round(zeta * n)
        assert np.array_equal(arrived + stayed, counts[5, channel])
    others = [t for t in range(10) if t not in (5, 5 + shift)]
    assert result[others].sum() == 0


def test_tes_draws_each_event_with_equal_probability():
    counts = np.array([[1, 2, 3, 4, 0, 10]], dtype=np.int64)
    rng = np.random.default_rng(7)
    total = sum(aug.draw_events(counts, np.array([5]), rng) for _ in range(4000))
    np.testing.assert_allclose(total[0] / 4000, counts[0] * 5 / 20, atol=0.1)


def test_tes_of_more_events_than_one_array_holds_draws_group_by_group_with_the_same_law(monkeypatch):
    """A trial of billions of events (a block of saturated pixels) would need tens of GB as one array."""
    counts = np.array([[1, 2, 3, 4, 0, 10], [0, 0, 7, 0, 1, 0]], dtype=np.int64)
    monkeypatch.setattr(aug, "DRAW_AT_ONCE", 5)
    rng = np.random.default_rng(7)
    draws = [aug.draw_events(counts, np.array([5, 3]), rng) for _ in range(4000)]
    assert all(np.all(d <= counts) and d.sum(axis=1).tolist() == [5, 3] for d in draws)
    np.testing.assert_allclose(sum(draws)[0] / 4000, counts[0] * 5 / 20, atol=0.1)
    huge = np.full((2, 400), 60_000, np.int64)  # 48 million events: drawn without an array of them
    monkeypatch.setattr(aug, "DRAW_AT_ONCE", 1 << 25)
    assert aug.draw_events(huge, np.array([1000, 0]), rng).sum(axis=1).tolist() == [1000, 0]
    saturated = np.full((1, 2 * 180 * 240), 65535, np.int64)  # 2.8e9 events in one group: past an exact draw
    with pytest.raises(NeurotacError, match="beyond the 1,000,000,000 TES draws from exactly"):
        aug.draw_events(saturated, np.array([10]), rng)


def test_tes_rounds_halves_like_python_round():
    counts = np.zeros((2, 2, 1, 5), np.uint16)
    counts[0, 0, 0, :3] = 1  # 3 events: 1.5 -> 2
    counts[0, 1, 0, :5] = 1  # 5 events: 2.5 -> 2
    assert aug.events_to_move(counts, 0.5)[0].tolist() == [2, 2]


def test_tes_refuses_fractional_counts():
    counts = random_counts(1).astype(np.float32) / 3
    with pytest.raises(SchemaError, match="whole-number"):
        aug.temporal_event_shift(counts, 1, 0.5, np.random.default_rng(0))


# ---------------------------------------------------------------- noise


@SETTINGS
@given(seed=seeds)
def test_noise_adds_exactly_a_stretch_of_the_noise_frames(seed):
    counts = random_counts(seed)
    pool = [random_counts(seed + 1, frames=5, scale=1.0), random_counts(seed + 2, frames=13, scale=1.0)]
    result, added, (which, start) = aug.add_noise(counts, pool, np.random.default_rng(seed))
    source = pool[which]
    expected = source[(start + np.arange(len(counts))) % len(source)]
    assert np.array_equal(result.astype(np.int64) - counts, expected)
    assert added == expected.sum()


def test_noise_table_must_match_window_and_frame_size():
    table = make_frames()
    with pytest.raises(SchemaError, match="12x10|10x12"):
        aug.noise_pool(make_frames(height=10, width=12), table.schema)
    with pytest.raises(SchemaError, match="window"):
        aug.noise_pool(make_frames(window_us=7000), table.schema)
    pool = aug.noise_pool(make_frames(trials=2, frames=4, shuffle=True), table.schema)
    assert [len(trial) for trial in pool] == [4, 4]


def test_noise_through_augment_frames_adds_only_noise():
    table = make_frames()
    noise = make_frames(trials=1, frames=20, seed=9)
    out, counted = aug.augment_frames(table, [aug.Noise(tuple(aug.noise_pool(noise, table.schema)))], copies=2, seed=3)
    pool = trial_counts(noise, "bolt0").astype(np.int64)
    for trial in ("bolt0", "bolt1"):
        for copy in copies_of(out, trial):
            difference = trial_counts(out, copy).astype(np.int64) - trial_counts(table, trial)
            starts = [s for s in range(20) if np.array_equal(difference, pool[(s + np.arange(8)) % 20])]
            assert starts
    assert counted["noise"]["copies"] == 6


# ---------------------------------------------------------------- tables: ids, labels, seeds


def all_methods(table):
    noise = make_frames(trials=1, frames=12, seed=4)
    return [
        aug.Rotate(0.0, 45.0),
        aug.Resize(1.25),
        aug.FrameShift(-1),
        aug.EventShift(-2, 0.5),
        aug.Noise(tuple(aug.noise_pool(noise, table.schema))),
    ]


@pytest.mark.parametrize("combine", ["independent", "hybrid"])
def test_labels_force_phase_and_times_never_move(combine):
    table = make_frames(shuffle=True)
    out, _ = aug.augment_frames(table, all_methods(table), copies=2, combine=combine, seed=1)
    original = {(r["trial"], r["frame"]): r for r in table.drop_columns(["counts"]).to_pylist()}
    for row in out.drop_columns(["counts"]).to_pylist():
        source = original[(row["source_trial"], row["frame"])]
        for name in ("t", "force", "phase", "material", "size_mm"):
            assert row[name] == source[name]
    expected_copies = 5 * 2 if combine == "independent" else 2
    assert out.num_rows == table.num_rows * (1 + expected_copies)


def test_trial_ids_are_unique_and_say_where_they_came_from():
    table = make_frames()
    out, _ = aug.augment_frames(table, [aug.FrameShift(-1), aug.EventShift(-2, 0.5)], copies=2)
    trials = out["trial"].to_pylist()
    per_trial = {}
    for name, source, done in zip(trials, out["source_trial"].to_pylist(), out["augment"].to_pylist()):
        per_trial.setdefault(name, set()).add((source, done))
    assert all(len(v) == 1 for v in per_trial.values())
    assert len(per_trial) == 3 * (1 + 4)
    assert per_trial["bolt1"] == {("bolt1", "")}
    assert per_trial["bolt1~tes(-2,0.5)#2"] == {("bolt1", "tes(-2,0.5)#2")}
    assert per_trial["bolt1~fs(-1)#1"] == {("bolt1", "fs(-1)#1")}
    assert out.schema.metadata == table.schema.metadata


def test_hybrid_composes_methods_in_one_copy_and_ids_say_so():
    table = make_frames()
    out, counted = aug.augment_frames(table, [aug.FrameShift(-1), aug.Resize(1.25)], combine="hybrid", copies=1)
    assert sorted(set(out["augment"].to_pylist())) == ["", "resize(1.25)+fs(-1)#1"]
    expected = aug.frame_shift(aug.Resize(1.25)(trial_counts(table, "bolt0"), np.random.default_rng(
        np.random.SeedSequence(0, spawn_key=aug._key("bolt0", "resize", 1, "hybrid"))))[0], -1)
    assert np.array_equal(trial_counts(out, "bolt0~resize(1.25)+fs(-1)#1"), expected)
    assert counted["fs"]["copies"] == counted["resize"]["copies"] == 3


def test_augmenting_an_augmented_table_keeps_the_first_source():
    table = make_frames(trials=1)
    once, _ = aug.augment_frames(table, [aug.FrameShift(1)])
    twice, _ = aug.augment_frames(once, [aug.EventShift(1, 0.25)], keep_original=False)
    rows = dict(zip(twice["trial"].to_pylist(), zip(twice["source_trial"].to_pylist(), twice["augment"].to_pylist())))
    assert rows["bolt0~fs(1)#1~tes(1,0.25)#1"] == ("bolt0", "fs(1)#1+tes(1,0.25)#1")
    with pytest.raises(NeurotacError, match="already taken"):
        aug.augment_frames(once, [aug.FrameShift(1)])


def test_only_augmented_drops_the_originals():
    table = make_frames()
    out, _ = aug.augment_frames(table, [aug.FrameShift(1)], copies=2, keep_original=False)
    assert "" not in out["augment"].to_pylist() and out.num_rows == 2 * table.num_rows


@SETTINGS
@given(seed=st.integers(0, 2**31))
def test_same_seed_same_copies_other_seed_other_copies(seed):
    table = make_frames(trials=2)
    methods = [aug.Rotate(0.0, 45.0), aug.EventShift(-2, 0.5)]
    first, _ = aug.augment_frames(table, methods, copies=2, seed=seed)
    again, _ = aug.augment_frames(table, methods, copies=2, seed=seed)
    other, _ = aug.augment_frames(table, methods, copies=2, seed=seed + 1)
    assert first.equals(again, check_metadata=True)
    counts, other_counts = sch.counts_numpy(first["counts"]), sch.counts_numpy(other["counts"])
    augmented = np.array([a != "" for a in first["augment"].to_pylist()])
    tes = np.array(["tes" in a for a in first["augment"].to_pylist()])
    assert np.array_equal(counts[~augmented], other_counts[~augmented])
    assert not np.array_equal(counts[tes], other_counts[tes])
    # two copies of one trial differ from each other too
    a = trial_counts(first, "bolt0~tes(-2,0.5)#1")
    b = trial_counts(first, "bolt0~tes(-2,0.5)#2")
    assert not np.array_equal(a, b)


def test_a_trials_copies_do_not_depend_on_the_other_trials():
    table = make_frames(trials=3)
    alone = table.filter(pa.compute.equal(table["trial"], "bolt2"))
    methods = [aug.EventShift(-2, 0.5)]
    full, _ = aug.augment_frames(table, methods, seed=5)
    part, _ = aug.augment_frames(alone, methods, seed=5)
    assert np.array_equal(trial_counts(full, "bolt2~tes(-2,0.5)#1"), trial_counts(part, "bolt2~tes(-2,0.5)#1"))


def test_shifts_refuse_trials_with_missing_frames():
    table = make_frames()
    gappy = table.filter(pa.compute.not_equal(table["frame"], 3))
    with pytest.raises(SchemaError, match="not consecutive"):
        aug.augment_frames(gappy, [aug.FrameShift(-1)])
    aug.augment_frames(gappy, [aug.Resize(1.25)])  # spatial methods do not care


def test_bad_settings_are_refused_when_built():
    with pytest.raises(NeurotacError):
        aug.EventShift(1, 1.5)
    with pytest.raises(NeurotacError):
        aug.Resize(0.0)
    with pytest.raises(NeurotacError):
        aug.Rotate(45.0, 0.0)
    with pytest.raises(NeurotacError):
        aug.augment_frames(make_frames(), [aug.FrameShift(1)], seed=-1)


def test_where_augments_only_the_chosen_trials_and_passes_the_others():
    table = make_frames()
    out, _ = aug.augment_frames(table, [aug.Resize(1.25)], where=[("size_mm", "12"), ("size_mm", "18")])
    assert sorted(set(out["trial"].to_pylist())) == ["bolt0", "bolt0~resize(1.25)#1", "bolt1", "bolt2", "bolt2~resize(1.25)#1"]
    with pytest.raises(SchemaError, match="no such column"):
        aug.augment_frames(table, [aug.Resize(1.25)], where=[("colour", "red")])
    with pytest.raises(NeurotacError, match="no trial matches"):
        aug.augment_frames(table, [aug.Resize(1.25)], where=[("size_mm", "99")])
