"""Hostile inputs that once crashed a verb or passed without a word: each is refused in one line
(exit 1 for bad data, 2 for a bad option), or, where the data is fine, kept."""

import json

import numpy as np
import pyarrow as pa
import pytest

from neurotac_cli import schema as sch, tables
from neurotac_cli.io import kernels
from tests.test_exits import files, frames_table, invoke  # noqa: F401 - `files` is a fixture


def one_line(stderr: str, code: int, result: int) -> bool:
    return code == result and "Traceback" not in stderr and stderr.strip().count("\n") == 0


def events(x, y, p, width, height, extra=None):
    table = sch.events_table(np.arange(len(x)), x, y, p, width, height)
    if extra is not None:
        table = table.append_column("source", pa.array(extra))
    return table


def test_the_counting_kernel_refuses_events_off_its_buffer():
    """Callers check events against the sensor; the kernel itself never writes past its frames."""
    out = np.zeros((1, 2, 4, 4), np.uint16)
    for x, y, p in ((0, 4, 1), (100, 3, 1), (0, 0, 2)):
        with pytest.raises(ValueError, match="outside the 4x4 frames"):
            kernels.count_events(np.array([0]), np.array([x]), np.array([y]), np.array([p]), 0, 10, 0, out)
    assert out.sum() == 0


def test_render_and_a_pooling_crop_refuse_events_beyond_the_stated_sensor(tmp_path):
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([0, 30], [0, 5], [0, 1], 10, 10).replace_schema_metadata(
        sch.set_meta(sch.events_schema(), sensor=sch.sensor_meta(10, 10)).metadata))
    code, stderr, _ = invoke(["render", "-o", str(tmp_path / "r.png"), path])
    assert one_line(stderr, code, 1) and "outside the 10x10 sensor" in stderr
    undeclared = str(tmp_path / "u.arrows")
    tables.write(undeclared, events([0, 9], [0, 5], [0, 1], 10, 10).replace_schema_metadata(sch.events_schema().metadata))
    code, stderr, _ = invoke(["crop", "--pool", "2x2", "--sensor", "4x4", "-o", str(tmp_path / "c.arrows"), undeclared])
    assert one_line(stderr, code, 1) and "outside the 4x4 sensor" in stderr
    code, stderr, _ = invoke(["crop", "--box", "0,0,5,5", "-o", str(tmp_path / "c.arrows"), path])  # a fixed box: refused, not cut
    assert one_line(stderr, code, 1) and "outside the 10x10 sensor" in stderr


@pytest.mark.parametrize("verb", [["crop", "--box", "0,0,5,5"], ["crop", "--pool", "2x2"], ["frame", "--window", "10ms"]])
def test_a_sensor_size_that_contradicts_the_table_s_own_is_a_usage_error(tmp_path, verb):
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([0, 9], [0, 5], [0, 1], 10, 10))
    code, stderr, _ = invoke([*verb, "--sensor", "20x20", "-o", str(tmp_path / "c.arrows"), path])
    assert one_line(stderr, code, 2) and "declares its sensor as 10x10" in stderr
    code, stderr, _ = invoke([*verb, "--sensor", "10x10", "-o", str(tmp_path / "c.arrows"), path])  # the same size: fine
    assert code == 0, stderr


def _recording(force_t, labels=None):
    return {"trial": "a", "t0": 0, "events": (np.arange(3) * 1000, np.array([1, 2, 3]), np.array([1, 2, 3]), np.array([0, 1, 1])),
            "force": (np.asarray(force_t), np.linspace(0, 1, len(force_t))), "labels": labels or {}}


def test_frame_names_what_a_recordings_table_would_lose_and_refuses_a_force_log_out_of_order(tmp_path):
    empty = {"trial": "b", "t0": 0, "events": tuple(np.array([], np.int64) for _ in range(4)),
             "force": (np.array([], np.int64), np.array([], np.float32)), "labels": {}}
    table = sch.recordings_table([_recording([0, 10_000, 20_000]), empty], 10, 10)
    table = table.append_column("size_mm", pa.array([12, 9])).append_column("points", pa.array([[1], [2]]))
    table = table.append_column("frame", pa.array([3, 4])).append_column("lab", pa.array(["x", "y"], pa.large_string()))
    path, out = str(tmp_path / "r.arrows"), str(tmp_path / "f.arrows")
    tables.write(path, table)
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", out, path])
    assert code == 0, stderr
    assert "size_mm (int64) carried into the frames as text" in stderr and "points (list<item: int64>) left out" in stderr
    assert "1 trial (b) holds no event and no force sample" in stderr
    assert "frame (int64) left out of the frames: the frames have a column of that name" in stderr and "lab (" not in stderr
    framed = tables.read([out])
    assert set(framed.column("size_mm").to_pylist()) == {"12"} and set(framed.column("lab").to_pylist()) == {"x"}
    tables.write(path, sch.recordings_table([_recording([0, 20_000, 10_000])], 10, 10))
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", out, path])
    assert one_line(stderr, code, 1) and "force time runs backwards at 1 sample of 3" in stderr


def test_a_crop_keeps_another_tool_s_columns_with_their_events(tmp_path):
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([1, 8, 2], [1, 8, 2], [0, 1, 1], 10, 10, extra=["a", "b", "c"]))
    out = str(tmp_path / "c.arrows")
    code, stderr, _ = invoke(["crop", "--box", "0,0,5,5", "-o", out, path])
    assert code == 0, stderr
    assert tables.read([out]).column("source").to_pylist() == ["a", "c"]


@pytest.mark.parametrize("bad", [-5.0, np.nan, np.inf, -3])
def test_frames_with_counts_that_are_no_numbers_or_negative_are_refused(files, tmp_path, bad):  # noqa: F811
    table = frames_table()
    counts = sch.counts_numpy(table.column("counts")).astype(np.int32 if isinstance(bad, int) else np.float32)
    counts[3, 0, 2, 2] = bad
    table = pa.Table.from_arrays([*table.columns[:3], sch.counts_array(counts), *table.columns[4:]],
                                 names=table.column_names).replace_schema_metadata(table.schema.metadata)
    path = str(tmp_path / "f.arrows")
    tables.write(path, table)
    for args in (["train", "--model", "tdnn", "--epochs", "1", "-o", str(tmp_path / "m.model")], ["predict", "--model", f"{files}/m.model"]):
        code, stderr, _ = invoke(args + [path])
        assert one_line(stderr, code, 1) and f"1 frames carry {'negative' if bad < 0 else 'NaN or infinite'} counts" in stderr


@pytest.mark.parametrize("option", [["--lr", "nan"], ["--lr", "0"], ["--batch-size", "0"], ["--units", "-5"], ["--beta1", "1"],
                                    ["--epochs", "0"], ["--seed", "-1"]])
def test_settings_outside_their_range_are_usage_errors(files, tmp_path, option):  # noqa: F811
    code, stderr, _ = invoke(["train", "--model", "tdnn", "-o", str(tmp_path / "m.model"), *option, f"{files}/f.arrows"])
    assert code == 2 and "Traceback" not in stderr


def test_a_grid_value_outside_its_range_is_a_usage_error(files):  # noqa: F811
    code, stderr, _ = invoke(["eval", "--cv", "kfold:2", "--model-spec", "tdnn", "--grid", "lr=nan", f"{files}/f.arrows"])
    assert code == 2 and "--lr must be a finite number above 0" in stderr


def _edit_model(source: str, target: str, header=None, tensors=None):
    from safetensors.torch import load_file, save_file
    from safetensors import safe_open

    with safe_open(source, framework="numpy") as handle:
        metadata = dict(handle.metadata())
    weights = load_file(source)
    if header:
        metadata["neurotac"] = json.dumps(header(json.loads(metadata["neurotac"])))
    if tensors:
        tensors(weights)
    save_file(weights, target, metadata=metadata)


def test_a_damaged_model_header_or_nan_weights_are_one_line(files, tmp_path):  # noqa: F811
    def no_height(header):
        del header["input"]["height"]
        return header

    def as_list(header):
        header["architecture"] = [1, 2]
        return header

    def poison(weights):
        next(iter(weights.values())).fill_(float("nan"))

    def newer(header):
        header["format_version"] = 99
        return header

    for name, edit in (("v.model", {"header": newer}), ("h.model", {"header": no_height}), ("a.model", {"header": as_list}),
                       ("n.model", {"tensors": poison})):
        _edit_model(f"{files}/m.model", str(tmp_path / name), **edit)
        code, stderr, _ = invoke(["predict", "--model", str(tmp_path / name), f"{files}/f.arrows"])
        assert one_line(stderr, code, 1), stderr
        if name == "v.model":
            assert "newer than this neurotac reads" in stderr
    assert "NaN or infinite" in stderr


def test_frame_warns_when_most_events_come_before_the_sync_instant(tmp_path):
    trials = [{"trial": "a", "t0": 0, "events": ([-5_000_000, -4_000_000, 100], [1, 2, 3], [1, 2, 3], [0, 1, 0]),
               "force": ([0, 2000], [0.0, 1.0])}]
    path = str(tmp_path / "r.arrows")
    tables.write(path, sch.recordings_table(trials, 8, 8))
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", str(tmp_path / "f.arrows"), path])
    assert code == 0 and "2 of 3 events (66.7%) come before their trial's sync instant" in stderr


@pytest.mark.parametrize("label", ["events=x", "trial=x", "t0=5", "counts=x", "phase=x"])
def test_a_label_named_like_a_column_is_refused(label, tmp_path):
    code, stderr, _ = invoke(["simulate", "--preset", "ch4", "--objects", f"steel:hex:1:{label}", "--out", str(tmp_path / "s")])
    assert one_line(stderr, code, 2) and "label name" in stderr


@pytest.mark.parametrize("args", [["--background-rate", "nan"], ["--set", "on_threshold=nan"]])
def test_simulator_settings_that_are_no_numbers_are_refused(args, tmp_path):
    code, stderr, _ = invoke(["simulate", "--trials", "1", *args, "--out", str(tmp_path / "s")])
    assert code in (1, 2) and "Traceback" not in stderr and "finite" in stderr


@pytest.mark.parametrize("args", [["--rotate", "nan"], ["--rotate-range", "nan", "nan"], ["--resize", "inf"]])
def test_augment_refuses_angles_and_scales_that_are_no_numbers(args, files):  # noqa: F811
    code, stderr, _ = invoke(["augment", *args, f"{files}/f.arrows"])
    assert code == 2 and "finite" in stderr


@pytest.mark.parametrize("args", [["--fs", "0"], ["--tes", "0", "0.5"], ["--tes", "-2", "0"], ["--rotate", "0"], ["--resize", "1"],
                                  ["--rotate", "0", "--fs", "1"]])
def test_augment_refuses_a_method_that_changes_nothing(args, files):  # noqa: F811
    code, stderr, _ = invoke(["augment", *args, f"{files}/f.arrows"])
    assert code == 2 and "changes nothing" in stderr.splitlines()[-1]
    if args == ["--rotate", "0", "--fs", "1"]:  # in a hybrid the other method changes every copy
        code, stderr, _ = invoke(["augment", *args, "--combine", "hybrid", f"{files}/f.arrows"])
        assert code == 0, stderr


def test_a_label_named_grasp_is_a_label_for_models_of_single_grasps(files, tmp_path):  # noqa: F811
    table = frames_table()
    table = table.append_column("grasp", pa.array(["power"] * table.num_rows))
    tables.write(str(tmp_path / "g.arrows"), table)
    assert invoke(["info", str(tmp_path / "g.arrows")])[0] == 0
    code, stderr, _ = invoke(["predict", "--model", f"{files}/m.model", str(tmp_path / "g.arrows")])
    assert code == 0, stderr


def test_a_force_log_naming_a_column_twice_is_one_line(tmp_path):
    from neurotac_cli.errors import FormatError
    from neurotac_cli.io.force import read_force_log

    path = tmp_path / "f.csv"
    path.write_text("t_ms,force_N,force_N\n0,1,1\n1,1,1\n")
    with pytest.raises(FormatError, match="more than once"):
        read_force_log(str(path))


def test_a_force_log_from_a_pipe_is_read_and_an_empty_device_is_named(tmp_path):
    """bash's `<(...)` gives a path that is a pipe, not a file: read once; /dev/null exists but holds nothing."""
    import os

    from neurotac_cli.errors import FormatError
    from neurotac_cli.io.force import read_force_log

    fifo = str(tmp_path / "log")
    os.mkfifo(fifo)
    pid = os.fork()
    if pid == 0:  # the writer end, as the shell's process substitution would be
        with open(fifo, "w") as handle:
            handle.write("t_ms,force_N\n0,0.5\n1,0.7\n")
        os._exit(0)
    log = read_force_log(fifo)
    os.waitpid(pid, 0)
    assert len(log) == 1 and len(log[0].t) == 2
    with pytest.raises(FormatError, match="the force log is empty"):
        read_force_log("/dev/null")


def test_a_frame_window_past_the_table_format_is_a_usage_error(files):  # noqa: F811
    code, stderr, _ = invoke(["frame", "--window", "9223372036854775807us", "-"])
    assert code == 2 and "longest duration" in stderr


def test_a_validation_choice_that_matches_no_trial_is_one_line(files, tmp_path):  # noqa: F811
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "1", "--val-where", "material=glass",
                              "-o", str(tmp_path / "m.model"), f"{files}/f.arrows"])
    assert one_line(stderr, code, 1) and "no trial has material=glass" in stderr


def test_export_refuses_events_a_camera_file_cannot_hold(tmp_path):
    for x, p in (([0, 30], [0, 1]), ([0, 3], [0, 2])):
        path = str(tmp_path / "e.arrows")
        tables.write(path, events(x, [0, 5], p, 10, 10).replace_schema_metadata(
            sch.set_meta(sch.events_schema(), sensor=sch.sensor_meta(10, 10)).metadata))
        for suffix in (".raw", ".aedat4", ".aedat"):
            code, stderr, _ = invoke(["export", "-o", str(tmp_path / f"e{suffix}"), path])
            assert one_line(stderr, code, 1), stderr


@pytest.mark.parametrize("model", ["lstm", "convlstm", "deform-gru"])
def test_a_recurrent_model_needs_a_layer(files, tmp_path, model):  # noqa: F811
    code, stderr, _ = invoke(["train", "--model", model, "--layers", "0", "-o", str(tmp_path / "m.model"), f"{files}/f.arrows"])
    assert code == 2 and "--layers must be a finite number from 1 to 64" in stderr


def test_an_automatic_crop_centre_refuses_events_beyond_the_stated_sensor(tmp_path):
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([0, 30], [0, 5], [0, 1], 10, 10).replace_schema_metadata(
        sch.set_meta(sch.events_schema(), sensor=sch.sensor_meta(10, 10)).metadata))
    code, stderr, _ = invoke(["crop", "--size", "4x4", "--center", "auto", "-o", str(tmp_path / "c.arrows"), path])
    assert one_line(stderr, code, 1) and "1 events lie outside the 10x10 sensor" in stderr


def test_a_model_whose_weights_diverged_is_not_written(files, tmp_path):  # noqa: F811
    from neurotac_cli import model as models
    from neurotac_cli.errors import ModelError

    trained = models.load(f"{files}/m.model")
    next(iter(trained.net.parameters())).data.fill_(float("nan"))
    with pytest.raises(ModelError, match="training diverged"):
        models.save(trained, str(tmp_path / "n.model"))
    assert not (tmp_path / "n.model").exists()


def test_a_camera_file_cut_mid_record_is_read_with_a_warning_and_the_loss_kept_in_its_metadata(tmp_path):
    """The same bytes piped warn of the cut record; read from a path they must too."""
    from neurotac_cli.io.writers import aedat2_bytes

    data = aedat2_bytes(np.arange(5) * 10, np.arange(5), np.arange(5), np.ones(5, np.uint8))
    one, two = tmp_path / "a.aedat", tmp_path / "b.aedat"
    one.write_bytes(data[:-3])
    two.write_bytes(data)
    out = str(tmp_path / "e.arrows")
    code, stderr, _ = invoke(["import", str(one), "-o", out])
    assert code == 0 and "a.aedat: the last 5 bytes are a record cut short" in stderr
    assert tables.read([out]).num_rows == 4
    code, stderr, described = invoke(["info", out])
    assert "its last 5 bytes, a record cut short, were left out" in described
    code, stderr, _ = invoke(["import", str(one), str(two), "-o", str(tmp_path / "r.arrows")])
    assert code == 0 and stderr.count("record cut short") == 1 and "a.aedat" in stderr


@pytest.mark.parametrize("args, said", [
    (["sync", "-", "--force", "f.csv", "--offset", "5ms"], "--offset sets the instant for --method offset"),
    (["simulate", "--trials", "1", "--out", "sim", "--keep-led"], "--keep-led keeps the blink in the --synced table"),
])
def test_an_option_the_chosen_mode_would_ignore_is_refused(args, said):
    code, stderr, _ = invoke(args, stdin=b"")
    assert one_line(stderr, code, 2) and said in stderr


def test_a_training_set_that_cannot_train_is_refused_before_any_progress_line(tmp_path):
    one_class = frames_table(trials=("a",))  # foam only
    no_force = frames_table()
    no_force = no_force.set_column(no_force.schema.get_field_index("force"), "force", pa.nulls(no_force.num_rows, pa.float32()))
    for table, args, said in [(one_class, ["--model", "material-dnn"], "1 material class(es)"),
                              (no_force, ["--model", "tdnn"], "carry no force")]:
        path = str(tmp_path / "f.arrows")
        tables.write(path, table)
        code, stderr, _ = invoke(["train", *args, "--epochs", "1", "-o", str(tmp_path / "m.model"), path])
        assert one_line(stderr, code, 1) and said in stderr


def _with_column(table, name, values):
    field = table.schema.field(name)
    return table.set_column(table.schema.get_field_index(name), field, pa.array(values, field.type))


def test_training_data_that_would_train_silently_wrong_is_refused(tmp_path):
    table = frames_table(trials=("a", "b", "c"))
    n = table.num_rows
    spike = _with_column(table, "force", [0.5] * 5 + [1e30] + [0.5] * (n - 6))
    flat = _with_column(table, "force", [0.0] * n)
    mixed = _with_column(table, "material", ["rubber"] + table.column("material").to_pylist()[1:])  # trial a: foam and rubber
    unlabelled = _with_column(table, "material", [None] * 4 + table.column("material").to_pylist()[4:])
    empty = _with_column(table, "material", [""] * 4 + table.column("material").to_pylist()[4:])
    partly = _with_column(table, "material", [None] + table.column("material").to_pylist()[1:])
    for data, args, said in [(spike, ["--model", "tdnn"], "force of 1e+30 N"), (flat, ["--model", "tdnn"], "0 N on every frame"),
                             (partly, ["--model", "material-dnn"], "trial 'a': material is 'foam' on some frames and missing (null) on 1 frame"),
                             (mixed, ["--model", "material-dnn"], "trial 'a' has more than one material (foam, rubber)"),
                             (unlabelled, ["--model", "material-dnn"], "1 trial with no material (a)"),
                             (empty, ["--model", "material-dnn"], "1 trial with no material (a)"),
                             (table, ["--model", "tdnn", "--val-per", "nosuch"], "--val-per nosuch: no label column"),
                             (table, ["--model", "tdnn", "--val-trials", "a", "--val-where", "material=foam"], "give one of them")]:
        path = str(tmp_path / "f.arrows")
        tables.write(path, data)
        code, stderr, _ = invoke(["train", *args, "--epochs", "1", "-o", str(tmp_path / "m.model"), path])
        assert one_line(stderr, code, 2 if "give one" in said else 1) and said in stderr, stderr


def test_a_session_s_labels_may_change_with_its_grasps():
    from neurotac_cli.errors import ModelError
    from neurotac_cli.model.data import sequences

    table = frames_table(trials=("s",), frames=6)
    table = _with_column(table, "material", ["foam"] * 3 + ["steel"] * 3)
    with pytest.raises(ModelError, match="more than one material"):
        sequences(table)
    session = table.append_column("grasp", pa.array([0, 0, 0, 1, 1, 1], pa.int32()))
    assert sequences(session).labels["material"] == ["foam"]


def test_a_validation_fraction_that_draws_no_trial_is_told(tmp_path):
    path = str(tmp_path / "f.arrows")
    tables.write(path, frames_table(trials=("a", "b")))  # one trial per material: none to draw per material
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--val-fraction", "0.5", "--val-per", "material", "--epochs", "1",
                              "-o", str(tmp_path / "m.model"), path])
    assert code == 0 and "no material value has two source trials to draw from" in stderr


def test_a_classifier_cannot_be_cross_validated_by_holding_out_its_own_classes(tmp_path):
    path = str(tmp_path / "f.arrows")
    tables.write(path, frames_table(trials=("a", "b", "c")))
    code, stderr, _ = invoke(["eval", "--cv", "group:material", "--model-spec", "material-dnn", "--epochs", "1", path])
    assert one_line(stderr, code, 2) and "holds out every trial of a material class" in stderr


def test_eval_of_frames_without_a_true_force_is_refused(files, tmp_path):  # noqa: F811
    table = frames_table()
    table = table.set_column(table.schema.get_field_index("force"), "force", pa.nulls(table.num_rows, pa.float32()))
    tables.write(str(tmp_path / "n.arrows"), table)
    code, stderr, _ = invoke(["eval", "--model", f"{files}/m.model", str(tmp_path / "n.arrows")])
    assert one_line(stderr, code, 1) and "no frame has a true force" in stderr


@pytest.mark.parametrize("args", [["import", "--sensor", "99999x99999", "-"], ["crop", "--pool", "70000x2", "-"]])
def test_sizes_beyond_16_bit_coordinates_are_usage_errors(args):
    code, stderr, _ = invoke(args)
    assert code == 2 and "beyond 65535 pixels a side" in stderr and "Traceback" not in stderr


def test_frames_too_large_for_one_table_cell_are_refused(tmp_path):
    tables.write(str(tmp_path / "e.arrows"), events([1, 2], [1, 2], [0, 1], 60000, 60000))
    code, stderr, _ = invoke(["frame", "--window", "10ms", str(tmp_path / "e.arrows")])
    assert one_line(stderr, code, 1) and "too large for one table cell" in stderr


@pytest.mark.parametrize("name, cut", [("davis240c_rotdisk.aedat", 100), ("atis_ncars_loris.dat", 10),
                                       ("prophesee_hd_expelliarmus.evt3.raw", 100)])
def test_a_camera_file_cut_inside_its_header_is_refused(tmp_path, name, cut):
    """An EVT file cut mid-header read as a header without events: an empty table, exit 0."""
    from tests.conftest import real_file

    (tmp_path / name).write_bytes(real_file(name).read_bytes()[:cut])
    code, stderr, _ = invoke(["import", str(tmp_path / name)])
    assert one_line(stderr, code, 1) and "header is cut short" in stderr


@pytest.mark.parametrize("args, words", [(["export", "-o", "{d}/w.raw"], "MB of time words"),
                                         (["render", "--slice", "1ms", "-o", "{d}/r.png"], "give a longer --slice")])
def test_a_gap_of_years_between_two_events_is_refused_not_out_of_memory(tmp_path, args, words):
    table = sch.events_table(np.array([0, 10**15]), np.array([1, 2]), np.array([1, 2]), np.array([0, 1]), 8, 8)
    tables.write(str(tmp_path / "e.arrows"), table)
    code, stderr, _ = invoke([a.format(d=tmp_path) for a in args] + [str(tmp_path / "e.arrows")])
    assert one_line(stderr, code, 1) and words in stderr


def test_scoring_a_classifier_on_classes_it_never_learnt_says_so(files, tmp_path):  # noqa: F811
    table = frames_table(trials=("a", "b", "c"))
    material = table.column("material").to_pylist()
    relabel = lambda names: table.set_column(table.schema.get_field_index("material"), "material", pa.array(names))  # noqa: E731
    tables.write(str(tmp_path / "none.arrows"), relabel(["glass" if m == "foam" else "wood" for m in material]))
    code, stderr, _ = invoke(["eval", "--model", f"{files}/c.model", str(tmp_path / "none.arrows")])
    assert one_line(stderr, code, 1) and "none of the trials' material values (glass, wood) is a class" in stderr
    tables.write(str(tmp_path / "some.arrows"), relabel(["glass" if t == "c" else m for t, m in zip(table.column("trial").to_pylist(), material)]))
    code, stderr, _ = invoke(["eval", "--model", f"{files}/c.model", str(tmp_path / "some.arrows")])
    assert code == 0 and "1 trial of classes the model was not trained on (glass), counted as wrong" in stderr


@pytest.mark.parametrize("verb", ["eval", "predict"])
def test_frames_that_do_not_record_their_window_are_read_with_a_warning(files, tmp_path, verb):  # noqa: F811
    table = frames_table()
    table = table.replace_schema_metadata({k: v for k, v in table.schema.metadata.items() if k != sch.WINDOW.encode()})
    tables.write(str(tmp_path / "w.arrows"), table)
    code, stderr, _ = invoke([verb, "--model", f"{files}/m.model", str(tmp_path / "w.arrows")])
    assert code == 0 and "the frames do not record their window" in stderr and "trained on 10 ms frames" in stderr


def _made_by(table, pool, dtype="uint16"):
    return table.replace_schema_metadata(sch.set_meta(table.schema, history=[
        {"command": "crop", "args": {"pool": pool}}, {"command": "frame", "args": {"dtype": dtype}}]).metadata)


@pytest.mark.parametrize("pool, dtype, said", [([3, 3], "uint16", "pooled 3x3 (different pooling)"),
                                               ([6, 6], "float32", "scaled as float32 (different counts)")])
def test_frames_pooled_or_scaled_unlike_the_training_frames_are_refused(tmp_path, pool, dtype, said):
    tables.write(str(tmp_path / "train.arrows"), _made_by(frames_table(), [6, 6]))
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "1", "-o", str(tmp_path / "m.model"), str(tmp_path / "train.arrows")])
    assert code == 0, stderr
    tables.write(str(tmp_path / "same.arrows"), _made_by(frames_table(), [6, 6]))
    tables.write(str(tmp_path / "other.arrows"), _made_by(frames_table(), pool, dtype))
    assert invoke(["predict", "--model", str(tmp_path / "m.model"), str(tmp_path / "same.arrows")])[0] == 0
    code, stderr, _ = invoke(["predict", "--model", str(tmp_path / "m.model"), str(tmp_path / "other.arrows")])
    assert one_line(stderr, code, 1) and said in stderr


def test_eval_refuses_an_infinite_true_force(files, tmp_path):  # noqa: F811
    table = frames_table()
    force = table.column("force").to_numpy(zero_copy_only=False).copy()
    force[2] = np.inf
    tables.write(str(tmp_path / "inf.arrows"), table.set_column(table.schema.get_field_index("force"), "force", pa.array(force)))
    code, stderr, _ = invoke(["eval", "--model", f"{files}/m.model", str(tmp_path / "inf.arrows")])
    assert one_line(stderr, code, 1) and "NaN or infinite" in stderr


@pytest.mark.parametrize("verb", [["eval", "--model", "{d}/m.model"], ["predict", "--model", "{d}/m.model"],
                                  ["train", "--model", "tdnn", "--epochs", "1", "-o", "{t}/m.model"]])
def test_frames_whose_time_runs_back_within_a_trial_are_refused(files, tmp_path, verb):  # noqa: F811
    """eval scored them: the models read each frame's time from t, so time running back turned their
    trends round without a word."""
    table = frames_table()
    t = table.column("t").to_numpy().copy()
    t[5:8] = t[5:8][::-1]  # trial b: 0, 30, 20, 10 ms at frames 0..3
    path = str(tmp_path / "back.arrows")
    tables.write(path, table.set_column(table.schema.get_field_index("t"), "t", pa.array(t)))
    code, stderr, _ = invoke([arg.format(d=files, t=tmp_path) for arg in verb] + [path])
    assert one_line(stderr, code, 1) and "trial 'b': t goes back from 30000 µs at frame 1 to 20000 µs at frame 2" in stderr, stderr


@pytest.mark.parametrize("args, code_expected, said", [
    (["--duration", "0s"], 2, "positive"),
    (["--set", "session_rest_us=1ms..2ms"], 2, "session_rest_us must start at 50 ms"),
])
def test_a_session_without_time_for_its_grasps_is_refused(tmp_path, args, code_expected, said):
    code, stderr, _ = invoke(["simulate", "--session", "--grasps", "1", *args, "--out", str(tmp_path / "s")])
    assert code == code_expected and said in stderr, stderr


@pytest.mark.parametrize("args, said", [
    (["--set", "bright_share=1", "--set", "bright_contrast=-3"], "--set bright_share, bright_contrast: these only apply with --session"),
    (["--set", "slip_share=0.5"], "--set slip_share: it only applies with --session"),
    (["--illumination-drift", "0.1"], "--illumination-drift only applies with --session"),
    (["--vary", "optics", "--set", "object_contrast=-1.5"], "--set object_contrast: --vary draws it (optics: 0.5 to 0.95), which would "
                                                            "replace the value given"),
    (["--vary", "all", "--set", "on_threshold=0.3"], "--set on_threshold: --vary draws it (pixels"),
    (["--vary", "noise", "--background-rate", "5"], "--background-rate: --vary draws it (noise: 0.02 to 1)"),
    (["--hold-out", "optics", "--set", "object_contrast=-1"], "--set object_contrast: --hold-out draws it (optics"),
    (["--vary", "pixels", "--hold-out", "optics", "--set", "object_contrast=-1"], "--set object_contrast: --hold-out draws it"),
    (["--vary", "pixels", "--unseen", "noise", "--set", "hot_pixels=3"], "--set hot_pixels: --unseen draws it (noise"),
    (["--session", "--set", "grasp_us=100ms"], "--set grasp_us: it only applies without --session"),
])
def test_a_setting_that_would_change_nothing_is_refused_not_ignored(tmp_path, args, said):
    trials = [] if "--session" in args else ["--trials", "1"]
    code, stderr, _ = invoke(["simulate", "--preset", "ch4", *trials, *args, "--out", str(tmp_path / "s")])
    assert code == 2 and said in stderr, stderr


def test_a_factor_family_is_drawn_about_the_value_set_so_that_value_is_not_replaced():
    from neurotac_cli.sim.physics import parse_variation

    variation = parse_variation("membrane,optics")
    assert variation.replaces(["creep_us", "membrane_youngs_pa", "object_contrast", "dark_level"]) == [
        ("object_contrast", "optics"), ("dark_level", "optics")]


def test_frame_warns_where_the_force_log_is_sampled_more_slowly_than_the_window_and_slips_lie_outside(tmp_path):
    code, stderr, _ = invoke(["simulate", "--preset", "ch4", "--trials", "1", "--synced", "-o", str(tmp_path / "r.arrows")])
    assert code == 0, stderr
    (tmp_path / "slips.csv").write_text("trial,slip_start_ms,slip_end_ms\nsteel-bolt8-01,90000,90010\n")
    code, stderr, _ = invoke(["frame", "--window", "500us", "--phases", "session", "--slips", str(tmp_path / "slips.csv"),
                              "-o", str(tmp_path / "f.arrows"), str(tmp_path / "r.arrows")])
    assert code == 0 and "more slowly than the 0.5 ms window" in stderr and "1 true slip lies outside its trial's frames" in stderr, stderr
    code, stderr, _ = invoke(["frame", "--window", "10ms", "--phases", "session", "-o", str(tmp_path / "g.arrows"), str(tmp_path / "r.arrows")])
    assert code == 0 and "more slowly" not in stderr


def test_info_describes_a_force_log_and_a_csv_table(tmp_path):
    (tmp_path / "force.csv").write_text("t_ms,force_N\n" + "".join(f"{2 * i},{i / 10}\n" for i in range(11)))
    code, _, out = invoke(["info", str(tmp_path / "force.csv")])
    assert code == 0 and "11 samples in 1 trial, every 2 ms over 0.020 s; 0 .. 1 N" in out
    (tmp_path / "faery.csv").write_text("t,x@64,y@48,on\n1,2,3,1\n")  # events as faery writes them: decoded, not a table
    code, _, out = invoke(["info", str(tmp_path / "faery.csv")])
    assert code == 0 and "kind          events" in out
    (tmp_path / "table.csv").write_text("trial,frame,force_pred\na,0,0.5\n")
    code, _, out = invoke(["info", str(tmp_path / "table.csv")])
    assert code == 0 and "trial: string, frame: int64, force_pred: double" in out and "force log" not in out


@pytest.mark.parametrize("args, said", [(["--model", "tdnn", "--max-points", "200"], "has no option 'max_points'"),
                                        (["--model", "gp", "--epochs", "3"], "'epochs' does not apply")])
def test_an_option_the_model_does_not_use_is_a_usage_error(files, args, said):  # noqa: F811
    code, stderr, _ = invoke(["train", *args, "-o", "m.model", f"{files}/f.arrows"])
    assert one_line(stderr, code, 2) and said in stderr


def test_sync_says_on_stderr_when_it_reads_a_force_column_of_unknown_unit_as_newtons(tmp_path):
    code, stderr, _ = invoke(["simulate", "--preset", "ch4", "--trials", "1", "--seed", "1", "--out", str(tmp_path / "d")])
    assert code == 0, stderr
    camera = next((tmp_path / "d").glob("steel-*.aedat"))
    log = camera.with_name(camera.stem + "_force.csv").read_text().splitlines()
    (tmp_path / "lbs.csv").write_text("\n".join(["t_ms,force_lbs", *log[1:]]) + "\n")
    code, stderr, _ = invoke(["sync", str(camera), "--force", str(tmp_path / "lbs.csv"), "-o", str(tmp_path / "r.arrows")])
    assert code == 0 and "warning: force column 'force_lbs': 'lbs' is no force unit" in stderr


def test_a_group_split_refuses_trials_without_the_label(tmp_path):
    table = frames_table(trials=("a", "b", "c"))
    materials = table.column("material").to_pylist()
    table = table.set_column(table.schema.get_field_index("material"), "material",
                             pa.array([None if t == "c" else m for t, m in zip(table.column("trial").to_pylist(), materials)]))
    tables.write(str(tmp_path / "f.arrows"), table)
    code, stderr, _ = invoke(["eval", "--cv", "group:material", "--model-spec", "tdnn", "--epochs", "1", str(tmp_path / "f.arrows")])
    assert one_line(stderr, code, 1) and "1 trial with no material value (c) would be tested in no fold" in stderr


def test_info_of_a_model_trained_without_validation_names_its_best_epoch_by_training_loss(files, tmp_path):  # noqa: F811
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "2", "--val-fraction", "0", "-o", str(tmp_path / "m.model"),
                              f"{files}/f.arrows"])
    assert code == 0, stderr
    code, _, out = invoke(["info", str(tmp_path / "m.model")])
    assert code == 0 and "by its training loss" in out and "nan" not in out.lower()
    code, _, out = invoke(["info", "--json", str(tmp_path / "m.model")])
    assert code == 0 and "NaN" not in out and json.loads(out)["training"]["best_val_loss"] is None


def test_frame_warns_where_phase_ranges_reach_past_the_trials(files, tmp_path):  # noqa: F811
    code, stderr, _ = invoke(["frame", "--window", "1ms", "--phases", "0-50,51-100,101-143", "-o", str(tmp_path / "f.arrows"),
                              f"{files}/r.arrows"])
    assert code == 0 and "the phase ranges reach past the last frame of 2 trials" in stderr


def test_classify_keeps_the_history_of_its_frames(files, tmp_path):  # noqa: F811
    table = frames_table()
    table = table.replace_schema_metadata(sch.set_meta(table.schema, history=[{"command": "frame", "args": {}}]).metadata)
    tables.write(str(tmp_path / "h.arrows"), table)
    code, stderr, _ = invoke(["classify", "--model", f"{files}/c.model", "-o", str(tmp_path / "p.arrows"), str(tmp_path / "h.arrows")])
    assert code == 0, stderr
    assert [step["command"] for step in sch.get_meta(tables.read([str(tmp_path / "p.arrows")]).schema, sch.HISTORY)] == ["frame", "classify"]


@pytest.mark.parametrize("args, said", [
    (["split", "--train", "a.arrows", "--test", "b.arrows", "{d}/f.arrows"], "give either --fraction"),
    (["split", "--fraction", "0.3", "--train", "a.arrows", "--test", "a.arrows", "{d}/f.arrows"], "must differ"),
    (["frame", "--window", "10ms", "--scale", "5", "{d}/r.arrows"], "a scale only applies to --dtype float32"),
    (["render", "--fps", "8", "-o", "a.png", "{d}/f.arrows"], "--fps sets the pace of a GIF"),
])
def test_options_that_cannot_apply_are_usage_errors(files, args, said):  # noqa: F811
    code, stderr, _ = invoke([arg.format(d=files) for arg in args])
    assert code == 2 and said in stderr


def test_select_names_only_the_tables_columns_and_a_pool_larger_than_the_crop_says_so(files):  # noqa: F811
    code, stderr, _ = invoke(["select", "--where", "framez > 3", f"{files}/f.arrows"])
    assert one_line(stderr, code, 1) and "neurotac_row_index" not in stderr and "columns: trial, frame" in stderr
    code, stderr, _ = invoke(["crop", "--pool", "16x16", f"{files}/f.arrows"])
    assert one_line(stderr, code, 1) and "the pool is larger than the crop" in stderr


def test_a_model_trained_on_several_files_reads_frames_made_as_they_were(tmp_path):
    def made(path, pool, source):
        table = _made_by(frames_table(trials=(f"{source}-a", f"{source}-b")), pool)
        history = [{"command": "import", "args": {"paths": [source]}}] + sch.get_meta(table.schema, sch.HISTORY)
        tables.write(str(tmp_path / path), table.replace_schema_metadata(sch.set_meta(table.schema, history=history).metadata))

    made("a.arrows", [6, 6], "a.aedat")
    made("b.arrows", [6, 6], "b.aedat")
    made("c.arrows", [6, 6], "c.aedat")
    made("d.arrows", [3, 3], "d.aedat")
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "1", "-o", str(tmp_path / "m.model"),
                              str(tmp_path / "a.arrows"), str(tmp_path / "b.arrows")])
    assert code == 0, stderr
    assert invoke(["predict", "--model", str(tmp_path / "m.model"), str(tmp_path / "c.arrows")])[0] == 0
    code, stderr, _ = invoke(["predict", "--model", str(tmp_path / "m.model"), str(tmp_path / "d.arrows")])
    assert one_line(stderr, code, 1) and "different pooling" in stderr


def test_sense_asks_for_a_centre_it_can_take_and_durations_take_hours(tmp_path):
    from neurotac_cli.units import parse_duration_us

    code, stderr, _ = invoke(["sense", "--model", "m.model", "--size", "60x60", "cam.raw"])
    assert code == 2 and "--size needs --center X,Y (sense streams" in stderr
    assert parse_duration_us("1h") == 3_600_000_000


@pytest.mark.parametrize("args, said, code", [
    (["train", "--model", "tdnn", "--epochs", "1", "-o", "-"], "not stdout", 2),
    (["train", "--model", "tdnn", "--epochs", "1", "-o", "{d}/m.arrows"], ".arrows names a table", 2),
    (["train", "--model", "tdnn", "--epochs", "1", "--label", "object", "-o", "{d}/m.model"], "--label chooses the class", 2),
    (["eval", "--cv", "group:material=", "--model-spec", "tdnn", "--epochs", "1"], "give the value to hold out", 2),
    (["study", "--model-spec", "tdnn", "--epochs", "1", "--cv", "kfold:2", "--metrics", "{d}/no/m.parquet"], "folder", 1),
])
def test_options_that_would_be_ignored_or_fail_late_are_refused_first(tmp_path, args, said, code):
    path = str(tmp_path / "f.arrows")
    tables.write(path, frames_table(trials=("a", "b", "c")))
    done, stderr, _ = invoke([arg.replace("{d}", str(tmp_path)) for arg in args] + [path])
    assert one_line(stderr, done, code) and said in stderr, stderr
    assert not any(tmp_path.glob("m.*")) and not (tmp_path / "-").exists()


@pytest.mark.parametrize("args, said", [
    (["train"], "Missing option '--model'. Choose from: tdnn, gp"),
    (["frame", "--window", "10ms", "--window", "7ms"], "--window given twice"),
    (["nosuch"], "No such command 'nosuch'"),
])
def test_click_s_own_usage_errors_are_one_line(args, said):
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", "from neurotac_cli.cli import main; main()", *args], capture_output=True, text=True,
                          stdin=subprocess.DEVNULL)
    assert one_line(done.stderr, done.returncode, 2) and said in done.stderr and "--help`)" in done.stderr, done.stderr


def test_bare_neurotac_shows_its_help_on_stdout():
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", "from neurotac_cli.cli import main; main()"], capture_output=True, text=True,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 0 and "Usage: neurotac" in done.stdout and "Commands:" in done.stdout and not done.stderr


def test_train_warns_of_forces_beyond_any_flexiforce_range_and_info_shows_settings_of_zero(tmp_path):
    table = frames_table(trials=("a", "b", "c"))
    table = _with_column(table, "force", (np.asarray(table.column("force").to_pylist()) * 1000).tolist())  # a log in mN
    path = str(tmp_path / "f.arrows")
    tables.write(path, table)
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "1", "--seed", "0", "-o", str(tmp_path / "m.model"), path])
    assert code == 0 and "beyond 450 N" in stderr
    made = table.replace_schema_metadata(sch.set_meta(table.schema, history=[
        {"command": "simulate", "args": {"seed": 0, "keep_led": False, "trials": 3}, "version": "0"}]).metadata)
    tables.write(str(tmp_path / "h.arrows"), made)
    code, _, described = invoke(["info", str(tmp_path / "h.arrows")])
    assert code == 0 and "simulate seed=0 trials=3" in described, described


def test_an_aedat4_recording_stopped_between_packets_reads_its_whole_packets(tmp_path):
    """A recorder stopped before it writes the index table leaves a file that ends at a packet's end:
    it is read as far as it goes (as a pipe reads it), and a header alone is an empty table."""
    import struct

    from neurotac_cli.io import read_events_table
    from tests.conftest import real_file

    data = real_file("dvxplorer_tonic.aedat4").read_bytes()
    header = end = 18 + struct.unpack_from("<I", data, 14)[0]
    for _ in range(20):
        end += 8 + struct.unpack_from("<I", data, end + 4)[0]
    whole = read_events_table(real_file("dvxplorer_tonic.aedat4"))
    (tmp_path / "stopped.aedat4").write_bytes(data[:end])
    stopped = read_events_table(tmp_path / "stopped.aedat4")
    assert 0 < stopped.num_rows < whole.num_rows
    assert stopped.select(["t", "x", "y", "p"]).equals(whole.slice(0, stopped.num_rows).select(["t", "x", "y", "p"]))
    (tmp_path / "header.aedat4").write_bytes(data[:header])
    code, stderr, _ = invoke(["import", str(tmp_path / "header.aedat4"), "-o", str(tmp_path / "e.arrows")])
    assert code == 0 and "no events in the file" in stderr


@pytest.mark.parametrize("header, size", [
    (b"% evt 2.0\n% geometry 70000x70000\n", "70000x70000"),
    (b"% evt 3.0\n% format EVT3;width=0;height=0\n", "0x0"),
    (b"#!AER-DAT2.0\r\n# sensor: 240x65537\r\n# AEChip: eu.seebetter.ini.chips.davis.DAVIS240C\r\n", "240x65537"),
])
def test_a_sensor_size_in_a_header_that_no_event_could_lie_on_is_refused(tmp_path, header, size):
    """Past 16 bits a jAER row flip wraps, and at 0 every event is outside: a damaged header, said so."""
    path = tmp_path / "rec.raw"
    path.write_bytes(header + bytes(64))
    for args, stdin in ((["import", str(path)], None), (["import", "-"], header + bytes(64))):
        code, stderr, _ = invoke(args + ["-o", str(tmp_path / "e.arrows")], stdin=stdin)
        assert one_line(stderr, code, 1) and f"declares a {size} sensor, which cannot be" in stderr, stderr
    code, stderr, _ = invoke(["import", str(path), "--sensor", "640x480", "-o", str(tmp_path / "e.arrows")])
    # --sensor overrides a Prophesee header's size; a jAER file's own height still flips its rows
    assert code == 0 if header.startswith(b"%") else one_line(stderr, code, 1) and "declares" in stderr


@pytest.mark.parametrize("header", ["t,x,y,p,x", "t,x,y,p,p", "t,t,x,y,p"])
def test_an_events_csv_naming_a_column_twice_is_one_line(tmp_path, header):
    """One of the two would be read and the other ignored, without a word: which holds the events cannot be told."""
    path = tmp_path / "e.csv"
    path.write_text(f"{header}\n1,2,3,1,0\n")
    code, stderr, _ = invoke(["import", str(path), "-o", str(tmp_path / "e.arrows")])
    assert one_line(stderr, code, 1) and "more than once" in stderr, stderr


def test_sync_says_when_a_force_log_of_one_grasp_reads_as_several_because_a_row_is_out_of_place(tmp_path):
    rng = np.random.default_rng(0)
    path = str(tmp_path / "e.arrows")
    tables.write(path, sch.events_table(np.arange(2000) * 200, rng.integers(0, 20, 2000), rng.integers(0, 20, 2000),
                                        rng.integers(0, 2, 2000), 20, 20))
    times = list(range(0, 80, 2))
    times[10], times[11] = times[11], times[10]
    (tmp_path / "f.csv").write_text("t_ms,force_N\n" + "".join(f"{t},1\n" for t in times))
    code, stderr, _ = invoke(["sync", path, "--force", str(tmp_path / "f.csv"), "-o", str(tmp_path / "r.arrows")])
    assert one_line(stderr, code, 1) and "read as 2 trials because its time steps back" in stderr and "from 22 to 20 ms" in stderr, stderr


@pytest.mark.parametrize("header, times", [("t_ms", [10**16 + 2 * i for i in range(20)]), ("t_s", [i * 10**13 for i in range(20)])])
def test_force_times_past_a_microsecond_clock_are_one_line_not_a_numpy_warning(tmp_path, header, times):
    """Past 2^53 they were called no numbers; past 2^63 µs they wrapped with a numpy warning on stderr."""
    from neurotac_cli.errors import FormatError
    from neurotac_cli.io.force import read_force_log

    path = tmp_path / "f.csv"
    path.write_text(f"{header},force_N\n" + "".join(f"{t},1\n" for t in times))
    with np.errstate(invalid="raise"), pytest.raises(FormatError, match="beyond what a clock in µs holds"):
        read_force_log(str(path))


def test_export_to_aedat4_refuses_coordinates_past_its_signed_16_bits(tmp_path):
    """dv's events hold x and y as int16: x = 40000 would be written as -25536."""
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([40_000, 0], [0, 5], [1, 0], 40_001, 10))
    code, stderr, _ = invoke(["export", "-o", str(tmp_path / "e.aedat4"), path])
    assert one_line(stderr, code, 1) and "AEDAT 4.0 addresses 32768x32768 pixels at most" in stderr
    assert not (tmp_path / "e.aedat4").exists()


def _set(path: str, value):
    """A header edit: the value at a dotted path set, or deleted where `value` is `...`."""
    def edit(header):
        *parents, last = path.split(".")
        part = header
        for key in parents:
            part = part[key]
        if value is ...:
            del part[last]
        else:
            part[last] = value
        return header
    return edit


@pytest.mark.parametrize("path, value, said", [
    ("input.normalisation.force_scale", 0, "force scale 0 is not"), ("input.normalisation.force_scale", float("nan"), "force scale nan"),
    ("input.normalisation.force_scale", "x", "force scale 'x'"), ("input.normalisation.force_scale", ..., "force scale None"),
    ("input.normalisation", ..., "input normalisation is not"), ("input.window_us", 0, "input window_us is not"),
    ("input.window_us", "10ms", "input window_us is not"), ("input.height", -10, "input height is not"),
    ("input.accumulated", "yes", "input accumulated is not"), ("input", [1], "input is not"), ("architecture", None, "architecture is not"),
    ("training", "x", "training is not"), ("training.data_history", "x", "training data_history is not"),
    ("task", "bogus", "task 'bogus' is not"), ("format_version", "1", "format_version '1' is not"),
    ("format_version", 0, "format_version 0 is not"), ("classes", -1, "class list is not"),
    ("input.sensor", {"a": 1}, "input sensor is not"), ("training.curve", [{"epoch": 0}], "training curve is not"),
    ("training.data_history", [{"args": "x"}], "training data_history is not"),
    ("training.trials", {"train": 5}, "training trials is not"), ("training.fit", [1], "training fit is not"),
    ("training.events_per_frame_max", "x", "events_per_frame_max is not"),
    ("training.member_curves", [5], "training member_curves is not"),
    ("training.member_curves", [[{"epoch": 0}]], "training curve is not"),
    ("training.member_best_epochs", [None, "x"], "member_best_epochs is not"), ("training.member_best_epochs", 5, "member_best_epochs is not")])
def test_a_force_model_header_edited_to_nonsense_is_one_line(files, tmp_path, path, value, said):  # noqa: F811
    """A force scale of 0 or NaN once estimated 0 or NaN N on every frame with exit 0; wrong types were tracebacks."""
    _edit_model(f"{files}/m.model", str(tmp_path / "x.model"), header=_set(path, value))
    for args in (["info"], ["predict", "--model"], ["eval", "--model"]):
        code, stderr, _ = invoke(args + [str(tmp_path / "x.model")] + ([f"{files}/f.arrows"] if len(args) > 1 else []))
        assert one_line(stderr, code, 1) and said in stderr, stderr


@pytest.mark.parametrize("classes", [None, "foam", ["foam"], ["foam", "foam"], [1, 2]])
def test_a_classifier_header_with_a_damaged_class_list_is_one_line(files, tmp_path, classes):  # noqa: F811
    """Duplicated names and a string (read as its letters) once classified with exit 0; numbers were a traceback."""
    _edit_model(f"{files}/c.model", str(tmp_path / "x.model"), header=_set("classes", classes))
    for args in (["info"], ["classify", "--model"]):
        code, stderr, _ = invoke(args + [str(tmp_path / "x.model")] + ([f"{files}/f.arrows"] if len(args) > 1 else []))
        assert one_line(stderr, code, 1) and "class list is not two or more distinct class names" in stderr, stderr


@pytest.mark.parametrize("setting, said", [
    ("on_threshold=1e9", "on_threshold must be in"), ("off_threshold=1e-6", "off_threshold must be in"),
    ("contact_delay_us=50ms..10ms", "contact_delay_us must be a range"), ("dark_level=-1", "dark_level must be >= 0"),
    ("creep_us=-5ms", "creep_us must be >= 0"), ("camera_offset_us=-5s..-1s", "camera_offset_us must be a range"),
    ("membrane_poisson=2", "membrane_poisson must be in [0, 0.5]"),
    ("position_jitter_px=1e9", "position_jitter_px at most the sensor"), ("led_box=500,0,10,10", "the LED would light no pixel"),
    ("object_contrast=0", "the camera cannot see the object")])
def test_simulator_settings_that_hung_crashed_or_made_nonsense_are_refused(setting, said, tmp_path):
    """A threshold of 1e9 or 1e-6 ran for hours on the LED blink's crossings; a range from high to low
    and a negative dark level were tracebacks; negative durations simulated without a word."""
    code, stderr, _ = invoke(["simulate", "--trials", "1", "--set", setting, "--out", str(tmp_path / "s")])
    assert code == 2 and "Traceback" not in stderr and said in stderr, stderr


@pytest.mark.parametrize("model, label, said", [("c.model", "object", "classifies by 'material', the label it was trained on"),
                                                ("m.model", "material", "tdnn estimates force")])
def test_eval_refuses_a_label_its_model_file_does_not_classify_by(files, model, label, said):  # noqa: F811
    """The --label was ignored: a classifier scored its own label, exit 0, under the name of the one asked for."""
    code, stderr, _ = invoke(["eval", "--model", f"{files}/{model}", "--label", label, f"{files}/f.arrows"])
    assert code == 2 and "Traceback" not in stderr and said in stderr, stderr
    code, stderr, _ = invoke(["eval", "--model", f"{files}/c.model", "--label", "material", f"{files}/f.arrows"])
    assert code == 0, stderr


@pytest.mark.parametrize("verb", ["eval", "study"])
def test_a_label_for_a_force_model_spec_is_refused(files, verb):  # noqa: F811
    """As `train` refuses it: a force model has no class to predict, so --label would change nothing."""
    extra = ["--cv", "kfold:2"] if verb == "eval" else ["--grid", "units=2,3"]
    code, stderr, _ = invoke([verb, "--model-spec", "tdnn", "--label", "object", *extra, f"{files}/f.arrows"])
    assert code == 2 and "Traceback" not in stderr and "tdnn estimates force" in stderr, stderr


@pytest.mark.parametrize("key, value", [("units", 0), ("layers", -1), ("delays", -2)])
def test_a_header_architecture_past_trains_bounds_is_one_line(files, tmp_path, key, value):  # noqa: F811
    """A unit count of 0 built an empty network, with torch's warnings on stderr before the error."""
    _edit_model(f"{files}/m.model", str(tmp_path / "x.model"), header=_set(f"architecture.{key}", value))
    for args in (["predict", "--model"], ["eval", "--model"]):
        code, stderr, _ = invoke(args + [str(tmp_path / "x.model"), f"{files}/f.arrows"])
        assert one_line(stderr, code, 1) and "architecture is out of bounds" in stderr and f"--{key}" in stderr, stderr


@pytest.mark.parametrize("args", [["train", "--model", "tdnn", "--epochs", "1", "-o", "{t}/m.png", "--plot", "{t}/./m.png"],
                                  ["eval", "--model", "{d}/m.model", "-o", "{t}/e.parquet", "--metrics", "{t}/e.parquet"],
                                  ["split", "--fraction", "0.5", "--train", "{t}/s.arrows", "--test", "{t}/../{n}/s.arrows"]])
def test_two_outputs_naming_one_file_are_refused(files, tmp_path, args):  # noqa: F811
    """The model file was overwritten by its own training plot, the metrics by the predictions, exit 0."""
    args = [a.format(t=tmp_path, d=files, n=tmp_path.name) for a in args] + [f"{files}/f.arrows"]
    code, stderr, _ = invoke(args)
    assert one_line(stderr, code, 2) and "two outputs name one file" in stderr, stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("args, said", [
    (["render", "--fps", "nan", "-o", "{t}/r.gif"], "'nan' is not a finite number in the range"),
    (["train", "--model", "tdnn", "--val-fraction", "nan", "-o", "{t}/m.model"], "'nan' is not a finite number in the range"),
    (["eval", "--cv", "kfold:2", "--model-spec", "tdnn", "--val-fraction", "nan"], "'nan' is not a finite number in the range"),
    (["crop", "--pool", "all", "--warn-above", "nan"], "'nan' is not a finite number in the range"),
    (["render", "--slice", "-5ms", "-o", "{t}/r.gif"], "expected a positive duration"),
    (["sync", "--min-coverage", "-1"], "--min-coverage"), (["sync", "--min-score", "-1"], "--min-score"),
    (["sync", "--saturation", "inf"], "'inf' is not a finite number"), (["sync", "--median", "-5ms"], "a duration of 0 or more")])
def test_a_value_outside_an_options_range_is_a_usage_error(files, tmp_path, args, said):  # noqa: F811
    """NaN passed click's range checks: a traceback (render, train), or an eval that ran and a crop
    that could no longer warn, exit 0; a negative --slice was exit 1 where 0 was exit 2; a negative
    LED coverage failed later with a message about spikes."""
    code, stderr, _ = invoke([a.format(t=tmp_path) for a in args] + [f"{files}/f.arrows"])
    assert one_line(stderr, code, 2) and said in stderr, stderr


def test_more_torch_threads_than_can_be_started_is_a_usage_error(files):  # noqa: F811
    """OpenMP could not start 100000 threads: the process died of a segmentation fault."""
    import subprocess

    done = subprocess.run(["neurotac", "predict", "--model", f"{files}/m.model", "--threads", "100000", f"{files}/f.arrows"],
                          capture_output=True, text=True, timeout=120)
    assert one_line(done.stderr, done.returncode, 2) and "--threads" in done.stderr, done.stderr


@pytest.mark.parametrize("blocker", ["file", "folder"])
def test_a_study_cache_entry_blocked_by_a_file_or_a_folder_is_one_line(files, tmp_path, blocker):  # noqa: F811
    """The folder an entry goes in being a file, or the entry a folder, was a traceback after the training."""
    args = ["eval", "--cv", "kfold:2", "--model-spec", "tdnn", "--epochs", "1", "--cache", str(tmp_path / "c"), f"{files}/f.arrows"]
    code, stderr, _ = invoke(args)
    assert code == 0, stderr
    entries = sorted((tmp_path / "c").glob("*/*.pkl"))
    for entry in entries:
        entry.unlink()
    if blocker == "file":  # every entry's folder a file
        for folder in {entry.parent for entry in entries}:
            folder.rmdir()
            folder.write_bytes(b"")
    else:  # every entry a folder
        for entry in entries:
            entry.mkdir()
    code, stderr, _ = invoke(args)
    *progress, error = stderr.strip().splitlines()  # after the study's one line of what it runs
    assert code == 1 and "Traceback" not in stderr and len(progress) == 1, stderr
    assert error.startswith("neurotac eval: error: cannot write the study cache entry") and "remove what is there" in error, stderr


@pytest.mark.parametrize("args, code", [
    (["info", ""], 1), (["import", ""], 1), (["predict", "--model", ""], 2), (["eval", "--model", "", "{f}"], 2),
    (["train", "--model", "tdnn", "-o", "", "{f}"], 2), (["split", "--train", "", "--test", "{t}/b.arrows", "--fraction", "0.5", "{f}"], 2),
    (["eval", "--model", "{f}", "-o", "", "{f}"], 2)])
def test_an_empty_path_says_so(files, tmp_path, args, code):  # noqa: F811
    """An unset shell variable read ": no such file"; `train -o ""` trained, then died of a traceback."""
    status, stderr, _ = invoke([a.format(f=f"{files}/f.arrows", t=tmp_path) for a in args])
    assert one_line(stderr, status, code) and "an empty" in stderr and "epoch" not in stderr, stderr


@pytest.mark.parametrize("args, said", [
    (["--objects", "steel:bolt8:-1,steel:hex:2"], "trial count -1 in 'steel:bolt8:-1' is negative"),
    (["--objects", "steel:boltnan:1"], "unknown object 'boltnan'"),
    (["--objects", "steel:hexinf:1"], "unknown object 'hexinf'"),
    (["--objects", "steel:hex:1:a=1:a=2"], "label 'a' given twice"),
    (["--vary", "all,pixels"], "all names every family, so it stands alone"),
    (["--unseen", "all"], "--unseen takes one family, not all"),
    (["--session", "--grasps", "2", "--objects", "steel:bolt8:0"], "every group of --objects has a count of 0"),
    (["--session", "--grasps", "1", "--set", "session_speed=1e-9..1"], "session_speed must start at 0.01"),
])
def test_simulator_groups_and_families_that_simulated_wrong_or_crashed_are_refused(tmp_path, args, said):
    """A group of -1 grasps simulated one of its objects in place of the others' grasps; an object of NaN
    or infinite size and a session whose groups all have 0 grasps were tracebacks; a label given twice
    kept its last value; a session speed of 1e-9 filled the memory."""
    if "--session" not in args:
        args = ["--trials", "1", *args]
    code, stderr, _ = invoke(["simulate", *args, "--out", str(tmp_path / "s")])
    assert one_line(stderr, code, 2) and said in stderr, stderr
    assert not (tmp_path / "s").exists()  # refused before the folder is made


@pytest.mark.parametrize("text", ["", "\n\n"])
def test_an_empty_manifest_is_one_line(tmp_path, text):
    """The CSV reader read its header after the file was closed: a traceback."""
    (tmp_path / "manifest.csv").write_text(text)
    code, stderr, _ = invoke(["sync", "--manifest", str(tmp_path / "manifest.csv"), "-o", str(tmp_path / "r.arrows")])
    assert one_line(stderr, code, 1) and "the manifest is empty" in stderr, stderr


def test_info_describes_a_csv_with_labels_beyond_ascii_and_a_force_log_with_semicolons(tmp_path):
    """A table neurotac wrote as CSV with a label such as 'Stoßdämpfer' was 'an unknown camera format',
    and a force log with semicolons, which `sync --force` reads, was refused as events without x, y, p."""
    path = str(tmp_path / "pred.csv")
    tables.write(path, pa.table({"trial": ["a", "b"], "frame": [0, 0], "object": ["Stoßdämpfer", 'say "hi",\nthen']}))
    code, stderr, out = invoke(["info", path])
    assert code == 0 and "rows          2" in out and "object: string" in out, stderr
    (tmp_path / "force.csv").write_text("t_ms;force_N\n" + "".join(f"{2 * i};{i / 10}\n" for i in range(11)))
    code, stderr, out = invoke(["info", str(tmp_path / "force.csv")])
    assert code == 0 and "11 samples in 1 trial" in out, stderr


def test_a_force_log_with_a_repeated_time_names_the_time_and_what_to_do(tmp_path):
    rows = [f"{2 * i},{i / 10}" for i in range(12)]
    (tmp_path / "force.csv").write_text("\n".join(["t_ms,force_N", *rows[:4], rows[3], *rows[4:]]) + "\n")
    tables.write(str(tmp_path / "cam.arrows"), events([1, 2], [1, 2], [0, 1], 32, 32))
    code, stderr, _ = invoke(["sync", str(tmp_path / "cam.arrows"), "--force", str(tmp_path / "force.csv")])
    assert code == 1 and "force time repeats 6 ms at sample 5 of trial 1" in stderr and "drop repeated rows" in stderr, stderr


@pytest.mark.parametrize("reader, what", [("neurotac_cli.io.force:read_force_log", "a force log"),
                                          ("neurotac_cli.io.slips:read_slips", "a CSV of true slips")])
def test_a_device_that_never_ends_is_refused_where_a_file_is_read_whole(reader, what):
    """/dev/zero as `sync --force` or `frame --slips`: refused at once, not read until memory runs out
    (in a process of bounded memory, so the test cannot take the machine's)."""
    import subprocess
    import sys

    module, name = reader.split(":")
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))\n"
            f"from {module} import {name}\nfrom neurotac_cli.errors import NeurotacError\n"
            f"try:\n    {name}('/dev/zero')\nexcept NeurotacError as error:\n    print(error)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout.strip() == f"/dev/zero is a device, not {what} (read whole, it would never end); save it to a file and give that", done.stderr[-500:]


@pytest.mark.parametrize("reader, what", [("neurotac_cli.io.force:read_force_log", "a force log"),
                                          ("neurotac_cli.io.slips:read_slips", "a CSV of true slips")])
def test_a_terminal_that_gives_nothing_is_refused_at_once_not_waited_on(reader, what):
    """A silent terminal (a pseudo-terminal nobody types into) as a file read whole: refused at once,
    where a blocking read of its first byte would wait for ever."""
    import os
    import subprocess
    import sys

    module, name = reader.split(":")
    leader, follower = os.openpty()
    try:
        path = os.ttyname(follower)
        code = (f"from {module} import {name}\nfrom neurotac_cli.errors import NeurotacError\n"
                f"try:\n    {name}({path!r})\nexcept NeurotacError as error:\n    print(error)")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    finally:
        os.close(leader)
        os.close(follower)
    assert done.stdout.strip() == f"{path} is a device, not {what} (read whole, it would never end); save it to a file and give that"


@pytest.mark.parametrize("kind", ["device", "fifo"])
def test_a_manifest_that_is_a_device_or_pipe_is_named_so_not_missing(tmp_path, kind):
    import os

    path = "/dev/null" if kind == "device" else str(tmp_path / "manifest.csv")
    if kind == "fifo":
        os.mkfifo(path)
    code, stderr, _ = invoke(["sync", "--manifest", path])
    assert one_line(stderr, code, 1) and f"{path} is a pipe or device, not a manifest file" in stderr, stderr


@pytest.fixture
def read_only_folder(tmp_path):
    """A folder no write goes into: without write permission, or for root (whom permissions do not
    stop) a read-only bind mount of it, where this machine allows one."""
    import os
    import subprocess

    folder = tmp_path / "read-only"
    folder.mkdir()
    if os.geteuid() != 0:
        folder.chmod(0o555)
        yield folder
        folder.chmod(0o755)
        return
    mounted = subprocess.run(["mount", "--bind", str(folder), str(folder)], capture_output=True).returncode == 0
    if not mounted or subprocess.run(["mount", "-o", "remount,bind,ro", str(folder)], capture_output=True).returncode:
        if mounted:
            subprocess.run(["umount", str(folder)])
        pytest.skip("no read-only bind mount here")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)])


def test_an_output_in_a_read_only_folder_is_refused_before_any_training(files, read_only_folder):  # noqa: F811
    import os

    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "1", "-o", str(read_only_folder / "m.model"), str(files / "f.arrows")])
    said = "(read-only file system; write elsewhere)" if os.geteuid() == 0 else "(permission denied; write elsewhere"
    assert one_line(stderr, code, 1) and f"cannot write {read_only_folder / 'm.model'} {said}" in stderr, stderr


def test_plot_trials_the_input_lacks_are_named_and_without_a_plot_are_a_usage_error(files, tmp_path):  # noqa: F811
    args = ["eval", "--model", f"{files}/m.model", f"{files}/f.arrows"]
    code, stderr, _ = invoke([*args, "--plot", str(tmp_path / "p.png"), "--plot-trials", "nosuch"])
    assert one_line(stderr, code, 1) and "no trial 'nosuch'" in stderr and not (tmp_path / "p.png").exists()
    code, stderr, _ = invoke([*args, "--plot-trials", "nosuch"])
    assert code == 2 and "give --plot" in stderr
    code, stderr, _ = invoke([*args, "--plot", str(tmp_path / "p.png"), "--plot-trials", ""])  # not the default trials
    assert code == 2 and "names no trial" in stderr


def test_plot_trials_named_twice_are_drawn_once():
    from neurotac_cli.commands.eval import _plotted_trials
    from tests.model.helpers import tiny_frames

    assert _plotted_trials(tiny_frames(trials=3), "t1,t1, t0") == ["t1", "t0"]


@pytest.mark.parametrize("args", [["eval", "--model", "{d}/m.model", "--metrics", "{t}/x.arrows"],
                                  ["study", "--model-spec", "tdnn", "--epochs", "1", "--cv", "kfold:2", "--metrics", "{t}/x.arrows"],
                                  ["split", "--fraction", "0.5", "--train", "{t}/x.arrows", "--test", "{t}/y.arrows"],
                                  ["train", "--model", "tdnn", "--epochs", "1", "-o", "{t}/m.model", "--curve", "{t}/x.arrows"]])
def test_a_side_output_that_is_an_input_is_refused_and_the_input_kept(files, tmp_path, args):  # noqa: F811
    source = tmp_path / "x.arrows"
    source.write_bytes((files / "f.arrows").read_bytes())
    code, stderr, _ = invoke([a.format(d=files, t=tmp_path) for a in args] + [str(source)])
    assert one_line(stderr, code, 2) and "is also an input" in stderr
    assert source.read_bytes() == (files / "f.arrows").read_bytes()


def test_figures_undefined_on_a_flat_force_are_said_so_in_the_summary():
    from neurotac_cli.model import scoring

    rows = [("all", "rmse", 0.2), ("all", "r2", 0.5), ("all", "rmse_pct_range", 5.0),
            ("trial:a", "rmse", 0.1), ("trial:a", "r2", float("nan")), ("trial:a", "rmse_pct_range", float("nan"))]
    said = scoring.summary(rows)
    assert "undefined where the measured force does not vary: 1 scope (trial:a)" in said
    assert "undefined" not in scoring.summary(rows[:3])


@pytest.mark.parametrize("suffix", [".json", ".ndjson"])
@pytest.mark.parametrize("verb", ["info", "import"])
def test_json_a_verb_wrote_for_other_tools_is_named_when_read_back(tmp_path, suffix, verb):
    source, text = str(tmp_path / "e.arrows"), str(tmp_path / f"e{suffix}")
    tables.write(source, events(np.array([1, 2]), np.array([1, 2]), np.array([0, 1]), 8, 8))
    assert invoke(["select", "--where", "t >= 0", source, "-o", text])[0] == 0
    code, stderr, _ = invoke([verb, text])
    assert one_line(stderr, code, 1) and "is JSON text" in stderr


def test_cross_validation_options_given_to_a_model_file_s_scoring_are_a_usage_error(files, monkeypatch):  # noqa: F811
    args = ["eval", "--model", f"{files}/m.model", f"{files}/f.arrows"]
    code, stderr, _ = invoke([*args, "--repeats", "3", "--seed", "5"])
    assert code == 2 and "--repeats, --seed apply to --cv only" in stderr
    monkeypatch.setenv("NEUROTAC_JOBS", "4")  # a session's environment is not a request
    assert invoke(args)[0] == 0


def test_a_box_given_to_a_view_that_draws_no_box_is_a_usage_error(files, tmp_path):  # noqa: F811
    code, stderr, _ = invoke(["render", "--size", "4x4", "--center", "3,3", f"{files}/f.arrows", "-o", str(tmp_path / "r.png")])
    assert code == 2 and "with --view crop" in stderr and not (tmp_path / "r.png").exists()


def test_a_sensor_size_given_for_a_table_is_a_usage_error(files):  # noqa: F811
    code, stderr, _ = invoke(["info", "--sensor", "10x10", f"{files}/f.arrows"])
    assert code == 2 and "a table carries its own" in stderr


@pytest.mark.parametrize("verb", [["concat"], ["info"], ["import"], ["select", "--where", "true"]])
def test_stdin_named_twice_is_a_usage_error(verb):
    code, stderr, _ = invoke([*verb, "-", "-"])
    assert code == 2 and "stdin holds one input" in stderr


def test_info_on_a_damaged_file_named_as_a_table_says_it_is_no_table(tmp_path):
    damaged = tmp_path / "bad.arrows"
    damaged.write_bytes(b"hello world\nfoo\n")
    code, stderr, _ = invoke(["info", str(damaged)])
    assert one_line(stderr, code, 1) and "is not an Arrow or Parquet table" in stderr


def test_info_names_a_frame_given_twice_that_training_would_refuse(files):  # noqa: F811
    code, _, said = invoke(["info", f"{files}/f.arrows", f"{files}/f.arrows"])
    assert code == 0 and "appears twice in the input" in said
    assert "repeated" not in invoke(["info", f"{files}/f.arrows"])[2]


def test_info_reads_a_camera_file_whose_first_bytes_hold_a_semicolon(tmp_path):
    import struct

    path = tmp_path / "semicolon.aedat"
    records = b"".join(struct.pack(">II", (y << 22) | (x << 12) | (p << 11), t) for x, y, p, t in [(10, 20, 1, 59), (11, 21, 0, 60), (12, 22, 1, 70)])
    path.write_bytes(b"#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.DAVIS240C\r\n" + records)  # 59 is `;`
    code, _, said = invoke(["info", str(path)])
    assert code == 0 and "AEDAT 2.0" in said and "CSV" not in said


def test_frames_without_a_measured_force_are_counted_as_left_out():
    from neurotac_cli import metrics
    from neurotac_cli.model import scoring

    rows = metrics.force_rows(["a"] * 4, ["holding"] * 4, [np.nan, np.nan, 1.0, 2.0], [0.5, 0.5, 1.0, 2.1])
    assert ("all", "unforced_frames", 2.0) in rows
    assert "2 frames with no measured force (null in the force column) left out" in scoring.summary(rows)
    assert not any(metric == "unforced_frames" for _, metric, _ in metrics.force_rows(["a"] * 2, ["holding"] * 2, [1.0, 2.0], [1.0, 2.0]))


@pytest.mark.parametrize("option, said", [(["--rotate", "360"], "--rotate 360 changes nothing"),
                                          (["--rotate-range", "-720", "720"], "is not in the range -360<=x<=360"),
                                          (["--rotate-range", "-1e308", "1e308"], "is not in the range -360<=x<=360")])
def test_rotations_of_whole_turns_or_beyond_one_turn_are_usage_errors(files, tmp_path, option, said):  # noqa: F811
    code, stderr, _ = invoke(["augment", *option, "-o", str(tmp_path / "a.arrows"), f"{files}/f.arrows"])
    assert one_line(stderr, code, 2) and said in stderr


def test_a_tes_of_nothing_in_a_hybrid_is_one_method_that_the_other_changes(files, tmp_path):  # noqa: F811
    """Its J 0 and ZETA 0 counted as two methods that change nothing, so the hybrid was refused."""
    code, stderr, _ = invoke(["augment", "--fs", "1", "--tes", "0", "0", "--combine", "hybrid", "-o", str(tmp_path / "a.arrows"),
                              f"{files}/f.arrows"])
    assert code == 0, stderr
    code, stderr, _ = invoke(["augment", "--tes", "0", "0", "-o", str(tmp_path / "b.arrows"), f"{files}/f.arrows"])
    assert one_line(stderr, code, 2) and "--tes with J 0 changes nothing" in stderr


@pytest.mark.parametrize("option, said", [(["--latency", "-5ms"], "--latency is a delay"),
                                          (["--method", "offset", "--offset", "0ms", "--latency", "1ms"], "--latency is the camera's delay"),
                                          (["--method", "xcorr", "--keep-led"], "--keep-led keeps the LED blink's burst"),
                                          (["--method", "offset", "--offset", "0ms", "--region", "0,0,2,2"], "--region is where led and xcorr look"),
                                          (["--region", "5,5,10,10"], "--region 5,5,10,10 reaches past the 10x10 sensor")])
def test_sync_settings_that_would_be_ignored_or_reach_past_the_sensor_are_usage_errors(tmp_path, option, said):
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([0, 9], [0, 5], [0, 1], 10, 10))
    (tmp_path / "force.csv").write_text("t_ms,force_N\n" + "".join(f"{t},0\n" for t in range(0, 40, 2)))
    code, stderr, _ = invoke(["sync", path, "--force", str(tmp_path / "force.csv"), *option])
    assert one_line(stderr, code, 2) and said in stderr


def test_a_force_log_that_is_a_table_or_a_camera_file_is_named_so_and_an_arrow_log_is_read(tmp_path):
    from neurotac_cli.io.force import read_table

    path = str(tmp_path / "e.arrows")
    tables.write(path, events([0, 9], [0, 5], [0, 1], 10, 10))
    code, stderr, _ = invoke(["sync", path, "--force", path])
    assert one_line(stderr, code, 1) and "is a neurotac events table, not a force log" in stderr
    (tmp_path / "cam.aedat").write_bytes(b"#!AER-DAT2.0\r\n" + bytes(range(256)) * 4)
    code, stderr, _ = invoke(["sync", path, "--force", str(tmp_path / "cam.aedat")])
    assert one_line(stderr, code, 1) and "holds binary data, not a force log" in stderr
    import pyarrow.feather as feather

    feather.write_feather(pa.table({"t_ms": [0.0, 2.0], "force_N": [0.0, 1.0]}), str(tmp_path / "log.feather"))
    assert read_table(str(tmp_path / "log.feather")).column("force_N").to_pylist() == [0.0, 1.0]


def test_session_phases_of_a_plain_events_table_are_a_usage_error(tmp_path):
    path = str(tmp_path / "e.arrows")
    tables.write(path, events([0, 9], [0, 5], [0, 1], 10, 10))
    code, stderr, _ = invoke(["frame", "--window", "10ms", "--phases", "session", "-o", str(tmp_path / "f.arrows"), path])
    assert one_line(stderr, code, 2) and "a plain events table has none" in stderr
    code, stderr, _ = invoke(["frame", "--window", "10ms", "--zero", "rest", "-o", str(tmp_path / "f.arrows"), path])
    assert one_line(stderr, code, 2) and "--zero rest reads the force log's rest level, and a plain events table has no log" in stderr


def test_frames_that_would_fill_a_disk_are_named_before_they_are_written(files, tmp_path, monkeypatch):  # noqa: F811
    from neurotac_cli.ops import frame

    monkeypatch.setattr(frame, "LARGE_OUTPUT_BYTES", 10)
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", str(tmp_path / "f.arrows"), f"{files}/r.arrows"])
    assert code == 0 and "counts make" in stderr and "pool the events first" in stderr
    monkeypatch.setattr(frame, "LARGE_OUTPUT_BYTES", 8 << 30)
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", str(tmp_path / "f.arrows"), f"{files}/r.arrows"])
    assert code == 0 and "counts make" not in stderr


def test_metadata_that_is_not_json_is_refused_at_the_door_and_a_negative_polarity_named(tmp_path):
    table = events([0, 9], [0, 5], [0, 1], 10, 10)
    path = str(tmp_path / "e.arrows")
    tables.write(path, table.replace_schema_metadata({**table.schema.metadata, b"neurotac:sync": b"garbage"}))
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", str(tmp_path / "f.arrows"), path])
    assert one_line(stderr, code, 1) and "metadata neurotac:sync is not valid JSON" in stderr
    signed = table.set_column(3, "p", pa.array([0, -1], pa.int8()))
    tables.write(path, signed)
    code, stderr, _ = invoke(["frame", "--window", "10ms", "-o", str(tmp_path / "f.arrows"), path])
    assert one_line(stderr, code, 1) and "polarity (column 'p') must be 0 (OFF) or 1 (ON)" in stderr


def test_frames_missing_inside_a_trial_are_named_by_eval_and_train_as_by_predict(files, tmp_path):  # noqa: F811
    import pyarrow.compute as pc

    table = tables.read([f"{files}/f.arrows"])
    first = table.column("trial")[0].as_py()
    gap = pc.and_(pc.equal(table.column("trial"), first), pc.equal(table.column("frame"), 2))
    path = str(tmp_path / "gap.arrows")
    tables.write(path, table.filter(pc.invert(gap)))
    for args in (["eval", "--model", f"{files}/m.model"], ["train", "--model", "tdnn", "--epochs", "1", "-o", str(tmp_path / "m.model")],
                 ["predict", "--model", f"{files}/m.model", "-o", str(tmp_path / "p.arrows")]):
        code, stderr, _ = invoke([*args, path])
        assert code == 0 and f"1 frame missing inside 1 trial ({first}: 1)" in stderr, (args, stderr)


def test_nonzero_with_nothing_left_to_score_or_with_a_classifier_is_refused(files, tmp_path):  # noqa: F811
    table = tables.read([f"{files}/f.arrows"])
    force = table.schema.get_field_index("force")
    path = str(tmp_path / "zero.arrows")
    tables.write(path, table.set_column(force, table.schema.field(force), pa.array(np.zeros(table.num_rows, np.float32))))
    code, stderr, _ = invoke(["eval", "--model", f"{files}/m.model", "--nonzero", path])
    assert one_line(stderr, code, 1) and "nothing is left to score" in stderr
    code, stderr, _ = invoke(["eval", "--model", f"{files}/c.model", "--nonzero", f"{files}/f.arrows"])
    assert one_line(stderr, code, 2) and "a classifier is scored on whole trials" in stderr
    from neurotac_cli import metrics

    rows = metrics.force_rows(["a"] * 3, ["none"] * 3, [0.0] * 3, [1.0] * 3, nonzero=True, whole=False)  # one fold of several
    assert ("all", "n", 0.0) in rows


def test_training_frames_that_do_not_record_their_window_are_named(files, tmp_path):  # noqa: F811
    table = tables.read([f"{files}/f.arrows"])
    path = str(tmp_path / "bare.arrows")
    tables.write(path, table.replace_schema_metadata({k: v for k, v in table.schema.metadata.items() if k != b"neurotac:window_us"}))
    code, stderr, _ = invoke(["train", "--model", "tdnn", "--epochs", "1", "-o", str(tmp_path / "m.model"), path])
    assert code == 0 and "the frames do not record their window" in stderr


def test_a_stream_cut_inside_its_end_marker_or_opening_with_one_is_named_so(files, tmp_path):  # noqa: F811
    data = open(f"{files}/f.arrows", "rb").read()
    for cut in (1, 4, 7):
        (tmp_path / "cut.arrows").write_bytes(data[:-cut])
        code, stderr, _ = invoke(["info", str(tmp_path / "cut.arrows")])
        assert one_line(stderr, code, 1) and "input ended mid-table" in stderr
    (tmp_path / "marker.arrows").write_bytes(data[-8:] + data)
    code, stderr, _ = invoke(["info", str(tmp_path / "marker.arrows")])
    assert one_line(stderr, code, 1) and "an end marker where its schema should be" in stderr


def test_a_parquet_force_log_s_typed_times_carry_their_unit_and_flags_are_no_force(tmp_path):
    import pyarrow.parquet as pq

    from neurotac_cli.io.force import read_force_log

    t = np.arange(20, dtype=np.int64) * 2
    pq.write_table(pa.table({"time": pa.array(t, pa.duration("ms")), "force": np.linspace(0, 1, 20)}), tmp_path / "d.parquet")
    (log,) = read_force_log(str(tmp_path / "d.parquet"), force_unit="N")
    assert log.t.tolist() == (t * 1000).tolist()
    pq.write_table(pa.table({"t_ms": t, "force_N": pa.array([True, False] * 10)}), tmp_path / "b.parquet")
    with pytest.raises(Exception, match="holds true/false flags, not forces"):
        read_force_log(str(tmp_path / "b.parquet"))


def test_a_table_stating_a_sensor_past_16_bit_coordinates_is_refused_at_the_door(tmp_path):
    table = events([0, 9], [0, 5], [0, 1], 10, 10)
    path = str(tmp_path / "e.arrows")
    tables.write(path, table.replace_schema_metadata(sch.set_meta(table.schema, sensor=sch.sensor_meta(100_000, 100_000)).metadata))
    code, stderr, _ = invoke(["export", "-o", str(tmp_path / "x.h5"), path])
    assert one_line(stderr, code, 1) and "metadata neurotac:sensor is" in stderr
    assert not (tmp_path / "x.h5").exists()


def test_force_times_that_one_microsecond_merges_name_the_unit(tmp_path):
    from neurotac_cli.errors import FormatError
    from neurotac_cli.io.force import read_force_log

    (tmp_path / "f.csv").write_text("t_ms,force_N\n" + "".join(f"{t},0\n" for t in range(0, 40, 2)))
    with pytest.raises(FormatError, match=r"0 and 2 ns round to one microsecond: is the unit ns\?"):
        read_force_log(str(tmp_path / "f.csv"), time_unit="ns")


def test_a_sensor_given_over_one_import_only_guessed_from_the_events_is_taken(tmp_path):
    (tmp_path / "ev.txt").write_text("".join(f"{t / 1e6:.6f} {t % 230} {t % 170} {t % 2}\n" for t in range(0, 5000)))
    path = str(tmp_path / "ev.arrows")
    code, stderr, _ = invoke(["import", "-o", path, str(tmp_path / "ev.txt")])
    assert code == 0, stderr
    out = str(tmp_path / "f.arrows")
    code, stderr, _ = invoke(["frame", "--window", "1ms", "--sensor", "240x180", "-o", out, path])
    assert code == 0, stderr
    framed = tables.read([out])
    assert sch.sensor_of(framed.schema) == (240, 180) and sch.camera_source(framed.schema)["sensor_from"] == "option"


def test_concat_refuses_frames_pooled_differently_though_their_shapes_agree(tmp_path):
    table = frames_table()

    def made(pool):
        history = [{"command": "frame", "args": {"window_us": 10_000, "dtype": "uint16"}}, {"command": "crop", "args": {"pool": list(pool)}}]
        return table.replace_schema_metadata(sch.set_meta(table.schema, history=history).metadata)

    tables.write(str(tmp_path / "a.arrows"), made((6, 6)))
    tables.write(str(tmp_path / "b.arrows"), made((3, 3)))
    code, stderr, _ = invoke(["concat", "--rename", "-o", str(tmp_path / "ab.arrows"), str(tmp_path / "a.arrows"), str(tmp_path / "b.arrows")])
    assert one_line(stderr, code, 1) and "was pooled 3x3" in stderr and "6x6" in stderr
    tables.write(str(tmp_path / "c.arrows"), made((6, 6)))
    code, stderr, _ = invoke(["concat", "--rename", "-o", str(tmp_path / "ac.arrows"), str(tmp_path / "a.arrows"), str(tmp_path / "c.arrows")])
    assert code == 0, stderr


def test_an_hdf5_export_of_events_a_clock_jump_apart_is_refused_and_a_long_span_stays_small(tmp_path):
    t = np.array([0, 10, 40 * 86_400_000_000])  # 40 days apart
    path = str(tmp_path / "e.arrows")
    tables.write(path, sch.events_table(t, np.zeros(3, int), np.zeros(3, int), np.zeros(3, int), 8, 8))
    code, stderr, _ = invoke(["export", "-o", str(tmp_path / "x.h5"), path])
    assert one_line(stderr, code, 1) and "the events span 40.0 days" in stderr
    assert not any(p.name.startswith("x.h5") for p in tmp_path.iterdir())
    tables.write(path, sch.events_table(np.array([0, 10, 3 * 3_600_000_000]), np.zeros(3, int), np.zeros(3, int), np.zeros(3, int), 8, 8))
    code, stderr, _ = invoke(["export", "-o", str(tmp_path / "y.h5"), path])
    assert code == 0, stderr
    assert (tmp_path / "y.h5").stat().st_size < 2_000_000  # 10.8 million ms_to_idx entries, compressed


@pytest.mark.parametrize("condition, mark", [("frame < 3 /*", "/*"), ("frame < 3 -- note", "--"), ("frame < 3; drop", ";")])
def test_a_condition_that_cuts_its_query_names_the_mark_that_cuts_it(files, condition, mark):  # noqa: F811
    code, stderr, _ = invoke(["select", "--where", condition, f"{files}/f.arrows"])
    assert one_line(stderr, code, 1) and f"a condition cannot hold `{mark}`" in stderr and "not a condition on each row" not in stderr


def test_a_condition_on_columns_sql_cannot_tell_apart_is_refused_and_the_row_index_never_clashes():
    """DuckDB reads names blind to case and renamed a second `Material` (`Material_1`), so a condition
    on it read `material` and kept every row; a user column named like the row index ordered the
    answer by itself (frames 34-36 kept for 0-2)."""
    from neurotac_cli.errors import NeurotacError
    from neurotac_cli.ops.rows import ROW_INDEX, select
    from tests.model.helpers import tiny_frames

    frames = tiny_frames(trials=3)
    cased = frames.append_column("Material", pa.array(["X"] * frames.num_rows))
    with pytest.raises(NeurotacError, match="differ only in case"):
        select(cased, "\"Material\" = 'steel'")
    assert select(cased, "frame < 3")[1]["kept"] == 9  # a condition that names neither still runs
    both_t = frames.append_column("T", pa.array(["warm"] * frames.num_rows))  # `t` and `T`; "material" holds a t
    assert select(both_t, "material = 'steel' OR frame < 3")[1]["kept"] > 0
    shadow = frames.append_column(ROW_INDEX, pa.array([f"{frames.num_rows - k:04d}" for k in range(frames.num_rows)]))
    kept = select(shadow, "frame < 3")[0]
    assert sorted(set(kept.column("frame").to_pylist())) == [0, 1, 2]


def test_concat_rename_renames_the_sources_of_augmented_copies_and_split_per_needs_a_trial_label():
    """`concat --rename` renamed a clashing trial but not the `source_trial` of its copies, which then
    named the other table's grasp; `split --per force` stratified by each trial's last row."""
    import pyarrow.compute as pc

    from neurotac_cli.errors import SchemaError, UsageError
    from neurotac_cli.ops.rows import concat, split
    from tests.model.helpers import tiny_frames

    frames = tiny_frames(trials=2, augmented_copies=1)
    table, _ = concat([("a", frames), ("b", frames)], rename=True)
    pairs = set(zip(table.column("trial").to_pylist(), table.column("source_trial").to_pylist()))
    later = {(trial, source) for trial, source in pairs if trial.endswith("~2")}
    assert later and all(source.endswith("~2") for _, source in later), pairs
    plain = tiny_frames(trials=1)
    both = concat([("x", plain), ("y", plain)], rename=True)[0]  # t0 and t0~2
    joined = concat([("a", plain), ("b", both)], rename=True)[0]  # b's t0 may not become the t0~2 b holds
    assert len(set(joined.column("trial").to_pylist())) == 3
    copies = tiny_frames(trials=2, augmented_copies=1)
    only = copies.filter(pc.not_equal(copies.column("trial"), copies.column("source_trial")))
    with pytest.raises(SchemaError, match="its source 't0' is not in b"):  # whose grasp: a's t0, or another's?
        concat([("a", copies), ("b", only)], rename=True)
    with pytest.raises(UsageError, match="force differs within trial"):
        split(tiny_frames(trials=4), fraction=0.5, per="force")


def test_concat_joins_metrics_tables(tmp_path):
    metrics = pa.table({"scope": ["all"], "metric": ["rmse"], "value": [0.1]})
    metrics = metrics.replace_schema_metadata(sch.set_meta(metrics.schema, kind="metrics").metadata)
    for name in ("m1", "m2"):
        tables.write(str(tmp_path / f"{name}.arrows"), metrics)
    code, stderr, _ = invoke(["concat", str(tmp_path / "m1.arrows"), str(tmp_path / "m2.arrows"), "-o", str(tmp_path / "m.arrows")])
    assert code == 0 and tables.read([str(tmp_path / "m.arrows")]).num_rows == 2, stderr


def test_noise_of_counts_is_not_added_to_scaled_frames_nor_a_tes_that_moves_nothing_kept(tmp_path):
    """`augment --noise` added raw counts to frames scaled by `frame --dtype float32` (their maximum 1.0
    became 5.2) without a word; `--tes 1 1e-9` moved no event and wrote copies equal to their sources."""
    counted = frames_table()
    history = lambda dtype: sch.set_meta(counted.schema, history=[{"command": "frame", "args": {"dtype": dtype}}]).metadata  # noqa: E731
    tables.write(str(tmp_path / "noise.arrows"), counted.replace_schema_metadata(history("uint16")))
    tables.write(str(tmp_path / "scaled.arrows"), counted.replace_schema_metadata(history("float32")))
    code, stderr, _ = invoke(["augment", "--noise", str(tmp_path / "noise.arrows"), str(tmp_path / "scaled.arrows")])
    assert one_line(stderr, code, 1) and "frame both alike" in stderr
    pooled = sch.set_meta(counted.schema, history=[{"command": "crop", "args": {"pool": [2, 2]}}]).metadata
    tables.write(str(tmp_path / "pooled.arrows"), counted.replace_schema_metadata(pooled))  # the same frame size, pooled
    code, stderr, _ = invoke(["augment", "--noise", str(tmp_path / "pooled.arrows"), str(tmp_path / "noise.arrows")])
    assert one_line(stderr, code, 1) and "the noise table was pooled 2x2" in stderr
    code, stderr, _ = invoke(["augment", "--tes", "1", "1e-9", str(tmp_path / "noise.arrows")])
    assert one_line(stderr, code, 1) and "moved no event" in stderr


def test_a_background_rate_no_camera_has_is_refused_before_it_fills_the_memory():
    code, stderr, _ = invoke(["simulate", "--trials", "1", "--synced", "--background-rate", "2e4"])
    assert one_line(stderr, code, 2) and "background_rate_hz must be in [0, 50]" in stderr


def test_study_refuses_nonzero_for_a_classifier_as_eval_does(tmp_path):
    tables.write(str(tmp_path / "f.arrows"), frames_table())
    code, stderr, _ = invoke(["study", "--model-spec", "material-dnn", "--cv", "kfold:2", "--nonzero", str(tmp_path / "f.arrows")])
    assert one_line(stderr, code, 2) and "a classifier is scored on whole trials" in stderr


def test_info_on_a_file_of_no_known_format_names_the_verb_that_has_format(tmp_path):
    (tmp_path / "zeros").write_bytes(bytes(4096))
    code, stderr, _ = invoke(["info", str(tmp_path / "zeros")])
    assert one_line(stderr, code, 1) and "`neurotac import --format`" in stderr


@pytest.mark.parametrize("call, words", [
    (lambda api, fr, ev: api.simulate("ch4", trials=1, on_threshold="0.3"), "on_threshold must be a number"),
    (lambda api, fr, ev: api.simulate("ch4", trials=1, sensor_width=240.5), "sensor_width must be a whole number"),
    (lambda api, fr, ev: api.simulate("ch4", trials=1, contact_delay_us=5), "contact_delay_us must be a tuple of 2 numbers"),
    (lambda api, fr, ev: api.frame(ev, "10ms", start_us=0.5), "start_us must be a whole number"),
    (lambda api, fr, ev: api.augment(fr, api.Noise("c.arrows")), "Noise takes a tuple"),
    (lambda api, fr, ev: api.augment(fr, api.Noise((np.full((3, 2, 8, 8), -5),))), "finite and not negative"),
    (lambda api, fr, ev: api.augment(fr, api.Noise((np.ones((3, 2, 4, 4), np.uint16),))), "noise frames are 4x4"),
    (lambda api, fr, ev: api.write(fr, "w.arrows", step="x"), "step must be"),
    (lambda api, fr, ev: api.from_tonic(np.array([(np.nan, 1, 1, 1)], dtype=[("t", "f8"), ("x", "i4"), ("y", "i4"), ("p", "i1")]),
                                        (8, 8, 2)), "not whole numbers"),
])
def test_the_library_refuses_values_of_the_wrong_type_with_its_own_error(tmp_path, monkeypatch, call, words):
    """Each raised TypeError or ValueError from deep inside, or changed a value without a word."""
    import neurotac_cli.api as api

    monkeypatch.chdir(tmp_path)
    events = sch.events_table(np.arange(4), np.array([1, 2, 3, 4]), np.array([1, 1, 2, 2]), np.array([0, 1, 0, 1]), 8, 8)
    with pytest.raises(api.NeurotacError, match=words):
        call(api, frames_table(), events)


def test_a_session_held_from_start_to_end_is_said_and_a_table_named_model_is_described(tmp_path):
    """`frame --phases session` labelled a log held at 2.5 N throughout as rest without a word (with
    `--zero rest` it warned); `info` refused an Arrow table named `t.model` as a broken model."""
    from neurotac_cli.ops.frame import Framing, _force_labels, _LabelDoubts

    doubts = _LabelDoubts(Framing(window_us=10_000, phases="session"))
    held = (2.5 + np.random.default_rng(1).normal(0, 0.02, 3000)).astype(np.float32)
    _force_labels(Framing(window_us=10_000, phases="session"), doubts, "s", held, True, held.size, held.size)
    assert any("found no grasp in 1 trial whose force rests far from the log's zero (s: +2.5" in n for n in doubts.notes())
    tables.write(str(tmp_path / "t.arrows"), frames_table())
    (tmp_path / "t.model").write_bytes((tmp_path / "t.arrows").read_bytes())
    code, stderr, output = invoke(["info", str(tmp_path / "t.model")])
    assert code == 0 and "frames" in output, stderr


def test_a_force_log_of_dates_is_named_so_by_info_and_sync(tmp_path):
    """A log of ISO timestamps: `info` said it read fine "as `sync --force` reads it", and `sync`
    refused it as not overlapping at 1.70411e+09 s."""
    rows = [f"2024-01-01T12:00:{k * 2 // 1000:02d}.{k * 2 % 1000:03d}000,{0.1 + 0.01 * (k % 3)}" for k in range(200)]
    (tmp_path / "iso.csv").write_text("time,force_N\n" + "\n".join(rows) + "\n")
    code, stderr, output = invoke(["info", str(tmp_path / "iso.csv")])
    assert code == 0 and "its times are dates (from 2024-01-01 12:00:00 UTC)" in output, stderr
    events = sch.events_table(np.arange(0, 400_000, 100), np.zeros(4000, np.uint16), np.zeros(4000, np.uint16),
                              np.ones(4000, np.uint8), 8, 8)
    tables.write(str(tmp_path / "e.arrows"), events)
    code, stderr, _ = invoke(["sync", str(tmp_path / "e.arrows"), "--force", str(tmp_path / "iso.csv"), "--method", "offset",
                              "--offset", "0us"])
    assert one_line(stderr, code, 1) and "its times are dates" in stderr, stderr
