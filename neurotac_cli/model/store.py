"""Model files: safetensors weights with a JSON header (DESIGN.md §4). No pickle: loading reads
arrays and JSON, builds the network from the header's config, and never executes code from the file."""

import dataclasses
import json
import math
import os

from neurotac_cli.errors import ModelError, UsageError, empty_path
from neurotac_cli.held import HeldSignals
from neurotac_cli.schema import is_positive_count, is_sensor
from neurotac_cli.model.names import FORMAT_VERSION
from neurotac_cli.tables import atomic_file

HEADER_KEY = "neurotac"


def save(model, path: str):
    """Write `model` to `path` atomically (temporary file beside it, then rename)."""
    from safetensors.torch import save_file

    tensors = {name: tensor.detach().contiguous().clone() for name, tensor in model.net.state_dict().items()}
    bad = _not_finite(tensors)
    if bad:
        raise ModelError(f"training diverged: the weights {', '.join(bad[:3])} hold NaN or infinite values; "
                         "nothing written (lower --lr, or check the training data)")
    header = json.dumps({**model.header(), DIGEST_KEY: weights_digest(tensors)}, sort_keys=True, default=_json_default)
    with atomic_file(path) as temporary:
        try:
            save_file(tensors, temporary, metadata={HEADER_KEY: header})
        except Exception as error:  # safetensors' own error type, from Rust: a full disk is not an OSError there
            raise _as_os_error(error) from None


def _as_os_error(error: Exception) -> Exception:
    """safetensors' error of writing ("I/O error: File too large (os error 27)") as the OSError it
    wraps, which `atomic_file` words as every output's; any other error as it is."""
    import re

    found = re.search(r"\(os error (\d+)\)", str(error))
    if type(error).__name__ != "SafetensorError" or not found:
        return error
    number = int(found.group(1))
    return OSError(number, os.strerror(number))


DIGEST_KEY = "weights_sha256"  # files written before it have none, and are checked for finite weights only


def weights_digest(tensors: dict) -> str:
    """SHA-256 over every tensor's name, type, shape and bytes, in name order: a byte changed in the
    weights (a damaged disk or copy) changes it, while a finite but absurd weight would pass any
    range check and estimate nonsense without a word."""
    import hashlib

    import torch

    digest = hashlib.sha256()
    for name in sorted(tensors):
        tensor = tensors[name].detach().contiguous().cpu()
        digest.update(f"{name}|{tensor.dtype}|{tuple(tensor.shape)}|".encode())
        digest.update(tensor.view(-1).view(torch.uint8).numpy().tobytes() if tensor.numel() else b"")
    return digest.hexdigest()


def _not_finite(tensors: dict) -> list[str]:
    import torch

    return [name for name, tensor in tensors.items() if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all())]


def _json_default(value):
    import numpy as np

    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, (np.ndarray, tuple, set)):
        return list(value)
    return str(value)


def read_header(path: str) -> dict:
    from safetensors import safe_open

    if not os.path.exists(path):
        if path == "":
            raise UsageError(empty_path("model"))
        raise ModelError(f"{path}: no such model file (train one with `neurotac train --model NAME -o {path}`)")
    if not os.path.isfile(path):
        raise ModelError(f"{path} is not a regular file; give a model file written by `neurotac train`")
    try:
        with safe_open(path, framework="numpy") as handle:  # the header only: no torch needed
            metadata = handle.metadata() or {}
    except Exception as error:  # safetensors raises its own error types for foreign bytes
        raise ModelError(f"{path} is not a neurotac model file ({str(error).splitlines()[0]}); give a file written by `neurotac train`") from None
    if HEADER_KEY not in metadata:
        raise ModelError(f"{path} is a safetensors file without a neurotac header; give a file written by `neurotac train`")
    try:
        header = json.loads(metadata[HEADER_KEY])
    except ValueError:
        raise ModelError(f"{path}: the model header is not valid JSON (file damaged?)") from None
    if not isinstance(header, dict) or header.get("format") != "neurotac-model":
        raise ModelError(f"{path}: not a neurotac model header")
    missing = [key for key in ("model", "task", "architecture", "input") if key not in header]
    if missing:
        raise ModelError(f"{path}: the model header lacks {', '.join(missing)} (file damaged?); train the model again")
    version = header.get("format_version", 1)
    if not is_positive_count(version):
        raise ModelError(f"{path}: the model header's format_version {version!r} is not a format number (file edited or "
                         "damaged?); train the model again")
    if version > FORMAT_VERSION:
        raise ModelError(f"{path}: model format {version!r} is newer than this neurotac reads ({FORMAT_VERSION}); "
                         "upgrade neurotac to run it")
    _check_parts(path, header)
    return header


def _check_parts(path: str, header: dict):
    """Refuse a header whose parts are not what `train` writes (a file edited by hand, or damaged):
    such parts fail deep in numpy or torch, or run with a nonsense constant (a force scale of 0 or
    NaN would estimate 0 or NaN N on every frame)."""
    def bad(what: str, should: str):
        return ModelError(f"{path}: the model header's {what} is not {should} (file edited or damaged?); train the model again")

    spec, training, task = header["input"], header.get("training"), header["task"]
    for what, value, kind in (("architecture", header["architecture"], dict), ("input", spec, dict),
                              ("training", {} if training is None else training, dict)):
        if not isinstance(value, kind):
            raise bad(what, "a JSON object")
    if task not in ("force", "material"):
        raise bad(f"task {task!r}", "force or material")
    for key in ("width", "height"):
        if not is_positive_count(spec.get(key)):
            raise bad(f"input {key}", "a whole number of pixels, 1 or more")
    if spec.get("window_us") is not None and not is_positive_count(spec["window_us"]):
        raise bad("input window_us", "a whole number of µs, 1 or more")
    if not isinstance(spec.get("accumulated", False), bool):
        raise bad("input accumulated", "true or false")
    normalisation = spec.get("normalisation")
    if not isinstance(normalisation, dict):
        raise bad("input normalisation", "a JSON object")
    scale = normalisation.get("force_scale")
    if task == "force" and not (isinstance(scale, (int, float)) and not isinstance(scale, bool) and 0 < scale < math.inf):
        raise bad(f"force scale {scale!r}", "a number of newtons above 0")
    classes = header.get("classes")
    if (task == "material" or classes is not None) and not (
            isinstance(classes, list) and len(classes) >= (2 if task == "material" else 0)
            and all(isinstance(c, str) and c for c in classes) and len(set(classes)) == len(classes)):
        raise bad("class list", "two or more distinct class names")
    sensor = spec.get("sensor")
    if sensor is not None and not is_sensor(sensor):
        raise bad("input sensor", "a width and a height in pixels")
    _check_training(bad, training or {})


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_training(bad, training: dict):
    """The parts of a header's training record that `info`, `eval` and `predict` read."""
    for key, kind, item in (("data_history", list, dict), ("curve", list, dict), ("trials", dict, None), ("fit", dict, None),
                            ("label", str, None)):
        value = training.get(key)
        if value is not None and (not isinstance(value, kind) or (item and not all(isinstance(v, item) for v in value))):
            raise bad(f"training {key}", f"a {'list of JSON objects' if item else 'JSON object' if kind is dict else 'string'}")
    if not all(isinstance(step.get("args", {}), dict) for step in training.get("data_history") or []):
        raise bad("training data_history", "a list of steps with their arguments as JSON objects")
    curves = [training.get("curve") or []]
    members = training.get("member_curves")
    if members is not None and not (isinstance(members, list) and all(isinstance(c, list) for c in members)):
        raise bad("training member_curves", "a list of training curves")
    curves += members or []
    best = training.get("member_best_epochs")
    if best is not None and not (isinstance(best, list) and all(isinstance(e, int) and not isinstance(e, bool) and e >= 0 for e in best)
                                 and (members is None or len(best) == len(members))):
        raise bad("training member_best_epochs", "a list of epoch numbers, one per member curve")
    if not all(isinstance(row, dict) and _number(row.get("train_loss")) and _number(row.get("val_loss")) for c in curves for row in c):
        raise bad("training curve", "a list of epochs with their train_loss and val_loss")
    if not all(isinstance(value, list) for value in (training.get("trials") or {}).values()):
        raise bad("training trials", "lists of trial names")
    busiest = training.get("events_per_frame_max")
    if busiest is not None and not _number(busiest):
        raise bad("training events_per_frame_max", "a number")


def load(path: str):
    """Read a model file written by `save`."""
    from safetensors.torch import load_file

    from neurotac_cli.model.core import FIT_ONLY, Model, _check_setting, _module

    header = read_header(path)
    name = header["model"]
    module = _module(name)
    config_type = module.Config
    known = {f.name for f in dataclasses.fields(config_type)}
    spec = header["input"]
    try:  # a header edited by hand, or damaged, fails here rather than deep in torch
        settings = {**getattr(module, "ABSENT_MEANS", {}), **header["architecture"]}
        config = config_type(**{k: v for k, v in settings.items() if k in known})
        for key, value in dataclasses.asdict(config).items():  # the bounds `train` holds its options to
            if key not in FIT_ONLY:  # bounds that moved since a model was fitted do not unmake it
                _check_setting(key, value, name)
        if header["task"] == "material":
            net = module.Net(config, len(header["classes"]))
        else:
            net = module.Net(config, (2, int(spec["height"]), int(spec["width"])))
    except UsageError as error:
        raise ModelError(f"{path}: the model header's {name} architecture is out of bounds ({error}); train the model "
                         "again") from None
    except (TypeError, KeyError, ValueError, AttributeError, RuntimeError) as error:
        raise ModelError(f"{path}: the model header does not describe a {name} network ({type(error).__name__}: "
                         f"{str(error).splitlines()[0] if str(error) else error!r}); train the model again") from None
    tensors = load_file(path)
    bad = _not_finite(tensors)
    if bad:
        raise ModelError(f"{path}: the weights {', '.join(bad[:3])} hold NaN or infinite values "
                         "(a training that diverged, or a damaged file); train the model again")
    if DIGEST_KEY in header and header[DIGEST_KEY] != weights_digest(tensors):
        raise ModelError(f"{path}: the weights do not match the checksum written with them (a damaged file or copy); "
                         "copy the model again or train it again")
    try:
        net.prepare_for(tensors)
        net.load_state_dict(tensors, strict=True)
    except (RuntimeError, KeyError) as error:
        raise ModelError(f"{path}: weights do not match the header's architecture ({str(error).splitlines()[0]})") from None
    implausible = getattr(net, "implausible", lambda tensors: None)(tensors)
    if implausible:
        raise ModelError(f"{path}: {implausible}, outside what its training can give (a damaged file?); train the model again")
    return Model(name, config, net, spec, header.get("classes"), header.get("training"))


def load_in_background(path: str, threads: int = 1, signals: "HeldSignals | None" = None):
    """Start loading a model file (torch's import included, which takes seconds) in a thread; the
    returned callable waits for the model, or raises the loader's error. A verb reading a pipe
    loads its model while the verbs upstream start, not after its first input arrives. The thread is
    not a daemon: a verb that fails on its input while torch is still being imported waits for the
    import before it exits (a process ending mid-import aborts in torch's C++ teardown). Ctrl-C and
    SIGTERM wait until the model has loaded (`HeldSignals`: `signals`, where the caller began holding
    them before its own imports).

    Once loaded, the objects made so far (torch's modules, the model) are moved out of the cyclic
    garbage collector's reach (`gc.freeze`): a full collection scans every object and took 85-100 ms
    with torch loaded, stalling whichever frame it fell on; frozen, the stream's collections scan only
    the objects it makes itself. Refcounting frees everything as before."""
    import atexit
    import gc
    import threading

    signals = signals or HeldSignals()
    outcome, done = {}, signals.done

    def run():
        try:
            import torch

            torch.set_num_threads(max(1, threads))
            outcome["model"] = load(path)
            gc.collect()
            gc.freeze()
            atexit.unregister(gc.unfreeze)  # once per process, however many models it loads
            atexit.register(gc.unfreeze)  # at exit the frozen objects are collected as any others
        except BaseException as error:  # noqa: BLE001 - handed to the caller, who reports it
            outcome["error"] = error
        finally:
            done.set()
            signals.deliver()

    thread = threading.Thread(target=run)
    thread.start()

    def result():
        thread.join()
        signals.restore()
        if "error" in outcome:
            raise outcome["error"]
        return outcome["model"]

    return result


