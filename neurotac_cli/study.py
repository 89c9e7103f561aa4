"""Studies: many independent tasks (grid points x folds x seeds), run in-process, on a local process
pool, or on a Dask distributed cluster, with results cached so an interrupted study resumes.

`run_tasks(function, tasks)` calls `function(**task)` for every task and returns the results in task
order. Whatever runs them, the results are the same: a task carries everything it depends on (its
seed included), so no result can depend on which worker ran it or in what order. Each result is
written to the cache as soon as it arrives, under a hash of the function and the task, so a re-run
of the same study only runs what is missing.

`parse_grid(["layers=1..5", "units=5,10,...,40"])` expands the `--grid` grammar into grid points.

Core code: no click, nothing on stdout, no exits. Progress goes to stderr.
"""

from __future__ import annotations

import collections
import contextlib
import datetime
import dataclasses
import errno
import hashlib
import io
import itertools
import json
import math
import os
import pathlib
import pickle
import re
import sys
import time
from typing import Callable

from neurotac_cli.errors import NeurotacError, UsageError

DEVICE_VARIABLE = "NEUROTAC_DEVICE"  # where force networks train (`--device`); part of a task's cache key off the CPU

# Bumped when the cache file layout or a task's result changes, so old entries are never misread
# (2: a cross-validation fold returns its validation figures beside its predictions; 3: each entry
# starts with its payload's SHA-256; 4: arrays and tables are stored as .npy and Arrow IPC bytes).
CACHE_FORMAT = 4
# How long to wait for a Dask scheduler to answer before saying it cannot be reached.
CONNECT_TIMEOUT = "20s"


class StudyError(NeurotacError):
    """A study that cannot run: a grid that does not parse, a scheduler that cannot be reached, a task
    that keeps killing its worker."""


# --------------------------------------------------------------------------------------------------
# Running tasks


def run_tasks(
    function: Callable,
    tasks: list[dict],
    *,
    jobs: int = 1,
    scheduler=None,
    cache_dir=None,
    retries: int = 2,
    label: str = "tasks",
    progress=None,
    shared: dict | None = None,
    note: Callable[[str], None] | None = None,
) -> list:
    """Run `function(**task)` for every task; return the results in task order.

    `function` must be a module-level (picklable) function. `jobs` > 1 runs tasks on a local process
    pool (`jobs` <= 0: one process per CPU); `scheduler` (a Dask scheduler address such as
    `tcp://10.0.0.5:8786`, or a `dask.distributed.Client`) runs them on a Dask cluster. `cache_dir`
    keeps one file per finished task, keyed by a hash of the function's name and the task, so a re-run
    skips what finished. `retries`: how many times a task whose worker died (or, on Dask, that raised)
    is run again before the study fails. `progress`: True/False to force the stderr progress line on
    or off; None shows it when stderr is a terminal or $NEUROTAC_PROGRESS is set.

    `shared`: keyword arguments common to every task (the frames table of a whole study), sent once
    to each worker rather than once per task, and hashed once into every task's cache key:
    `run_tasks(fit_fold, [{"fold": 0, "seed": 1}, ...], shared={"frames": frames})` calls
    `fit_fold(frames=frames, fold=0, seed=1)`. `note(line)` hears how many came from the cache.
    """
    tasks = list(tasks)
    if scheduler and jobs not in (None, 0, 1):
        raise UsageError(
            f"--jobs {jobs} and --scheduler {scheduler} both given (the Dask cluster decides how many "
            "tasks run at once; pass one of them)"
        )
    shared = dict(shared or {})
    common = {"shared": data_digest(shared)} if shared else {}
    keys = [task_key(function, {**task, **common}) for task in tasks]
    cache = _Cache(cache_dir) if cache_dir else None

    results = cache.found(keys) if cache is not None else {}
    # Identical tasks run once: the same inputs give the same result.
    pending = {key: task for key, task in zip(keys, tasks) if key not in results}

    meter = Progress(len(dict.fromkeys(keys)), cached=len(results), label=label, enabled=progress)
    if results and note is not None:  # a wall time measured around a resumed study counts only what runs now
        note(cache.told(results, meter.total, label))

    def finished(key, value):
        results[key] = value
        if cache is not None:
            cache.put(key, value)
        meter.advance()

    meter.show()
    try:
        if pending:
            _run_pending(function, pending, shared, jobs, scheduler, retries, label, finished)
    finally:
        meter.close()
    return [results[key] for key in keys]


def _run_pending(function, pending: dict, shared: dict, jobs, scheduler, retries: int, label: str, finished):
    """Every pending task on the Dask cluster, the local pool or here; `finished(key, result)` as each ends."""
    if scheduler:
        _run_dask(function, pending, shared, scheduler, retries, label, finished)
    elif jobs is not None and jobs != 1:
        workers = (os.cpu_count() or 1) if jobs <= 0 else jobs
        _run_pool(function, pending, shared, workers, retries, finished)
    else:
        for key, task in pending.items():
            finished(key, _call(function, task, shared))


# The `shared` arguments of the study a pool worker process serves, set once when it starts.
_WORKER_SHARED: dict = {}


def _set_worker_shared(shared: dict):
    global _WORKER_SHARED
    _WORKER_SHARED = shared


def _call(function, task: dict, shared: dict | None = None):
    """Runs on a worker. Tasks travel as one dict so no task name can clash with the pool's own
    keywords (Dask's `key`, `workers`, `priority`...)."""
    shared = _WORKER_SHARED if shared is None else shared
    clash = shared.keys() & task.keys()
    if clash:
        raise TypeError(f"task arguments {sorted(clash)} are also given in shared=")
    with _one_thread():
        return function(**shared, **task)


_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


@contextlib.contextmanager
def _one_thread():
    """Every task runs its torch/BLAS arithmetic on one thread, wherever it runs: a torch training
    run gives different last digits on 1 and 2 threads (measured), and Dask workers start with
    OMP_NUM_THREADS=1, so this is what makes in-process, pool and cluster results identical. Use
    --jobs or a cluster, not threads, for speed."""
    torch = sys.modules.get("torch")
    if torch is not None:
        before = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            yield
        finally:
            torch.set_num_threads(before)
        return
    # torch not loaded yet: it reads these when the task imports it (and then keeps one thread).
    saved = {name: os.environ.get(name) for name in _THREAD_VARIABLES}
    os.environ.update({name: "1" for name in _THREAD_VARIABLES})
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _run_pool(function, pending: dict, shared: dict, workers: int, retries: int, finished):
    """A local process pool. A worker that dies breaks the whole pool (BrokenProcessPool): keep what
    finished, start a new pool and resubmit the rest; a task lost with `retries` + 1 broken pools fails."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    remaining = dict(pending)
    losses = {key: 0 for key in remaining}
    while remaining:
        pool = ProcessPoolExecutor(
            max_workers=min(workers, len(remaining)),
            mp_context=_mp_context(),
            initializer=_set_worker_shared,
            initargs=(shared,),
        )
        broken = False
        try:
            futures = {pool.submit(_call, function, task): key for key, task in remaining.items()}
            waiting = set(futures)
            while waiting:
                done, waiting = wait(waiting, return_when=FIRST_COMPLETED)
                for future in done:
                    key = futures[future]
                    try:
                        value = future.result()
                    except BrokenProcessPool:
                        broken = True
                        continue
                    del remaining[key]
                    finished(key, value)
                if broken:
                    break
        except BaseException:
            # the workers run on otherwise: a SIGTERM (`kill`, a driver's terminate()) reaches this
            # process alone, and its exit would wait for every task already running
            for process in list((pool._processes or {}).values()):
                process.terminate()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=not broken, cancel_futures=True)
        if broken:
            for key in remaining:
                losses[key] += 1
            lost = [key for key in remaining if losses[key] > retries]
            if lost:
                raise StudyError(
                    f"{len(lost)} task(s) lost their worker {retries + 1} times (a worker process died: out of "
                    "memory, or killed); free memory or run fewer at once with a smaller --jobs"
                )


def _mp_context():
    """Fork is fast but unsafe once torch has started threads; forkserver gives fresh workers that
    still import neurotac_cli from the same environment."""
    import multiprocessing

    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    return multiprocessing.get_context(method)


def _run_dask(function, pending: dict, shared: dict, scheduler, retries: int, label: str, finished):
    """A Dask cluster. The scheduler reruns tasks of a worker that died by itself (up to its
    `distributed.scheduler.allowed-failures`); `retries` reruns tasks that raised."""
    try:
        from distributed import Client, as_completed
        from distributed.scheduler import KilledWorker
    except ImportError as error:
        raise StudyError(
            f"--scheduler needs Dask distributed ({error}); install it with `pip install 'neurotac[dask]'`"
        ) from None

    own_client = not isinstance(scheduler, Client)
    client = _client(Client, scheduler) if own_client else scheduler
    prefix = re.sub(r"[^A-Za-z0-9_.]+", "-", label).strip("-") or "tasks"
    futures = {}
    try:
        # Shared data goes to every worker once; the tasks refer to it by its futures.
        shared_futures = client.scatter(shared, broadcast=True, hash=True) if shared else {}
        for key, task in pending.items():
            future = client.submit(
                _call, function, task, shared_futures, key=f"{prefix}-{key}", pure=False, retries=retries
            )
            futures[future] = key
        for future in as_completed(list(futures), loop=client.loop):
            try:
                value = future.result()
            except KilledWorker as error:
                raise StudyError(
                    f"a task killed every worker that ran it ({error}); it may need more memory than a worker "
                    "has: start workers with a larger --memory-limit"
                ) from None
            finished(futures[future], value)
            future.release()
    finally:
        for future in futures:
            if not future.done():
                future.cancel()
        if own_client:
            client.close()


def _client(Client, scheduler):
    """A Dask client of the scheduler at this address or scheduler file. A path is a scheduler file
    (`dask scheduler --scheduler-file PATH`), the usual hand-over on SLURM/PBS where the scheduler's
    address is not known before its job starts."""
    where = {"scheduler_file": str(scheduler)} if os.path.isfile(str(scheduler)) else {"address": scheduler}
    if "address" in where and not re.match(r"^([a-z]+://)?[^\s/:]+(:\d+)$|^[a-z]+://", str(scheduler)):
        raise UsageError(
            f"--scheduler {scheduler!r} is neither an address like tcp://HOST:8786 nor a scheduler file "
            "(give the address `dask scheduler` printed, or the path of its --scheduler-file)"
        )
    if "address" in where:
        _check_speaks_dask(str(scheduler))
    try:
        return Client(**where, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except MemoryError:  # a reply read as a Dask message's length (exabytes)
        raise StudyError(f"{scheduler} answered, but not as a Dask scheduler does; give the address `dask scheduler` "
                         "printed (its port, 8786 unless set, not the dashboard's 8787)") from None
    except (OSError, TimeoutError, ValueError) as error:
        raise StudyError(
            f"cannot reach the Dask scheduler at {scheduler} ({error}); start one with `dask scheduler` "
            "and workers with `dask worker ADDRESS`, or drop --scheduler to run here"
        ) from None


def _check_speaks_dask(address: str) -> None:
    """Refuse an address that is not a Dask scheduler's, in seconds: a scheduler sends its handshake
    as a connection opens (a message whose first 8 bytes are a small frame count), while a web
    server waits for a request or answers in text. Given such a server, Dask's client waited for
    good (one that never answers) or read its reply as a message of exabytes and failed as out of
    memory, with a traceback from its clean-up. TLS and other transports are left to Dask."""
    import socket

    match = re.match(r"^(?:tcp://)?\[?([^\s/\]]+?)\]?:(\d+)$", address)
    if not match:
        return
    host, port = match.group(1), int(match.group(2))
    try:
        connection = socket.create_connection((host, port), timeout=PROBE_TIMEOUT)
    except OSError:
        return  # unreachable (or slow to answer): Dask's own attempt says so, within its timeout
    first = b""
    with connection:
        try:
            while len(first) < 8:
                more = connection.recv(8 - len(first))
                if not more:
                    break
                first += more
        except socket.timeout:
            first = None
        except OSError:
            return
    if first is None or len(first) < 8 or int.from_bytes(first, "little") > 1 << 20:
        heard = ("sent nothing when connected" if first is None else "closed the connection" if not first
                 else f"answered {first[:8]!r}")
        raise StudyError(f"{address} is not a Dask scheduler: it {heard}; give the address `dask scheduler` printed "
                         "(its port, 8786 unless set, not the dashboard's 8787)")


PROBE_TIMEOUT = 5.0  # seconds a scheduler has to send its handshake once connected (a few ms on a LAN)


# --------------------------------------------------------------------------------------------------
# Task identity and the cache


def task_key(function: Callable, task: dict) -> str:
    """A hash of the function's qualified name, the neurotac version and the task's content: the
    name of the task's cache entry. Tables and arrays in a task are hashed by content."""
    from neurotac_cli import __version__

    name = f"{getattr(function, '__module__', '?')}.{getattr(function, '__qualname__', repr(function))}"
    identity = {"function": name, "version": __version__, "format": CACHE_FORMAT, "task": _canonical(task)}
    device = os.environ.get(DEVICE_VARIABLE, "").strip()
    if device and device != "cpu":  # a GPU's trainings differ in the last digits: kept apart from the CPU's
        identity["device"] = device
    text = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def data_digest(data) -> str:
    """A content hash of a table, array, bytes or file path (by the file's bytes): use it in a task in
    place of the data itself, so the task stays small and its cache key still changes with the data."""
    hasher = hashlib.sha256()
    if isinstance(data, (str, os.PathLike)) and os.path.isfile(data):
        with open(data, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                hasher.update(block)
    else:
        hasher.update(json.dumps(_canonical(data), sort_keys=True).encode())
    return hasher.hexdigest()[:32]


def _canonical(value):
    """`value` as JSON-able data that is equal exactly when the values are."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return {"float": value.hex()}
    if isinstance(value, dict):
        return {"dict": sorted(([str(k), _canonical(v)] for k, v in value.items()))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return {"set": sorted(json.dumps(_canonical(v), sort_keys=True) for v in value)}
    if isinstance(value, os.PathLike):
        return {"path": os.fspath(value)}
    if isinstance(value, bytes):
        return {"bytes": hashlib.sha256(value).hexdigest()}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"dataclass": type(value).__qualname__, "fields": _canonical(dataclasses.asdict(value))}
    module = type(value).__module__.split(".")[0]
    if module == "numpy":
        import numpy as np

        if isinstance(value, np.generic):
            return _canonical(value.item())
        if isinstance(value, np.ndarray):
            array = np.ascontiguousarray(value)
            digest = hashlib.sha256(array.view(np.uint8).reshape(-1) if array.size else b"").hexdigest()
            return {"ndarray": [str(array.dtype), list(array.shape), digest]}
    if module == "pyarrow":
        return {"arrow": _arrow_digest(value)}
    if callable(value) and hasattr(value, "__qualname__"):
        return {"callable": f"{value.__module__}.{value.__qualname__}"}
    raise TypeError(
        f"a task value of type {type(value).__name__} cannot be hashed for the study cache; "
        "pass plain values, paths, arrays or Arrow tables (or their data_digest)"
    )


def _arrow_digest(value) -> str:
    import pyarrow as pa

    if isinstance(value, pa.RecordBatch):
        value = pa.Table.from_batches([value])
    if isinstance(value, pa.Table):
        return hashlib.sha256(_arrow_bytes(value.combine_chunks())).hexdigest()
    if isinstance(value, pa.Schema):
        return hashlib.sha256(value.serialize().to_pybytes()).hexdigest()
    raise TypeError(f"cannot hash a {type(value).__name__} for the study cache")


# --------------------------------------------------------------------------------------------------
# Results as pickles that cannot run code when read
#
# A pickle names the callables that rebuild its objects, and loading one calls them: a crafted cache
# entry (its checksum made to match) could run anything. So a result is pickled with its arrays,
# numpy scalars and Arrow tables taken out as .npy and Arrow IPC bytes (formats that hold data only),
# leaving a pickle of builtin containers and numbers; the reader rebuilds those two kinds itself and
# refuses every class a pickle names but `complex`.

_SAFE_GLOBALS = {("builtins", "complex")}


class _ResultPickler(pickle.Pickler):
    def persistent_id(self, value):
        kind = type(value).__module__.split(".")[0]
        if kind == "numpy":
            import numpy as np

            if isinstance(value, np.ndarray):
                return ("npy", _npy_bytes(value))
            if isinstance(value, np.generic):
                return ("npy scalar", _npy_bytes(value))
        elif kind == "pyarrow":
            import pyarrow as pa

            if isinstance(value, pa.Table):
                return ("arrow", _arrow_bytes(value))
        return None

    def reducer_override(self, value):
        # Called only for values of non-builtin types: everything the reader would refuse stops here.
        if type(value) is complex or value is complex:
            return NotImplemented
        raise TypeError(
            f"a task result holding a {type(value).__module__}.{type(value).__qualname__} cannot be kept in the "
            "study cache; return builtin containers, numbers, strings, numpy arrays or Arrow tables"
        )


def _npy_bytes(value) -> bytes:
    import numpy as np

    sink = io.BytesIO()
    try:
        np.save(sink, np.asarray(value), allow_pickle=False)
    except ValueError:
        raise TypeError(f"a task result holds a numpy {value.dtype} array, which the study cache cannot keep "
                        "(object arrays need pickle); return arrays of numbers or strings") from None
    return sink.getvalue()


def _arrow_bytes(value) -> bytes:
    import pyarrow as pa

    sink = io.BytesIO()
    with pa.ipc.new_stream(sink, value.schema) as writer:
        writer.write(value)
    return sink.getvalue()


def _dump_result(value) -> bytes:
    sink = io.BytesIO()
    _ResultPickler(sink, protocol=pickle.HIGHEST_PROTOCOL).dump(value)
    return sink.getvalue()


class _ResultUnpickler(pickle.Unpickler):
    def find_class(self, module, name):
        if (module, name) in _SAFE_GLOBALS:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"the study cache does not read {module}.{name}")

    def persistent_load(self, pid):
        if not (isinstance(pid, tuple) and len(pid) == 2 and isinstance(pid[1], bytes)):
            raise pickle.UnpicklingError("a malformed array or table in a study cache entry")
        kind, data = pid
        if kind in ("npy", "npy scalar"):
            import numpy as np

            array = np.load(io.BytesIO(data), allow_pickle=False)
            return array[()] if kind == "npy scalar" else array
        if kind == "arrow":
            import pyarrow as pa

            try:
                table = pa.ipc.open_stream(data).read_all()
                table.validate(full=True)
            except (pa.ArrowException, OSError) as error:
                raise pickle.UnpicklingError(f"a damaged table in a study cache entry ({error})") from None
            return table
        raise pickle.UnpicklingError(f"the study cache does not read {kind!r} values")


class _Cache:
    """One pickle per finished task (see `_dump_result`: reading one never runs code), written to a
    temporary name and renamed into place, so an interruption leaves either the whole result or nothing."""

    def __init__(self, folder):
        self.folder = pathlib.Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise StudyError(f"cannot create the study cache folder {folder} ({error.strerror}; pick another --cache)") from None

    def path(self, key: str) -> pathlib.Path:
        return self.folder / key[:2] / f"{key}.pkl"

    # Each entry is its payload's SHA-256, then the payload: a damaged entry (a flipped bit, a file
    # cut or replaced) is run again, since read as it is it would fail with a traceback, or put
    # changed numbers into the study's results.
    DIGEST = 32

    def get(self, key: str):
        try:
            with open(self.path(key), "rb") as handle:
                data = handle.read()
        except OSError:
            return False, None  # no entry, or an unreadable one: run the task
        digest, payload = data[: self.DIGEST], data[self.DIGEST :]
        if len(data) <= self.DIGEST or hashlib.sha256(payload).digest() != digest:
            return False, None
        try:
            return True, _ResultUnpickler(io.BytesIO(payload)).load()
        except (EOFError, ValueError, TypeError, pickle.UnpicklingError, AttributeError, ImportError):
            return False, None  # not a result this version writes (or a crafted one): run the task again

    def put(self, key: str, value) -> None:
        from neurotac_cli.tables import atomic_file

        target = self.path(key)
        payload = _dump_result(value)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with atomic_file(str(target)) as temporary, open(temporary, "wb") as handle:
                handle.write(hashlib.sha256(payload).digest() + payload)
                handle.flush()
                os.fsync(handle.fileno())
        except OSError as error:
            from neurotac_cli.errors import OutputError

            # something else where an entry goes (a file, a folder) has its own advice; the rest, a full
            # disk or a read-only folder, the advice every output gets
            blocked = error.errno in (errno.EEXIST, errno.ENOTDIR, errno.EISDIR)
            why, what_to_do = (error.strerror, "remove what is there") if blocked else OutputError.why(error)
            raise StudyError(f"cannot write the study cache entry {target} ({why}: {error.filename2 or error.filename}); "
                             f"{what_to_do}, or pick another --cache") from None

    def found(self, keys) -> dict:
        """{key: result} of the keys that have a readable entry."""
        results = {}
        for key in dict.fromkeys(keys):
            found, value = self.get(key)
            if found:
                results[key] = value
        return results

    def keys(self) -> set[str]:
        return {path.stem for path in self.folder.glob("*/*.pkl")}

    def told(self, keys, total: int, label: str) -> str:
        """The line saying how many of a study's `total` tasks came from the cache, and when the oldest
        of them finished (UTC, ISO 8601 to the second: a script compares it with its own start to tell
        an earlier run's trainings from those its own studies shared)."""
        written = min(self.path(key).stat().st_mtime for key in keys)
        oldest = datetime.datetime.fromtimestamp(written, datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
        return f"{label}: {len(keys)} of {total} tasks from the cache {self.folder}, the oldest finished {oldest} (not in this run's time)"


def cached_keys(cache_dir) -> set[str]:
    """The task keys that have a result in `cache_dir` (for tests and `neurotac info`-like reports)."""
    return _Cache(cache_dir).keys() if pathlib.Path(cache_dir).is_dir() else set()


# --------------------------------------------------------------------------------------------------
# Progress


class Progress:
    """`label: 12/40 done (3 cached), 0:34 elapsed, ~1:20 left` on stderr: rewritten in place on a
    terminal, one line at most every 10 s otherwise."""

    def __init__(self, total: int, *, cached: int = 0, label: str = "tasks", enabled=None, stream=None):
        self.stream = stream or sys.stderr
        if enabled is None:
            enabled = bool(os.environ.get("NEUROTAC_PROGRESS")) or _isatty(self.stream)
        self.enabled = enabled and total > 0
        self.terminal = _isatty(self.stream)
        self.total, self.cached, self.done = total, cached, cached
        self.label = label
        self.start = time.monotonic()
        self.last_shown = -math.inf
        self.shown_done = None

    def advance(self):
        self.done += 1
        self.show()

    def show(self, final: bool = False):
        if not self.enabled:
            return
        now = time.monotonic()
        interval = 0.2 if self.terminal else 10.0
        if not final and self.done < self.total and now - self.last_shown < interval:
            return
        if final and not self.terminal and self.shown_done == self.done:
            return
        self.last_shown, self.shown_done = now, self.done
        line = self.line(now)
        end = "" if self.terminal and not final else "\n"
        prefix = "\r\033[K" if self.terminal else ""
        self.stream.write(f"{prefix}{line}{end}")
        self.stream.flush()

    def line(self, now: float) -> str:
        elapsed = now - self.start
        ran = self.done - self.cached
        text = f"{self.label}: {self.done}/{self.total} done"
        if self.cached:
            text += f" ({self.cached} cached)"
        text += f", {_clock(elapsed)} elapsed"
        if self.done < self.total:
            text += f", ~{_clock(elapsed / ran * (self.total - self.done))} left" if ran else ", time left unknown"
        return text

    def close(self):
        if self.enabled and self.last_shown > -math.inf:
            self.show(final=True)


def _isatty(stream) -> bool:
    from neurotac_cli.tables import is_terminal

    return is_terminal(stream)


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, seconds = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{seconds:02d}" if hours else f"{minutes}:{seconds:02d}"


# --------------------------------------------------------------------------------------------------
# The --grid grammar

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_RANGE = re.compile(rf"^({_NUMBER})\.\.({_NUMBER})(?::({_NUMBER}))?$")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.-]*$")


def parse_grid(specs) -> list[dict]:
    """Expand `--grid` specs into grid points: the product of every name's values, the last name
    varying fastest.

    \b
    Each spec is `NAME=VALUES` (several may share one string, separated by spaces). VALUES is a comma
    list of numbers or words; `A..B` is the integers A to B inclusive, `A..B:STEP` steps by STEP, and
    `A,B,...,Z` continues the step B-A up to Z:
        parse_grid(["layers=1..3", "units=5,10,...,20"])  ->  12 points
        parse_grid(["model=lstm,cnnlstm seed=0..9"])       ->  20 points
    No spec gives one point with no parameters ([{}]).
    """
    axes: dict[str, list] = {}
    for spec in specs or ():
        for item in str(spec).split():
            name, sep, text = item.partition("=")
            name = name.strip()
            if not sep or not _NAME.match(name):
                raise UsageError(f"grid spec {item!r} is not NAME=VALUES (write e.g. --grid layers=1..5)")
            if name in axes:
                raise UsageError(f"grid name {name!r} is given twice (give all its values at once: {name}=1,2,3)")
            axes[name] = _grid_values(name, text)
    names = list(axes)
    return [dict(zip(names, point)) for point in itertools.product(*axes.values())]


def _grid_values(name: str, text: str) -> list:
    parts = [part.strip() for part in text.split(",")]
    if not text.strip() or any(part == "" for part in parts):
        raise UsageError(f"grid {name}={text!r} has an empty value (write e.g. {name}=5,10,40)")
    values: list = []
    index = 0
    while index < len(parts):
        part = parts[index]
        if part == "...":
            if len(values) < 2 or index + 1 >= len(parts):
                raise UsageError(
                    f"grid {name}={text}: `...` needs two values before it and one after (e.g. {name}=5,10,...,40)"
                )
            first, second, last = values[-2], values[-1], _scalar(parts[index + 1])
            if not all(isinstance(v, (int, float)) for v in (first, second, last)):
                raise UsageError(f"grid {name}={text}: `...` continues numbers only")
            values.extend(_arange(second, last, second - first, name, text)[1:])
            index += 2
            continue
        match = _RANGE.match(part)
        if match:
            start, stop = _scalar(match.group(1)), _scalar(match.group(2))
            if not match.group(3) and not (isinstance(start, int) and isinstance(stop, int)):
                # A..B steps by 1: between 1e-3 and 1e-2 that is one value, not the range meant
                raise UsageError(f"--grid {name}={text}: {part} has no step, and A..B steps by 1 between whole numbers "
                                 f"only; give a step ({part}:STEP) or list the values ({name}=A,B,C)")
            step = _scalar(match.group(3)) if match.group(3) else 1
            values.extend(_arange(start, stop, step, name, text))
        elif ".." in part:
            raise UsageError(f"--grid {name}={text}: {part!r} is not a range of numbers (write e.g. {name}=1..5 or {name}=1..9:2)")
        else:
            values.append(_scalar(part))
        index += 1
    repeated = sorted(str(value) for value, times in collections.Counter(values).items() if times > 1)
    if repeated:  # each point would be trained again for nothing (1 and 1.0 are one value)
        raise UsageError(f"grid {name}={text} gives {', '.join(repeated)} more than once; give each value once")
    return values


def _arange(start, stop, step, name, text) -> list:
    if step == 0 or (stop - start) * step < 0:
        raise UsageError(f"grid {name}={text}: the range {start}..{stop} with step {step} never reaches its end")
    count = int(math.floor((stop - start) / step + 1e-9)) + 1
    if count > 100_000:
        raise UsageError(f"grid {name}={text} has {count} values (more than 100000; use a larger step)")
    last = start + (count - 1) * step
    if abs(last - stop) > 1e-9 * max(1.0, abs(stop)):  # A..B is inclusive: an end the steps pass over would be left out
        raise UsageError(f"grid {name}={text}: the steps of {step} from {start} end at {round(last, 12)}, not at {stop}; "
                         "give an end the steps reach, or list the values")
    if all(isinstance(v, int) for v in (start, stop, step)):
        return [start + i * step for i in range(count)]
    return [round(start + i * step, 12) for i in range(count)]


def _scalar(text: str):
    """`5` -> 5, `0.5` -> 0.5, `1e-3` -> 0.001, anything else stays a string."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def grid_points(specs, fixed: dict | None = None) -> list[dict]:
    """The grid points of `--grid` specs, each with the `fixed` hyperparameters (options such as
    `--epochs 30` given beside the grid) added; a name both fixed and varied is refused."""
    points = parse_grid(specs)
    fixed = {name: value for name, value in (fixed or {}).items() if value is not None}
    both = sorted(fixed.keys() & set(points[0]))
    if both:
        raise UsageError(
            f"{', '.join(both)} given both as an option and in --grid (give each hyperparameter once: "
            f"a single value in --grid, e.g. --grid {both[0]}=30, fixes it)"
        )
    return [{**point, **fixed} for point in points]
