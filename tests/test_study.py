"""Studies: the same results in-process, on a local pool and on a real Dask cluster; a dead worker's
tasks are retried; an interrupted study resumes with only the missing tasks; the --grid grammar."""

import os
import pathlib
import re
import signal

import click
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from neurotac_cli.errors import NeurotacError
from neurotac_cli.options import study_options
from neurotac_cli.study import cached_keys, data_digest, parse_grid, run_tasks, task_key

TRIALS = 6


# -- task functions: module level, so workers in other processes can import them -------------------


def loo_fold(layers: int, units: int, fold: int, seed: int) -> dict:
    """A tiny random-feature regression: `layers` random tanh layers of `units` units, a ridge read-out
    fitted on every trial but `fold`, scored on trial `fold`. Cheap, seeded only by its arguments."""
    data = np.random.default_rng(1234)
    inputs = data.normal(size=(TRIALS, 20, 3))
    targets = np.sin(inputs.sum(axis=2))
    rng = np.random.default_rng(seed)
    features = inputs
    for _ in range(layers):
        features = np.tanh(features @ rng.normal(size=(features.shape[-1], units)))
    train = [trial for trial in range(TRIALS) if trial != fold]
    x = features[train].reshape(-1, units)
    y = targets[train].reshape(-1)
    weights = np.linalg.solve(x.T @ x + 1e-3 * np.eye(units), x.T @ y)
    error = features[fold] @ weights - targets[fold]
    return {"layers": layers, "units": units, "fold": fold, "mse": float(np.mean(error**2))}


def square(x: int, calls: str = "", stop_at: int = -1, die_at: int = -1) -> int:
    """Notes each call in the folder `calls`; at task `stop_at` the study is interrupted (while the
    file `calls/stop` exists); at task `die_at` the worker process is killed, once."""
    folder = pathlib.Path(calls) if calls else None
    if folder is not None:
        if x == stop_at and (folder / "stop").exists():
            raise KeyboardInterrupt
        if x == die_at and not (folder / "died").exists():
            (folder / "died").touch()
            os.kill(os.getpid(), signal.SIGKILL)
        (folder / f"{x}.{os.getpid()}.{len(list(folder.glob(f'{x}.*')))}").touch()
    return x * x


def calls_per_task(folder) -> dict[int, int]:
    counts: dict[int, int] = {}
    for path in pathlib.Path(folder).glob("*.*.*"):
        task = int(path.name.split(".")[0])
        counts[task] = counts.get(task, 0) + 1
    return counts


def weighted_sum(table, weight: float) -> float:
    return float(sum(table.column("v").to_pylist()) * weight)


def study_tasks(grid):
    return [{**point, "fold": fold, "seed": 7 + fold} for point in grid for fold in range(TRIALS)]


# -- a real Dask cluster, shared by the tests of this module --------------------------------------


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=50
    ) as local:
        yield local


# -- the same results whatever runs the tasks ----------------------------------------------------


def test_grid_by_leave_one_out_study_gives_identical_results_in_process_on_a_pool_and_on_dask(cluster):
    tasks = study_tasks(parse_grid(["layers=1..2", "units=4,8"]))
    assert len(tasks) == 4 * TRIALS
    here = run_tasks(loo_fold, tasks)
    pooled = run_tasks(loo_fold, tasks, jobs=2)
    dask = run_tasks(loo_fold, tasks, scheduler=cluster.scheduler_address)
    assert here == pooled == dask
    assert [(r["layers"], r["units"], r["fold"]) for r in dask] == [(t["layers"], t["units"], t["fold"]) for t in tasks]


def test_a_command_with_study_options_runs_through_the_scheduler(cluster, tmp_path):
    @click.command()
    @study_options
    def tiny(jobs, scheduler, cache):
        results = run_tasks(square, [{"x": x} for x in range(5)], jobs=jobs, scheduler=scheduler, cache_dir=cache)
        click.echo(" ".join(map(str, results)))

    runner = CliRunner()
    via_dask = runner.invoke(tiny, ["--scheduler", cluster.scheduler_address, "--cache", str(tmp_path / "c")])
    via_env = runner.invoke(tiny, [], env={"NEUROTAC_JOBS": "2"})
    assert via_dask.exit_code == 0, via_dask.output
    assert via_dask.output == via_env.output == "0 1 4 9 16\n"
    assert len(cached_keys(tmp_path / "c")) == 5


def test_shared_data_reaches_every_backend_and_enters_the_cache_key(cluster, tmp_path):
    pa = pytest.importorskip("pyarrow")
    table = pa.table({"v": [1.0, 2.0, 3.0]})
    tasks = [{"weight": w} for w in (1.0, 2.0, 0.5)]
    expected = [6.0, 12.0, 3.0]
    for options in ({}, {"jobs": 2}, {"scheduler": cluster.scheduler_address}):
        assert run_tasks(weighted_sum, tasks, shared={"table": table}, **options) == expected
    run_tasks(weighted_sum, tasks, shared={"table": table}, cache_dir=tmp_path)
    assert len(cached_keys(tmp_path)) == 3
    other = pa.table({"v": [1.0, 1.0, 1.0]})
    assert run_tasks(weighted_sum, tasks, shared={"table": other}, cache_dir=tmp_path) == [3.0, 6.0, 1.5]
    assert len(cached_keys(tmp_path)) == 6


# -- a worker that dies ----------------------------------------------------------------------------


def test_killing_a_dask_worker_mid_study_still_completes_it(cluster, tmp_path):
    tasks = [{"x": x, "calls": str(tmp_path), "die_at": 3} for x in range(8)]
    results = run_tasks(square, tasks, scheduler=cluster.scheduler_address, label="kill")
    assert results == [x * x for x in range(8)]
    assert (tmp_path / "died").exists()
    assert calls_per_task(tmp_path)[3] == 1  # the killed attempt never finished; the retry did


def test_killing_a_local_pool_worker_mid_study_still_completes_it(tmp_path):
    tasks = [{"x": x, "calls": str(tmp_path), "die_at": 2} for x in range(6)]
    assert run_tasks(square, tasks, jobs=2) == [x * x for x in range(6)]
    assert (tmp_path / "died").exists()


def test_a_task_that_always_kills_its_worker_fails_the_study_with_a_message(tmp_path):
    with pytest.raises(NeurotacError, match="lost their worker 2 times"):
        run_tasks(_always_dies, [{"x": 0}, {"x": 1}], jobs=2, retries=1)


def _always_dies(x):
    if x == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return x


# -- interruption and resume -----------------------------------------------------------------------


def test_a_rerun_after_an_interruption_runs_only_the_missing_tasks(tmp_path):
    calls, cache = tmp_path / "calls", tmp_path / "cache"
    calls.mkdir()
    (calls / "stop").touch()
    tasks = [{"x": x, "calls": str(calls), "stop_at": 6} for x in range(10)]
    with pytest.raises(KeyboardInterrupt):
        run_tasks(square, tasks, cache_dir=cache)
    assert sorted(calls_per_task(calls)) == list(range(6))
    assert len(cached_keys(cache)) == 6
    assert not list(cache.glob("*/.*.tmp"))  # nothing half-written

    (calls / "stop").unlink()
    assert run_tasks(square, tasks, cache_dir=cache) == [x * x for x in range(10)]
    assert calls_per_task(calls) == {x: 1 for x in range(10)}


def test_a_cache_filled_in_process_is_reused_by_a_dask_run(cluster, tmp_path):
    calls, cache = tmp_path / "calls", tmp_path / "cache"
    calls.mkdir()
    tasks = [{"x": x, "calls": str(calls)} for x in range(8)]
    run_tasks(square, tasks[:5], cache_dir=cache)
    assert run_tasks(square, tasks, scheduler=cluster.scheduler_address, cache_dir=cache) == [x * x for x in range(8)]
    assert calls_per_task(calls) == {x: 1 for x in range(8)}


def test_an_unreadable_cache_entry_is_run_again(tmp_path):
    tasks = [{"x": 3}]
    run_tasks(square, tasks, cache_dir=tmp_path)
    (entry,) = tmp_path.glob("*/*.pkl")
    entry.write_bytes(b"garbage")
    assert run_tasks(square, tasks, cache_dir=tmp_path) == [9]


@pytest.mark.parametrize("damage", ["flip", "replace"])
def test_a_damaged_cache_entry_is_run_again_not_read(tmp_path, damage):
    """A flipped byte in an entry's pickle was a traceback (UnicodeDecodeError) or a changed result taken
    without a word; another valid pickle in its place was a traceback where the result was used."""
    import pickle

    tasks = [{"x": 3, "calls": str(tmp_path / "calls")}]
    (tmp_path / "calls").mkdir()
    run_tasks(square, tasks, cache_dir=tmp_path / "c")
    (entry,) = (tmp_path / "c").glob("*/*.pkl")
    data = bytearray(entry.read_bytes())
    if damage == "flip":
        data[-3] ^= 0x01
    entry.write_bytes(bytes(data) if damage == "flip" else pickle.dumps("another value"))
    assert run_tasks(square, tasks, cache_dir=tmp_path / "c") == [9]
    assert calls_per_task(tmp_path / "calls") == {3: 2}


class _Touch:
    """Pickles as a call of `Path.touch`: what a crafted entry could make a reader run."""

    def __init__(self, marker):
        self.marker = pathlib.Path(marker)

    def __reduce__(self):
        return pathlib.Path.touch, (self.marker,)


@pytest.mark.parametrize("where", ["whole", "inside"])
def test_a_crafted_cache_entry_with_a_right_checksum_runs_no_code_and_its_task_runs_again(tmp_path, where):
    import hashlib
    import pickle

    tasks = [{"x": 3, "calls": str(tmp_path / "calls")}]
    (tmp_path / "calls").mkdir()
    run_tasks(square, tasks, cache_dir=tmp_path / "c")
    (entry,) = (tmp_path / "c").glob("*/*.pkl")
    marker = tmp_path / "code-ran"
    crafted = _Touch(marker) if where == "whole" else {"result": [9, _Touch(marker)]}
    payload = pickle.dumps(crafted, protocol=pickle.HIGHEST_PROTOCOL)
    entry.write_bytes(hashlib.sha256(payload).digest() + payload)
    assert run_tasks(square, tasks, cache_dir=tmp_path / "c") == [9]
    assert not marker.exists()
    assert calls_per_task(tmp_path / "calls") == {3: 2}


def pair_of_tables_and_figures(n: int):
    """What a cross-validation fold returns: a predictions table and a dict of figures."""
    import pyarrow as pa

    table = pa.table({"trial": ["a"] * n, "force_pred": np.arange(n, dtype=np.float32)})
    figures = {"val_mse": float("nan"), "epochs": np.float64(n), "curve": np.linspace(0, 1, n), "z": 1 + 2j}
    return table.replace_schema_metadata({"neurotac:kind": '"predictions"'}), figures


def test_tables_arrays_and_numbers_come_back_from_the_cache_as_they_went_in(tmp_path):
    tasks = [{"n": 4}]
    (table, figures), = run_tasks(pair_of_tables_and_figures, tasks, cache_dir=tmp_path)
    (cached_table, cached_figures), = run_tasks(pair_of_tables_and_figures, tasks, cache_dir=tmp_path)
    assert cached_table.equals(table, check_metadata=True)
    assert np.array_equal(cached_figures.pop("curve"), figures.pop("curve"))
    assert repr(cached_figures) == repr(figures)


def test_a_result_the_cache_could_not_read_back_safely_is_refused_when_written(tmp_path):
    with pytest.raises(TypeError, match="cannot be kept in the study cache"):
        run_tasks(_a_function_object, [{"x": 1}], cache_dir=tmp_path)


def _a_function_object(x):
    return {"x": x, "f": os.system}


def test_identical_tasks_run_once(tmp_path):
    tasks = [{"x": 2, "calls": str(tmp_path)}] * 3
    assert run_tasks(square, tasks) == [4, 4, 4]
    assert calls_per_task(tmp_path) == {2: 1}


# -- task identity ---------------------------------------------------------------------------------


def test_task_key_follows_content_not_identity():
    first = {"data": np.arange(5.0), "fold": 1, "config": {"a": 1, "b": [1, 2]}}
    same = {"config": {"b": (1, 2), "a": 1}, "fold": 1, "data": np.arange(5.0)}
    changed = {"data": np.arange(5.0) + 1e-9, "fold": 1, "config": {"a": 1, "b": [1, 2]}}
    assert task_key(square, first) == task_key(square, same)
    assert task_key(square, first) != task_key(square, changed)
    assert task_key(square, first) != task_key(loo_fold, first)
    assert task_key(square, {"x": 1}) != task_key(square, {"x": 1.0})


def test_data_digest_of_a_table_changes_with_its_content():
    pa = pytest.importorskip("pyarrow")
    table = pa.table({"t": [1, 2, 3]})
    assert data_digest(table) == data_digest(pa.table({"t": [1, 2, 3]}))
    assert data_digest(table) != data_digest(pa.table({"t": [1, 2, 4]}))


def test_progress_goes_to_stderr_with_done_total(capsys):
    run_tasks(square, [{"x": x} for x in range(3)], progress=True, label="demo")
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "demo: 3/3 done" in captured.err


def test_jobs_and_scheduler_together_are_refused():
    with pytest.raises(NeurotacError, match="both given"):
        run_tasks(square, [{"x": 1}], jobs=2, scheduler="tcp://127.0.0.1:1")


@pytest.mark.parametrize("reply, words", [(b"HTTP/1.1 400 Bad Request\r\n\r\n", "answered b'HTTP/1.1'"), (None, "sent nothing")])
def test_an_address_that_is_not_a_dask_scheduler_is_refused_in_seconds(monkeypatch, reply, words):
    """A web server's port given as --scheduler: Dask's client waited for good on one that never
    answers, or read an answer as a message of exabytes and failed as out of memory."""
    import socket
    import threading

    from neurotac_cli import study

    monkeypatch.setattr(study, "PROBE_TIMEOUT", 1.0)
    server = socket.create_server(("127.0.0.1", 0))
    held = []

    def serve():
        connection, _ = server.accept()
        held.append(connection)
        if reply:
            connection.sendall(reply)

    threading.Thread(target=serve, daemon=True).start()
    with pytest.raises(NeurotacError, match=re.escape(words) + ".*not the dashboard"):
        run_tasks(square, [{"x": 1}], scheduler=f"tcp://127.0.0.1:{server.getsockname()[1]}")
    server.close()


def test_a_scheduler_file_works_as_an_address(cluster, tmp_path):
    import json

    (tmp_path / "scheduler.json").write_text(json.dumps({"address": cluster.scheduler_address}))
    assert run_tasks(square, [{"x": 4}], scheduler=str(tmp_path / "scheduler.json")) == [16]


def test_a_malformed_scheduler_address_says_what_to_give():
    with pytest.raises(NeurotacError, match="neither an address"):
        run_tasks(square, [{"x": 1}], scheduler="my-cluster")


def test_an_unreachable_scheduler_is_a_user_error(monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr("neurotac_cli.study.CONNECT_TIMEOUT", "1s")
    with pytest.raises(NeurotacError, match="cannot reach the Dask scheduler"):
        run_tasks(square, [{"x": 1}], scheduler="tcp://127.0.0.1:9")


# -- the --grid grammar ----------------------------------------------------------------------------


def test_grid_ranges_lists_and_ellipses():
    assert parse_grid(["layers=1..3"]) == [{"layers": 1}, {"layers": 2}, {"layers": 3}]
    assert [p["units"] for p in parse_grid(["units=5,10,...,40"])] == [5, 10, 15, 20, 25, 30, 35, 40]
    assert [p["s"] for p in parse_grid(["s=0..10:5"])] == [0, 5, 10]
    assert [p["lr"] for p in parse_grid(["lr=1e-3,0.01"])] == [0.001, 0.01]
    assert parse_grid(["model=lstm,convlstm seed=0..1"]) == [
        {"model": "lstm", "seed": 0},
        {"model": "lstm", "seed": 1},
        {"model": "convlstm", "seed": 0},
        {"model": "convlstm", "seed": 1},
    ]
    assert parse_grid([]) == [{}]


@pytest.mark.parametrize(
    "spec", ["layers", "=1", "layers=", "layers=1,,2", "units=5,...", "a=1 a=2", "k=5..1", "k=1..5:0", "w=a,b,...,c"]
)
def test_bad_grid_specs_say_what_to_write(spec):
    with pytest.raises(NeurotacError, match="grid"):
        parse_grid([spec])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(-5, 5), st.integers(0, 4)), min_size=1, max_size=3))
def test_grid_size_is_the_product_of_the_axis_sizes(axes):
    specs = [f"a{i}={start}..{start + length}" for i, (start, length) in enumerate(axes)]
    points = parse_grid(specs)
    assert len(points) == int(np.prod([length + 1 for _, length in axes]))
    assert len({tuple(sorted(p.items())) for p in points}) == len(points)


# -- arithmetic that does not depend on where a task ran --------------------------------------------


def torch_sums(seed: int) -> tuple:
    """Sums and a dot product of 2M floats: torch splits such reductions by thread, so their last
    digits differ between 1 and 2 threads (as a training run's do)."""
    import torch

    generator = torch.Generator().manual_seed(seed)
    x, w = torch.randn(2_000_000, generator=generator), torch.randn(2_000_000, generator=generator)
    return x.sum().item(), (x @ w).item()


def test_torch_results_are_identical_in_process_and_on_dask(cluster):
    torch = pytest.importorskip("torch")
    torch.set_num_threads(2)
    tasks = [{"seed": seed} for seed in range(3)]
    assert [torch_sums(**task) for task in tasks] != run_tasks(torch_sums, tasks)  # the pin matters
    assert run_tasks(torch_sums, tasks) == run_tasks(torch_sums, tasks, scheduler=cluster.scheduler_address)
    assert torch.get_num_threads() == 2  # the caller's setting is given back


# -- a real study through the command line ---------------------------------------------------------


def _eval(args, env=None):
    from neurotac_cli.cli import cli

    result = CliRunner().invoke(cli, ["eval", *args], env=env, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result


def _metrics(path):
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    rows = zip(*(table.column(name).to_pylist() for name in ("scope", "metric", "value")))
    return [(scope, metric, "nan" if value != value else value) for scope, metric, value in rows]


@pytest.fixture(scope="module")
def tiny_frames_file(tmp_path_factory):
    pytest.importorskip("torch")
    from tests.model.helpers import tiny_frames, write_stream

    path = tmp_path_factory.mktemp("frames") / "frames.arrows"
    write_stream(tiny_frames(trials=5), path)
    return str(path)


def test_eval_cv_through_the_scheduler_gives_the_metrics_of_the_in_process_run(cluster, tiny_frames_file, tmp_path):
    study = ["--cv", "loo", "--model-spec", "tdnn", "--layers", "1", "--units", "4", "--epochs", "3", "--seed", "2"]
    _eval([*study, tiny_frames_file, "--metrics", str(tmp_path / "here.parquet"), "-o", str(tmp_path / "here.arrows")])
    _eval([*study, tiny_frames_file, "--metrics", str(tmp_path / "dask.parquet"), "-o", str(tmp_path / "dask.arrows"),
           "--scheduler", cluster.scheduler_address])
    here, dask = _metrics(tmp_path / "here.parquet"), _metrics(tmp_path / "dask.parquet")
    assert len(here) > 20 and here == dask


def test_eval_cv_rerun_with_a_cache_trains_nothing(tiny_frames_file, tmp_path):
    study = ["--cv", "loo", "--model-spec", "tdnn", "--layers", "1", "--units", "4", "--epochs", "2",
             "--cache", str(tmp_path / "cache"), tiny_frames_file, "-o", str(tmp_path / "p.arrows")]
    first = _eval([*study, "--metrics", str(tmp_path / "first.parquet")], env={"NEUROTAC_PROGRESS": "1"})
    again = _eval([*study, "--metrics", str(tmp_path / "again.parquet")], env={"NEUROTAC_PROGRESS": "1"})
    assert "5/5 done, " in first.stderr
    assert "5/5 done (5 cached)" in again.stderr
    assert "from the cache" not in first.stderr and "tdnn folds: 5 of 5 tasks from the cache" in again.stderr
    assert _metrics(tmp_path / "first.parquet") == _metrics(tmp_path / "again.parquet")


def test_study_command_runs_a_grid_through_the_scheduler_as_in_process(cluster, tiny_frames_file, tmp_path):
    from neurotac_cli.cli import cli

    grid = ["study", "--model-spec", "tdnn", "--grid", "layers=1..2", "--grid", "units=3 epochs=2", "--cv", "loo",
            "--seed", "3", tiny_frames_file]
    runner = CliRunner()
    here = runner.invoke(cli, [*grid, "--metrics", str(tmp_path / "here.parquet"), "-o", str(tmp_path / "here.arrows")])
    dask = runner.invoke(cli, [*grid, "--metrics", str(tmp_path / "dask.parquet"), "-o", str(tmp_path / "dask.arrows"),
                               "--scheduler", cluster.scheduler_address])
    assert here.exit_code == 0 and dask.exit_code == 0, here.output + dask.output
    assert "tdnn layers=2, units=3, epochs=2: MSE" in here.stderr

    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "here.parquet")
    assert table.schema.names == ["scope", "metric", "value", "model", "layers", "units", "epochs"]
    assert sorted(set(table.column("layers").to_pylist())) == [1, 2]
    assert _metrics(tmp_path / "here.parquet") == _metrics(tmp_path / "dask.parquet")

    # each point scores as `eval --cv` scores it
    _eval(["--cv", "loo", "--model-spec", "tdnn", "--layers", "2", "--units", "3", "--epochs", "2", "--seed", "3", "--no-per-trial",
           tiny_frames_file, "--metrics", str(tmp_path / "one.parquet"), "-o", str(tmp_path / "one.arrows")])
    point = table.filter(pa_equal(table.column("layers"), 2))
    rows = [(s, m, "nan" if v != v else v) for s, m, v in zip(*(point.column(c).to_pylist() for c in ("scope", "metric", "value")))]
    assert sorted(rows, key=str) == sorted(_metrics(tmp_path / "one.parquet"), key=str)


def test_study_command_refuses_a_parameter_the_model_does_not_have(tiny_frames_file):
    from neurotac_cli.cli import cli

    result = CliRunner().invoke(cli, ["study", "--model-spec", "tdnn", "--grid", "filters=1,2", tiny_frames_file])
    assert result.exit_code == 2  # an option the model does not have is a usage error
    assert "has no option 'filters'" in result.stderr


def pa_equal(column, value):
    import pyarrow.compute as pc

    return pc.equal(column, value)


@pytest.mark.parametrize("setting, value, words", [("layers", "abc", "whole number"), ("delays", 1.5, "whole number"),
                                                    ("lr", "abc", "takes a number")])
def test_a_setting_of_the_wrong_type_is_refused_before_training(setting, value, words, tiny_frames_file):
    from neurotac_cli.cli import cli
    from neurotac_cli.errors import UsageError
    from neurotac_cli.model.core import make_spec

    with pytest.raises(UsageError, match=words):  # a usage error (exit 2), as a value outside its range is
        make_spec("tdnn", **{setting: value})
    assert make_spec("tdnn", layers=2.0)["layers"] == 2 and isinstance(make_spec("tdnn", layers=2.0)["layers"], int)
    result = CliRunner().invoke(cli, ["study", "--model-spec", "tdnn", "--grid", f"{setting}={value}", tiny_frames_file])
    assert result.exit_code == 2 and words in result.stderr


@pytest.mark.parametrize("spec, words", [("lr=1e-3..1e-2", "give a step"), ("lr=0.5..2", "give a step"),
                                         ("layers=1..x", "not a range of numbers")])
def test_a_range_that_would_collapse_or_does_not_parse_is_refused_naming_the_grid(spec, words):
    with pytest.raises(NeurotacError, match=f"--grid {spec}: .*{words}"):
        parse_grid([spec])
    assert [p["lr"] for p in parse_grid(["lr=1e-3..3e-3:1e-3"])] == [0.001, 0.002, 0.003]


@pytest.mark.parametrize("verb", [["study"], ["eval", "--cv", "loo"]])
def test_a_bad_grid_is_a_usage_error_before_any_input_is_read(verb):
    from neurotac_cli.cli import cli

    result = CliRunner().invoke(cli, [*verb, "--model-spec", "tdnn", "--grid", "layers=1..x"], input=b"")
    assert result.exit_code == 2 and "--grid layers=1..x" in result.output and "--layers" not in result.output


def test_a_study_that_takes_tasks_from_the_cache_says_so_once(tiny_frames_file, tmp_path):
    from neurotac_cli.cli import cli

    grid = ["study", "--model-spec", "tdnn", "--grid", "layers=1..2", "--units", "3", "--epochs", "2", "--cv", "loo",
            "--cache", str(tmp_path / "cache"), tiny_frames_file, "-o", str(tmp_path / "oof.arrows")]
    first = CliRunner().invoke(cli, grid)
    again = CliRunner().invoke(cli, grid)
    assert first.exit_code == 0 and again.exit_code == 0, first.output + again.output
    assert "from the cache" not in first.stderr
    assert again.stderr.count("from the cache") == 1
    assert re.search(r"tdnn grid: 10 of 10 tasks from the cache \S+, the oldest finished 20\d\d-\d\d-\d\dT\d\d:\d\d:\d\dZ "
                     r"\(not in this run's time\)", again.stderr)


def test_a_grid_value_given_twice_is_refused():
    with pytest.raises(NeurotacError, match="gives 2 more than once"):
        parse_grid(["layers=1..3,2"])


@pytest.mark.parametrize("spec", ["units=5,10,...,41", "layers=1..4:2"])
def test_a_grid_range_whose_steps_pass_over_its_end_is_refused_not_cut_short(spec):
    from neurotac_cli.errors import UsageError
    from neurotac_cli.study import parse_grid

    with pytest.raises(UsageError, match="give an end the steps reach"):
        parse_grid([spec])


def test_sigterm_ends_a_pool_without_waiting_for_its_running_tasks(tmp_path):
    """`kill PID` reaches the main process alone; its exit waited for every task already running."""
    import subprocess
    import sys
    import time

    (tmp_path / "slow_pool.py").write_text(
        "import sys, time\nfrom neurotac_cli import cli, study\n\n\ndef slow(**task):\n    time.sleep(60)\n\n\n"
        "if __name__ == '__main__':\n    cli._end_on_sigterm()\n    try:\n"
        "        study._run_pool(slow, {'a': {}, 'b': {}}, {}, 2, 0, lambda key, value: None)\n"
        "    except cli.Terminated:\n        sys.exit(143)\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    process = subprocess.Popen([sys.executable, str(tmp_path / "slow_pool.py")], env=env)
    time.sleep(4)  # the workers started and inside their tasks
    started = time.monotonic()
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=30) == 143 and time.monotonic() - started < 10
