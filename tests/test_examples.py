"""The reproduction scripts' helpers: results pages written beside the thesis's numbers without
touching anyone else's section, and the frames tool; every script parses, and chapter 3's runs end
to end at a tiny size."""

import importlib.util
import pathlib
import re
import subprocess
import sys

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


def load(name):
    # the example scripts import each other (`from chapters import ...`), as when run from examples/
    if str(EXAMPLES) not in sys.path:
        sys.path.insert(0, str(EXAMPLES))
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_metrics(path, rows):
    scopes, metrics, values = zip(*rows)
    pq.write_table(
        pa.table({"scope": list(scopes), "metric": list(metrics), "value": list(values), "model": ["m"] * len(rows)}),
        path,
    )


def force_rows(mse, val_mse=None):
    rows = [("all", "mse", mse), ("all", "mse_fold_mean", mse), ("all", "mse_fold_sd", mse / 2), ("all", "mae", mse / 2)]
    if val_mse is not None:
        rows += [("all", "val_mse_fold_mean", val_mse), ("all", "val_mse_fold_sd", val_mse / 4)]
    for phase in ("grasping", "holding", "releasing"):
        rows += [(f"phase:{phase}", "mse", mse), (f"phase:{phase}", "dtw_fold_mean", 1.0)]
    return rows


PAGE = """# Reproduced results

intro kept as written

<!-- results:ch3:start -->
old
<!-- results:ch3:end -->

<!-- results:models:start -->
engineer E's table, not ours
<!-- results:models:end -->
"""


def test_chapter3_tables_sit_beside_the_thesis_and_leave_other_sections_alone(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch3"
    folder.mkdir()
    for k, n, mse in ((1, 5, 0.4), (1, 40, 0.3), (4, 5, 0.25), (4, 40, 0.2)):
        write_metrics(folder / f"tdnn@layers={k},units={n}.metrics.parquet", force_rows(mse))
    write_metrics(folder / "gp.metrics.parquet", force_rows(0.22))
    write_metrics(folder / "material-dnn@layers=2,units=30.metrics.parquet", [("all", "accuracy", 0.75), ("class:steel", "recall", 1.0)])
    write_metrics(folder / "material-force.metrics.parquet", [("all", "accuracy", 0.5)])
    write_metrics(folder / "material-timing.metrics.parquet", [("all", "accuracy", 0.97)] +
                  [(f"class:{c}", "recall", r) for c, r in (("foam", 1.0), ("rubber", 0.95), ("silicone", 1.0), ("steel", 0.9))])
    page = tmp_path / "results.md"
    page.write_text(PAGE)

    results.main(["ch3", str(folder), str(page), "--run", "Run: test."])
    text = page.read_text()
    assert "intro kept as written" in text and "engineer E's table, not ours" in text
    assert "\nold\n" not in text
    assert "| k=4 | 0.250 (0.180) | **0.200** (0.160) |" in text  # ours (thesis Table 3.2), our lowest in bold
    assert "| k=1 | 0.400 (0.160) | 0.300 (*0.150*) |" in text  # the thesis's lowest of the cells shown
    assert "Lowest: k=4, n=40: 0.200" in text
    assert "| material-dnn (k=2, n=30), events | 75.0 | – | 79.17 |" in text
    assert "25.0 points above the force-only classifier" in text
    assert "our material-timing reaches 97.0%, its lowest recall steel 90.0%" in text
    assert "](" not in text and "\n\n\n" not in text  # figures not drawn: no link and no gap where they would be

    results.main(["ch3", str(folder), str(page), "--run", "Run: test."])
    assert page.read_text() == text  # idempotent


def test_a_missing_section_is_appended_with_its_markers(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch4"
    folder.mkdir()
    for model, mse in (("lstm", 0.3), ("convlstm", 0.2), ("deform-gru", 0.05)):
        write_metrics(folder / f"{model}.metrics.parquet", force_rows(mse))
    write_metrics(folder / "heldout.metrics.parquet", force_rows(0.4))
    page = tmp_path / "page.md"
    results.main(["ch4", str(folder), str(page)])
    text = page.read_text()
    assert text.count("<!-- results:ch4:start -->") == 1 and "<!-- results:ch4:end -->" in text
    assert "our models rank convlstm < lstm (thesis: convlstm < lstm)" in text
    assert "2.0× its leave-one-out error" in text
    assert "ours (deform-gru) scores 0.050 N², 0.2× the best of the thesis's models here (convlstm)" in text


def test_chapter5_orders_methods_and_draws_its_figures(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch5"
    folder.mkdir()
    for name, mse in (("none", 8.0), ("fs-1", 5.5), ("fs1", 7.0), ("tes-2_0.5", 6.0), ("tes-1_0.25", 6.5), ("hybrid", 7.5)):
        write_metrics(folder / f"{name}.metrics.parquet", [("all", "mse_fold_mean", mse), ("all", "mse_fold_sd", 0.5)])
    page = tmp_path / "page.md"
    results.main(["ch5", str(folder), str(page), "--figures", str(tmp_path / "fig")])
    text = page.read_text()
    methods = [line.split("|")[1].strip() for line in text.splitlines() if line.startswith("| ") and "N²" not in line]
    assert methods == ["No augmentation", "FS-1", "FS+1", "TES-2(0.50)", "TES-1(0.25)", "Resize + FS-1, hybrid"]
    assert "| FS-1 | 5.500 | 0.500 | 0 | -31% | 5.51 (0.41) |" in text
    assert (tmp_path / "fig" / "ch5-methods.png").is_file() and (tmp_path / "fig" / "ch5-tes.png").is_file()


def test_every_table_carries_the_protocol_line(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch4"
    folder.mkdir()
    for model, mse in (("lstm", 0.3), ("convlstm", 0.2)):
        write_metrics(folder / f"{model}.metrics.parquet", force_rows(mse))
    page = tmp_path / "page.md"
    results.main(["ch4", str(folder), str(page), "--protocol", "Protocol: pooled 4x4, 5 seeds. Wall time 9 s."])
    lines = page.read_text().splitlines()
    headings = [i for i, line in enumerate(lines) if line.startswith("#### ")]
    assert len(headings) >= 3
    assert all(lines[i + 2] == "*Protocol: pooled 4x4, 5 seeds. Wall time 9 s.*" for i in headings)


def test_held_out_size_table_lists_every_model_with_its_spread_over_seeds(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch4"
    folder.mkdir()
    for model, mse in (("convlstm", 0.4), ("deform-gru", 0.03)):
        seeds = [(f"fold:{r}/0", "mse", mse * (1 + r)) for r in range(2)] + [(f"fold:{r}/0", "n", 100.0) for r in range(2)]
        write_metrics(folder / f"heldout-{model}.metrics.parquet", force_rows(mse) + seeds)
    page = tmp_path / "page.md"
    results.main(["ch4", str(folder), str(page)])
    text = page.read_text()
    assert "| convlstm | 0.400 | 0.600 ± 0.283 | 0.200 | – | 0.159 | 0.385 |" in text
    assert "| deform-gru | 0.030 | 0.045 ± 0.021 | 0.015 | – | – | – |" in text


def test_chapter5_sets_deform_gru_beside_the_convlstm_on_each_training_set(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch5"
    folder.mkdir()
    for name, mse, ours in (("none", 8.0, 1.0), ("fs-1", 5.5, 1.2)):
        write_metrics(folder / f"{name}.metrics.parquet", [("all", "mse_fold_mean", mse), ("all", "mse_fold_sd", 0.5)])
        write_metrics(folder / f"deform-gru@set={name}.metrics.parquet", [("all", "mse_fold_mean", ours), ("all", "mse_fold_sd", 0.1)])
    page = tmp_path / "page.md"
    results.main(["ch5", str(folder), str(page), "--figures", str(tmp_path / "fig")])
    text = page.read_text()
    assert "| FS-1 | 5.500 | 0.500 | 0 | -31% | 5.51 (0.41) | 1.200 | 0.100 | +20% |" in text
    assert "0 of 1 methods lower its error" in text


def shell_paths(**env):
    """OUT, RESULTS and FIGURES as lib.sh sets them, or its exit status and stderr when it refuses."""
    import os

    script = f'source "{EXAMPLES}/lib.sh"; echo "$OUT"; echo "$RESULTS"; echo "$FIGURES"'
    return subprocess.run(["bash", "-c", script], capture_output=True, text=True, env={**os.environ, **env})


def test_a_quick_run_writes_under_examples_only(tmp_path):
    done = shell_paths(MODE="quick", OUT=str(tmp_path / "q"))
    assert done.returncode == 0
    assert done.stdout.split() == [str(tmp_path / "q"), str(tmp_path / "q" / "results.md"), str(tmp_path / "q" / "figures")]
    default = shell_paths(MODE="quick")
    assert all(pathlib.Path(path).resolve().is_relative_to(EXAMPLES) for path in default.stdout.split())


@pytest.mark.parametrize("target", ["RESULTS", "FIGURES", "OUT", "NEUROTAC_CACHE"])
def test_a_quick_run_cannot_write_into_docs(tmp_path, target):
    docs = EXAMPLES.parent / "docs"
    before = sorted((path, path.stat().st_mtime_ns) for path in docs.rglob("*"))
    where = docs / "results.md" if target == "RESULTS" else docs / "x" / ".." / "results"
    done = shell_paths(MODE="quick", **{"OUT": str(tmp_path / "q"), target: str(where)})
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "error: a quick run cannot write to" in done.stderr
    assert sorted((path, path.stat().st_mtime_ns) for path in docs.rglob("*")) == before
    standard = shell_paths(MODE="standard", OUT=str(tmp_path / "s"))
    assert standard.stdout.split()[1] == str(EXAMPLES / ".." / "docs" / "results.md")


def test_frames_tool_selects_by_label_and_stacks_originals_with_copies(tmp_path):
    tool = load("frames_tool")
    schema = pa.schema([("trial", pa.string()), ("object", pa.string())], metadata={b"neurotac:kind": b'"frames"'})
    pq.write_table(pa.table({"trial": ["a", "b"], "object": ["bolt12", "bolt18"]}, schema=schema), tmp_path / "f.parquet")
    tool.select(tmp_path / "f.parquet", tmp_path / "small.parquet", "object=bolt12")
    small = pq.read_table(tmp_path / "small.parquet")
    assert small.column("trial").to_pylist() == ["a"] and small.schema.metadata == schema.metadata
    copies = pa.table({"trial": ["a~fs#1"], "object": ["bolt12"], "source_trial": ["a"], "augment": ["fs(-1)"]})
    pq.write_table(copies, tmp_path / "copies.parquet")
    tool.concat(tmp_path / "all.parquet", [tmp_path / "f.parquet", tmp_path / "copies.parquet"])
    stacked = pq.read_table(tmp_path / "all.parquet")
    assert stacked.column("source_trial").to_pylist() == ["a", "b", "a"]
    assert stacked.column("augment").to_pylist() == ["", "", "fs(-1)"]


@pytest.mark.parametrize("script", ["lib.sh", "ch3.sh", "ch4.sh", "ch5.sh"])
def test_the_chapter_scripts_parse(script):
    done = subprocess.run(["bash", "-n", str(EXAMPLES / script)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def cache_line(folder, finished: float) -> str:
    """The line `eval --cv` prints on taking tasks from a study cache whose entries finished at `finished` (epoch s)."""
    import os

    from neurotac_cli.study import _Cache

    cache, keys = _Cache(folder), ["a" * 32, "b" * 32]
    for key in keys:
        cache.path(key).parent.mkdir(parents=True, exist_ok=True)
        cache.path(key).write_bytes(b"")
        os.utime(cache.path(key), (finished, finished))
    return cache.told(keys, 5, "tdnn folds")


EARLIER, LATER = 946684800.0, 32503680000.0  # 2000 and 2999: before and after any run of these tests


@pytest.mark.parametrize("finished, marked", [(EARLIER, True), (LATER, False)])
def test_a_study_s_seconds_are_marked_only_when_it_took_an_earlier_run_s_tasks_from_the_cache(tmp_path, finished, marked):
    # neurotac stands in as a shell function that prints, as `eval --cv` does, the line of the tasks it took from the cache
    line = cache_line(tmp_path / "cache", finished)
    script = f'''
        MODE=tiny OUT={tmp_path} source {EXAMPLES / "lib.sh"}
        DIR={tmp_path}
        neurotac() {{ echo "{line}" >&2; }}
        study one --cv loo
        wall_time
    '''
    done = subprocess.run(["bash", "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert ("cached" in (tmp_path / "one.seconds").read_text()) == marked
    assert ("1 of them took tasks from the cache of an earlier run" in done.stdout) == marked


@pytest.mark.slow
def test_the_chapter_3_script_runs_end_to_end_at_a_tiny_size(tmp_path):
    """Simulate, sync, frame, crop, the TDNN and DNN grids, the GP, the figures and the results page:
    every step of examples/ch3.sh, with one grid point, two epochs and two folds."""
    import os

    env = dict(os.environ, MODE="tiny", OUT=str(tmp_path), NEUROTAC_JOBS="1")
    env.pop("NEUROTAC_SCHEDULER", None)
    env.pop("NEUROTAC_CACHE", None)
    done = subprocess.run(["bash", str(EXAMPLES / "ch3.sh")], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    page = (tmp_path / "results.md").read_text()
    assert "<!-- results:ch3:start -->" in page and "<!-- results:ch3:end -->" in page
    assert "| k=1 | **" in page and "| gp | " in page
    for figure in ("ch3-tdnn.png", "ch3-gp.png", "ch3-confusion.png"):
        assert (tmp_path / "figures" / figure).stat().st_size > 0
    for study in ("tdnn", "gp", "material-dnn", "material-force"):
        assert (tmp_path / "ch3" / f"{study}.metrics.parquet").stat().st_size > 0
    assert "from the cache" not in page

    # A study run again over the cache: its seconds leave the cached tasks out, and the page says so.
    (tmp_path / "ch3" / "material-force.metrics.parquet").unlink()
    done = subprocess.run(["bash", str(EXAMPLES / "ch3.sh")], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "cached" in (tmp_path / "ch3" / "material-force.seconds").read_text()
    assert "(1 of them took tasks from the cache of an earlier run" in (tmp_path / "results.md").read_text()


def test_a_grid_held_in_one_table_is_read_by_its_parameter_columns(tmp_path):
    results = load("chapters")
    table = pa.table({
        "scope": ["all"] * 4, "metric": ["mse_fold_mean"] * 4, "value": [0.4, 0.3, 0.2, 0.1], "model": ["tdnn"] * 4,
        "layers": [1, 1, 2, 2], "units": [5, 10, 5, 10],
    })
    pq.write_table(table, tmp_path / "tdnn.metrics.parquet")
    points = results.grid(results.studies(tmp_path), "tdnn")
    assert {key: results.get(f, "all", "mse_fold_mean") for key, f in points.items()} == {
        (1, 5): 0.4, (1, 10): 0.3, (2, 5): 0.2, (2, 10): 0.1}


def test_chapter3_validation_table_marks_the_lowest_beside_thesis_table_3_1(tmp_path):
    results = load("chapters")
    folder = tmp_path / "ch3"
    folder.mkdir()
    for k, n, val in ((1, 5, 0.5), (1, 40, 0.45), (4, 5, 0.35), (4, 40, 0.6)):
        write_metrics(folder / f"tdnn@layers={k},units={n}.metrics.parquet", force_rows(0.3, val_mse=val))
    page = tmp_path / "results.md"
    results.main(["ch3", str(folder), str(page), "--run", "Run: test."])
    text = page.read_text()
    assert "TDNN validation error, k layers × n units (thesis Table 3.1)" in text
    assert "| k=4 | **0.350** (0.200) | 0.600 (*0.150*) |" in text
    assert "Lowest validation error: k=4, n=5: 0.350 N² (thesis: k=4, n=40, 0.15)" in text


def test_chapter4_layer_sweep_table_and_figure(tmp_path):
    results = load("chapters")
    folder, figures = tmp_path / "ch4", tmp_path / "figures"
    folder.mkdir()
    for model, values in (("convlstm", (0.5, 0.3, 0.4)), ("lstm", (0.6, 0.7, 0.2))):
        table = pa.table({
            "scope": ["all"] * 9, "metric": ["val_mse_fold_mean", "val_mse_fold_sd", "mse"] * 3,
            "value": [v for value in values for v in (value, value / 10, 2 * value)], "model": [model] * 9,
            "layers": [1, 1, 1, 2, 2, 2, 4, 4, 4], "epochs": [4] * 9,
        })
        pq.write_table(table, folder / f"sweep-{model}.metrics.parquet")
    page = tmp_path / "results.md"
    results.main(["ch4", str(folder), str(page), "--figures", str(figures), "--run", "Run: test."])
    text = page.read_text()
    assert "(thesis Fig. 4.4(a))" in text
    assert "| 2 | **0.300 ± 0.030** | 0.600 | 0.700 ± 0.070 | 1.400 |" in text
    assert "convlstm 2 layers (thesis 4), lstm 4 layers (thesis 6)" in text
    assert (figures / "ch4-layers.png").stat().st_size > 1000 and "ch4-layers.png" in text


def test_models_section_is_written_once_under_one_heading(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))  # results.py renders with chapters.py's helpers
    results = load("results")
    monkeypatch.setattr(results, "ROOT", tmp_path)
    (tmp_path / "docs").mkdir()
    page = tmp_path / "docs" / "results.md"
    page.write_text(PAGE)
    results.write_section(["### Latency", "", results.md_table(["model", "p50 ms"], [["deform-gru", "0.59"]]), ""])
    text = page.read_text()
    assert "engineer E's table" not in text and "\nold\n" in text  # only its own section replaced
    assert "<!-- results:models:start -->\n### Latency\n\n| model | p50 ms |\n|---|---|\n| deform-gru | 0.59 |\n<!-- results:models:end -->" in text
    page.write_text("# Reproduced results\n")
    results.write_section(["### Latency"])
    results.write_section(["### Latency"])
    text = page.read_text()
    assert text.count("## Models of this toolkit against the thesis's") == 1 and text.count("### Latency") == 1


def test_results_counts_the_nonzero_frames_of_each_phase_per_grasp(tmp_path, monkeypatch):
    """The note under the D_B table rests on these counts: frames of zero force are not counted."""
    monkeypatch.syspath_prepend(str(EXAMPLES))
    results = load("results")
    table = pa.table({
        "trial": ["a"] * 6 + ["b"] * 4,
        "phase": ["none", "grasping", "holding", "holding", "releasing", "releasing", "grasping", "grasping", "holding", "releasing"],
        "force": [0.0, 1.0, 2.0, 2.1, 0.5, 0.0, 0.4, 1.2, 2.0, 0.3],
    })
    path = tmp_path / "f.arrows"
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_stream(sink, table.schema) as writer:
        writer.write_table(table)
    counts = results.phase_frames(path)
    assert counts == {"grasping": (1, 1.5, 2), "holding": (1, 1.5, 2), "releasing": (1, 1, 1)}
    line = results.d_b_caveat(counts)[0]
    assert line.startswith("Non-zero frames per grasp (min-median-max): grasping 1-1.5-2, holding 1-1.5-2, releasing 1-1-1.")
    assert "in the grasping, holding and releasing phases it rests on at most 2 values" in line and "0.0001 N² floor" in line
    assert "D_B fits" not in results.d_b_caveat({"holding": (22, 25, 29)})[0]


def test_only_a_sessions_run_at_the_goals_size_is_published(tmp_path):
    sessions = load("sessions")
    parse = lambda *words: sessions.argparse.Namespace(  # noqa: E731
        quick="--quick" in words, epochs="convlstm=2" if "--epochs" in words else None,
        train_sessions=1 if "--train-sessions" in words else None, train_grasps=None, test_sessions=None,
        models="deform-gru" if "--models" in words else ",".join(sessions.MODELS),
        randomised_models="" if "--randomised-models" in words else sessions.RANDOMISED_MODELS)
    assert sessions.publishes(parse())
    assert not sessions.publishes(parse("--quick"))
    assert not sessions.publishes(parse("--epochs"))
    assert not sessions.publishes(parse("--train-sessions"))
    assert not sessions.publishes(parse("--models"))  # the table would lose the other models' rows
    assert not sessions.publishes(parse("--randomised-models"))
    page = tmp_path / "results.md"
    page.write_text("# Reproduced results\n\n## Chapter 3\n\nkept\n")
    sessions.publish("| model | RMSE |\n|---|---|\n| deform-gru | 0.5 |\n", str(page))
    sessions.publish("| model | RMSE |\n|---|---|\n| deform-gru | 0.4 |\n", str(page))
    text = page.read_text()
    assert "kept" in text and text.count("## Sessions of many grasps") == 1
    assert "| deform-gru | 0.4 |" in text and "0.5" not in text
    assert sessions.publishes(parse("--models"), fewer_allowed=True)
    assert not sessions.publishes(parse("--models", "--quick"), fewer_allowed=True)
    assert sessions.published(str(page)) == "| model | RMSE |\n|---|---|\n| deform-gru | 0.4 |\n"


def test_the_constant_reading_is_the_training_contacts_mean_and_ignores_rest():
    sessions = load("sessions")
    table = lambda force, phase: pa.table({"force": pa.array(force, pa.float64()), "phase": pa.array(phase, pa.string())})  # noqa: E731
    train = table([0.0, 1.0, 3.0, None, 9.0], ["none", "grasping", "holding", "none", None])
    test = table([1.0, 3.0, 5.0, 0.0], ["holding", "holding", "releasing", "none"])
    mean, rmse = sessions.constant_rmse(train, test)
    assert mean == 2.0 and rmse == pytest.approx(((1 + 1 + 9) / 3) ** 0.5)


def test_a_sessions_run_of_fewer_models_replaces_only_their_rows():
    sessions = load("sessions")
    old = "Test: 2 sessions.\n\n| model | RMSE |\n|---|---|\n| deform-gru | 0.5 |\n| lstm | 0.6 |\n\nUnseen.\n\n" \
          "| model | % |\n|---|---|\n| deform-gru | 40 |\n| lstm, randomised | 19 |\n"
    new = "Test: 2 sessions.\n\n| model | RMSE |\n|---|---|\n| deform-gru | 0.4 |\n\nUnseen.\n\n" \
          "| model | % |\n|---|---|\n| deform-gru | 39 |\n"
    merged = sessions.merged_rows(old, new)
    assert merged == old.replace("| deform-gru | 0.5 |", "| deform-gru | 0.4 |").replace("| deform-gru | 40 |", "| deform-gru | 39 |")
    with pytest.raises(SystemExit, match="other sessions"):
        sessions.merged_rows(old, new.replace("2 sessions", "1 session"))
    with pytest.raises(SystemExit, match="one model in two rows"):
        sessions.merged_rows(old.replace("| lstm | 0.6 |", "| deform-gru | 0.6 |"), new)
    with pytest.raises(SystemExit, match="no row for convlstm"):
        sessions.merged_rows(old, new.replace("| deform-gru | 39 |", "| deform-gru | 39 |\n| convlstm | 21 |"))


def test_a_quick_rig_sessions_run_prints_its_tables_and_leaves_docs_alone(tmp_path, monkeypatch):
    rigs = load("rig_sessions")
    slip = {"slip_f1": 0.5, "slip_hits": 1, "slip_true": 2, "slip_found": 2, "slip_within_20": 1.0}
    session = {"contact_rmse": 0.2, "rest_mean_abs": 0.01, "drift_n_per_min": 0.001, "contact_f1": 1.0, "slip_f1": 0.5}

    def one_rig(seed, out, grasps, model, epochs):
        return seed, {"about": f"physics {seed}", "range": 4.0, "session": session, "cut": dict(session, contact_rmse=0.19),
                      "detection": {"press": 800.0, "bar": 40.0, "on_bar": 12.5, "fixed": slip, "scaled": dict(slip, slip_f1=1.0),
                                    "contact": {"contact_f1": 1.0}}}

    monkeypatch.setattr(rigs, "one_rig", one_rig)
    published = []
    monkeypatch.setattr(rigs, "publish", published.append)
    rigs.main(["--quick", "--model", "deform-gru", "--jobs", "1", "--out", str(tmp_path)])
    text = (tmp_path / "rig_sessions.md").read_text()
    assert "| 201 | physics 201 | 800 | 40 / 12.5 | 0.50 | 1.00 | 1.00 | 1.00 | 2 | 1.00 |" in text
    assert "| 211 | 5.0 | 1.05 |" in text
    assert "rigs that took no part in the choice (1): slip F1 pooled over their test sessions, fixed 0.500" in text
    assert not published


def test_a_rig_is_one_fixed_draw_of_the_physics_that_simulate_accepts(tmp_path, monkeypatch):
    """The rigs of other physics: the same seed gives the same options, and simulate takes every one of them."""
    from click.testing import CliRunner

    from neurotac_cli.cli import cli

    monkeypatch.syspath_prepend(str(EXAMPLES))
    results = load("results")
    options, about = results.rig(101)
    assert results.rig(101) == (options, about) and results.rig(102)[0] != options
    assert "tilt" in about and options.count("--set ") >= 30
    done = CliRunner().invoke(cli, ["simulate", "--preset", "ch4", "--trials", "1", "--seed", "1", "--synced", *options.split()])
    assert done.exit_code == 0, done.output[-500:]


def test_the_constant_baseline_reads_the_training_mean_of_nonzero_force(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))
    results = load("results")
    train, test = tmp_path / "train.parquet", tmp_path / "test.parquet"
    pq.write_table(pa.table({"force": [0.0, 1.0, 3.0]}), train)  # mean of the non-zero forces: 2 N
    pq.write_table(pa.table({"force": [0.0, 1.0, 3.0, 2.0]}), test)  # errors -1, 1, 0 over a 2 N range
    assert results.constant_pct(train, test) == pytest.approx(100 * (2 / 3) ** 0.5 / 2)


def test_a_quick_rig_materials_run_tables_every_classifier_and_leaves_docs_alone(tmp_path, monkeypatch):
    rigs = load("rig_materials")
    names = ("ours (material-timing)", "thesis DNN, k=2 n=30")

    def one_rig(seed, work, repeats):
        accuracy = 0.95 if seed == 101 else 0.85
        timing = {("all", "accuracy"): accuracy, ("class:foam", "recall"): 1.0, ("class:steel", "recall"): 0.8}
        return seed, f"physics {seed}", {names[0]: timing, names[1]: {("all", "accuracy"): 0.5}}

    monkeypatch.setattr(rigs, "one_rig", one_rig)
    published = []
    monkeypatch.setattr(rigs, "publish", published.append)
    rigs.main(["--quick", "--jobs", "1", "--work", str(tmp_path)])
    text = (tmp_path / "rig_materials.md").read_text()
    assert "| 101 | physics 101 | 95.0 | 50.0 | foam 100%, steel 80% |" in text
    assert "ours (material-timing): mean 90.0% over 2 rigs, lowest 85.0%, at least 90% on 1 of 2." in text
    assert not published


def test_a_quick_physics_grasps_run_tables_its_models_beside_the_constant_and_leaves_docs_alone(tmp_path, monkeypatch):
    physics = load("physics_grasps")
    monkeypatch.setattr(physics, "training_data", lambda work, pipeline, sets: tmp_path / "train.arrows")
    monkeypatch.setattr(physics, "frames", lambda work, name, pipeline, simulate: tmp_path / f"{name}.arrows")
    monkeypatch.setattr(physics, "constant_pct", lambda train, test: 34.6)
    errors = {"tdnn": ([30.0], [33.0]), "deform-gru": ([16.0], [20.0])}
    monkeypatch.setattr(physics, "one_model", lambda name, work, train, tests, seeds, sets:
                        (name, {"seen": errors[name][0], "unseen": errors[name][1]}))
    published = []
    monkeypatch.setattr(physics, "publish", published.append)
    physics.main(["--quick", "--jobs", "1", "--work", str(tmp_path)])
    text = (tmp_path / "physics_grasps.md").read_text()
    assert "| deform-gru | 16.0 ± 0.0 | 20.0 ± 0.0 | 1.25 |" in text
    assert "| constant (training mean) | 34.6 | 34.6 |  |" in text
    assert "Lowest error on the unseen physics: deform-gru, 20.0 ± 0.0% against the constant's 34.6%." in text
    assert not published


def test_the_slip_hysteresis_script_scores_every_session_at_every_share(tmp_path, capsys):
    """Starts are the same at every share, so going on at half the bars finds the same slips in no more runs."""
    sessions = load("sessions")
    sessions.simulate(str(tmp_path / "test"), 3501, 1, 6, None)
    load("slip_hysteresis").main(["--sessions", str(tmp_path), "--keep-share", "1,0.5"])
    pooled = [line for line in capsys.readouterr().out.splitlines() if line.startswith("pooled")]
    assert [line.split(":")[0] for line in pooled] == ["pooled, keep 1", "pooled, keep 0.5"]
    counts = [re.search(r"(\d+) of (\d+) found, (\d+) flagged", line).groups() for line in pooled]
    (hits_1, true_1, flagged_1), (hits_half, true_half, flagged_half) = [[int(n) for n in c] for c in counts]
    assert true_1 > 0 and true_1 == true_half and hits_1 == hits_half and flagged_half <= flagged_1


def test_the_slip_gain_script_scores_fixed_and_followed_bars_on_the_same_slips(tmp_path, capsys):
    sessions = load("sessions")
    sessions.simulate(str(tmp_path / "test"), 3501, 1, 6, None)
    load("slip_gain").main(["--sessions", str(tmp_path), "--bars-from", "test", "--rigs", str(tmp_path / "no-rigs")])
    out = capsys.readouterr().out
    assert out.startswith("bars from test: ")
    pooled = [line for line in out.splitlines() if line.startswith("pooled")]
    assert [line.split(":")[0] for line in pooled] == ["pooled test, fixed", "pooled test, follow"]
    found = [[int(n) for n in re.search(r"(\d+) of (\d+) found, (\d+) flagged", line).groups()] for line in pooled]
    assert found[0][1] > 0 and found[0][1] == found[1][1]
    # a model that carries the bars of a sensor ten times as sensitive: held fixed they flag nothing,
    # followed they flag this session's slips again
    import dataclasses

    gain = load("slip_gain")
    stream = gain.read(str(tmp_path / "test" / "frames.arrows"))[0]
    right = gain.bars_of([stream])
    wrong = dataclasses.replace(right, min_events=10 * right.min_events, min_events_on=10 * right.on_events,
                                press_off=10 * right.press_off, release_on=10 * right.release_on)
    flags = gain.score(stream, wrong, gain.detection_config([stream]))
    hits = {way: gain.figures([stream["slip"]], [flags[way]])["slip_hits"] for way in flags}
    assert hits["fixed"] == 0 and hits["follow"] > 0


def test_the_material_domains_script_scores_sizes_and_sensors_both_ways_and_a_quick_run_publishes_nothing(tmp_path, capsys, monkeypatch):
    script = load("material_domains")
    published = []
    monkeypatch.setattr(script, "publish_section", lambda *args, **kwargs: published.append(args))
    script.main(["--quick", "--work", str(tmp_path), "--jobs", "1"])
    out = capsys.readouterr().out
    sizes = [line for line in out.splitlines() if line.startswith("| 5 |")]
    assert [row.split(" | ")[1] for row in sizes] == ["7.5 mm"]
    assert len(sizes[0].split(" | ")) == 2 + 4  # seed, size, material-timing and material-rises both ways
    sensors = [line for line in out.splitlines() if line.startswith(f"| {script.RIGS[0]} |")]
    assert len(sensors) == 1
    assert len(sensors[0].split(" | ")) == 2 + 2 + 1  # rig, physics, material-timing both ways, many sensors
    for row in sizes + sensors:
        cells = [float(cell) for cell in row.strip(" |").split(" | ")[2:]]
        assert all(0 <= cell <= 100 for cell in cells)
    (family,) = [line for line in out.splitlines() if line.startswith("| membrane |")]
    assert all(0 <= float(cell) <= 100 for cell in family.split(" | ")[1:3])
    assert (tmp_path / "material_domains.md").exists() and not published


def test_a_quick_members_run_tables_one_member_against_three_and_leaves_docs_alone(tmp_path, monkeypatch):
    members = load("members")
    monkeypatch.setattr(members, "frames", lambda work, name, pipeline, simulate: tmp_path / f"{name}.arrows")
    figures = {("ch4", 1): (5.0, 0.5), ("ch4", 3): (4.0, 0.25), ("ch4-rig101", 1): (10.0, 2.0), ("ch4-rig101", 3): (11.0, 1.0)}
    monkeypatch.setattr(members, "scores", lambda work, data, tag, count, seeds: figures[(tag, count)])
    published = []
    monkeypatch.setattr(members, "publish", published.append)
    members.main(["--quick", "--work", str(tmp_path)])
    text = (tmp_path / "members.md").read_text()
    assert "| default physics | 5.00 ± 0.50 | 4.00 ± 0.25 | 0.80 |  |" in text
    assert "| rig 101 | 10.00 ± 2.00 | 11.00 ± 1.00 | 1.10 | ON/OFF thresholds" in text
    assert "Three members read lower than one on 1 of 2 physics; on average 0.95 times one member's error." in text
    assert not published


def test_a_quick_rig_families_run_puts_one_family_of_the_rig_on_the_default_physics_and_leaves_docs_alone(tmp_path, monkeypatch):
    families = load("rig_families")
    made = {}
    monkeypatch.setattr(families, "frames", lambda work, name, pipeline, simulate: made.setdefault(name, simulate) and tmp_path / name)
    figures = {"ch4": 4.0, "ch4-rig101-pixels": 5.0, "ch4-rig101-membrane": 3.0, "ch4-rig101": 9.0}
    monkeypatch.setattr(families, "scores", lambda work, data, tag, count, seeds: (figures[tag], 0.1))
    published = []
    monkeypatch.setattr(families, "publish", published.append)
    families.main(["--quick", "--work", str(tmp_path)])
    text = (tmp_path / "rig-families.md").read_text()
    values = families.drawn(101)
    assert made["ch4"] == "--seed 1"
    assert made["ch4-rig101-pixels"].startswith(f"--seed 1 --set on_threshold={values['on_threshold']:.6g} --set off_threshold=")
    assert "membrane_youngs_pa" not in made["ch4-rig101-pixels"] and "on_threshold" not in made["ch4-rig101-membrane"]
    assert made["ch4-rig101"] == "--seed 1 " + load("results").rig(101)[0]  # the rig of the members table and the models section
    assert "| pixels | 5.00 (1.25x) |" in text and "| membrane | 3.00 (0.75x) |" in text
    assert "| every family (the rig) | 9.00 (2.25x) |" in text and "| product of the families' ratios | 0.94x |" in text
    assert "The family that costs most alone: rig 101, pixels (1.25x)." in text
    assert "No family alone reaches its rig's whole error on any of the 1 rigs" in text
    assert not published


def test_the_models_section_shows_a_lower_bound_where_a_study_took_an_earlier_run_s_tasks(tmp_path, monkeypatch):
    results = load("results")
    logs = {"fresh": cache_line(tmp_path / "later", LATER) + "\n", "resumed": cache_line(tmp_path / "earlier", EARLIER) + "\n",
            "none": ""}

    def sh(command, log=None):  # stands in for `neurotac eval`: its metrics, its stderr and 42 s
        pathlib.Path(command.split("--metrics ")[1].split()[0]).write_bytes(b"")
        pathlib.Path(log).write_text(logs[log.name.split("-")[0]])
        return 42.0

    monkeypatch.setattr(results, "sh", sh)
    monkeypatch.setattr(results, "metrics", lambda path: {})
    timing = {}
    for tag in logs:
        results.evaluate(tmp_path, "data", tag, "--cv loo", timing)
    assert timing == {"fresh": "42 s", "resumed": "≥ 42 s", "none": "42 s"}
