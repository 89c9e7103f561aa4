"""HDF5 event files (`.h5`, `.hdf5`), read with h5py in slices of `SLICE_EVENTS` events.

Three layouts are in common use, each found by its names:

- Prophesee Metavision: a compound dataset `CD/events` of (x, y, p, t), t in integer µs. The SDK
  compresses it with its ECF codec, an HDF5 filter plugin that HDF5 loads from `HDF5_PLUGIN_PATH`;
  without it the data cannot be decoded, and the error says so.
- DSEC, TUM-VIE: one dataset per field, `x, y, t, p`, in a group `events/` (or at the root); DSEC
  adds a `t_offset` in µs at the root, added to every t.
- e2vid: `xs, ys, ts, ps` in `events/`; its times are float seconds. evlib writes the same names
  with float µs, so float times that are all whole numbers are read as µs, others as seconds (float
  whole numbers too large for their type to hold fractions are refused: either unit fits them).
  `t_offset` belongs to DSEC's layout and is read with it alone.

Integer times are µs. A polarity above zero is ON, so 0/1, -1/1 and booleans read alike.
Coordinates must be whole numbers. The sensor size comes from a `geometry` attribute ("1280x720",
as Metavision writes it) or integer `width`/`height` attributes of the file or the events' group;
otherwise from --sensor, else from the events' extent (a first pass over them), as for a DAT file.

What is refused, in one line, rather than read as something else: two layouts in one group (which
one is meant?), a field that is not one number per event, events stored in other files (external
links, virtual datasets, external raw storage: their bytes would escape the file's hash and depend
on the working folder), chunked datasets with whole chunks never written (HDF5 hands out fill
values for them; a contiguous dataset written in part cannot be told from a whole one), a codec
HDF5 cannot load, and a file another program holds open for writing.
"""

import numpy as np

from neurotac_cli.errors import FormatError, InputError, NeurotacError
from neurotac_cli.io.reader import Decoded
from neurotac_cli.units import parse_size

SIGNATURE = b"\x89HDF\r\n\x1a\n"
# the superblock sits at 0 or, after a user block, at 512 x 2^n bytes (those a 64 KiB head holds)
SIGNATURE_OFFSETS = (0, 512, 1024, 2048, 4096, 8192, 16384, 32768)
SLICE_EVENTS = 1 << 20
DSEC_FIELDS, E2VID_FIELDS = ("x", "y", "t", "p"), ("xs", "ys", "ts", "ps")
GROUPS = ("events", "")
LARGEST_US = 2.0**62  # timestamps beyond it (about 146,000 years) are damage, and would overflow int64 µs
ECF_FILTER = 0x8ECF  # Prophesee's self-assigned filter code


def is_hdf5(head: bytes) -> bool:
    return any(head[offset:offset + len(SIGNATURE)] == SIGNATURE for offset in SIGNATURE_OFFSETS)


def open_hdf5(path: str, head: bytes, sensor) -> Decoded:
    import h5py

    try:
        import hdf5plugin  # noqa: F401 - registers Blosc, LZ4, Zstd, ... with HDF5 (DSEC is Blosc-compressed)
    except ImportError:
        pass
    with _opened(h5py, path) as handle:
        layout = _layout(handle)
        datasets = _datasets(handle, layout)
        for name, dataset in ({layout["compound"]: datasets["t"]} if layout["compound"] else datasets).items():
            _check_stored(name, dataset)
        count = len(next(iter(datasets.values())))
        offset = _offset(handle) if layout["fields"] == DSEC_FIELDS and not layout["compound"] else 0
        seconds, note = _time_unit(layout, datasets["t"], count)
        declared = _declared_sensor(handle, layout)
    meta = {"source": {"hdf5_layout": layout["name"], "hdf5_events": int(count)}}
    if note:
        meta["source"]["note"] = note

    def chunks():
        with _opened(h5py, path) as handle:
            datasets = _datasets(handle, layout)
            for start in range(0, count, SLICE_EVENTS):
                yield _slice(datasets, layout, start, min(count, start + SLICE_EVENTS), offset, seconds)

    return Decoded(sensor=declared, chunks=chunks, meta=meta)


def _opened(h5py, path: str):
    try:
        return h5py.File(path, "r")
    except OSError as error:
        if "unable to lock file" in str(error).lower():
            raise InputError("another program holds the file open for writing (HDF5's file lock); import it once "
                             "written, or, if no writer is left, set HDF5_USE_FILE_LOCKING=FALSE") from None
        raise


def _layout(handle) -> dict:
    """How the events are stored, as the names of what to read."""
    import h5py

    for group, name in (("CD", "events"), ("", "events")):  # Metavision's compound, or the same at the root
        parent = _present(handle, group)
        node = _present(parent, name, "/".join(filter(None, (group, name)))) if isinstance(parent, h5py.Group) else None
        shown = "/".join(filter(None, (group, name)))
        if group and node is not None and not (isinstance(node, h5py.Dataset) and node.dtype.names):
            found = "a group" if isinstance(node, h5py.Group) else f"a dataset of {node.dtype}"
            raise FormatError(f"/{shown} is {found}, not Metavision's compound dataset of events (fields x, y, p, t)")
        if isinstance(node, h5py.Dataset) and node.dtype.names:
            compound = _member(parent, name, shown)
            missing = {"x", "y", "p", "t"} - set(compound.dtype.names)
            if missing:
                raise FormatError(f"{shown} has no field {sorted(missing)[0]!r} (fields: {', '.join(compound.dtype.names)})")
            if compound.ndim != 1:
                raise FormatError(f"{shown} has shape {compound.shape}: Metavision's events are one list")
            for field in ("x", "y", "t", "p"):
                _one_number(compound.dtype[field], f"{shown} field {field}")
            return {"name": "metavision" if group else "compound events", "group": group, "fields": ("x", "y", "t", "p"),
                    "compound": name}
    for group in GROUPS:
        node = _present(handle, group)
        if node is None:
            continue
        if isinstance(node, h5py.Dataset):
            raise FormatError(f"/{group} is one dataset ({node.dtype} of shape {node.shape}), whose columns this reader "
                              "cannot name: it reads one dataset per field in events/ (x, y, t, p as DSEC; xs, ys, ts, ps as "
                              "e2vid) or Metavision's compound CD/events")
        sets = [fields for fields in (DSEC_FIELDS, E2VID_FIELDS) if all(name in node for name in fields)]
        if len(sets) > 1:
            raise FormatError(f"/{group} holds both x,y,t,p and xs,ys,ts,ps: which events are meant is not clear; keep one")
        if sets:
            return {"name": "/".join(filter(None, (group, ",".join(sets[0])))), "group": group, "fields": sets[0], "compound": None}
        partial = [name for name in DSEC_FIELDS + E2VID_FIELDS if name in node]
        if partial:
            raise FormatError(f"/{group} holds {', '.join(partial)} but not a whole set of x, y, t, p (DSEC) or xs, ys, ts, "
                              "ps (e2vid)")
    raise FormatError("an HDF5 file without events in a layout this reader knows: CD/events (Metavision), "
                      "events/{x,y,t,p} (DSEC), events/{xs,ys,ts,ps} (e2vid); found "
                      f"{', '.join(sorted(handle.keys())[:8]) or 'nothing'} at the root")


def _present(group, name: str, shown: str | None = None):
    """`_node`, or None where `group` has no member `name` ("" is the group itself)."""
    if not name:
        return group
    return _node(group, name, shown) if group.get(name, getlink=True) is not None else None


def _node(group, name: str, shown: str | None = None):
    """A member of the file itself: links to other files are refused, as are links to nothing."""
    import h5py

    shown = shown or name
    link = group.get(name, getlink=True)
    if isinstance(link, h5py.ExternalLink):
        raise FormatError(f"/{shown} is a link to {link.filename}: import that file; events in other files would depend "
                          "on the folder it is read from and escape this file's hash")
    try:
        return group[name]
    except (KeyError, RuntimeError):  # a soft link to nothing, or a loop of soft links
        raise FormatError(f"/{shown} is a link that leads to no object") from None


def _member(group, name: str, shown: str):
    """A dataset of the file itself (`_node`), not a virtual one gathered from other files."""
    import h5py

    dataset = _node(group, name, shown)
    if not isinstance(dataset, h5py.Dataset):
        raise FormatError(f"/{shown} is a group, not a dataset of events")
    if dataset.is_virtual:
        raise FormatError(f"/{shown} is a virtual dataset whose events live in other files: import those files")
    return dataset


def _datasets(handle, layout) -> dict:
    """{field: dataset} (the one compound dataset under each name for Metavision), each checked."""
    group = handle[layout["group"]] if layout["group"] else handle
    if layout["compound"]:
        dataset = _member(group, layout["compound"], "/".join(filter(None, (layout["group"], layout["compound"]))))
        return {field: dataset for field in ("x", "y", "t", "p")}
    found = {}
    for field, name in zip("xytp", layout["fields"]):
        shown = "/".join(filter(None, (layout["group"], name)))
        dataset = _member(group, name, shown)
        if dataset.ndim != 1:
            raise FormatError(f"/{shown} holds {dataset.dtype} of shape {dataset.shape}, not one number per event")
        _one_number(dataset.dtype, f"/{shown}")
        found[field] = dataset
    lengths = {len(dataset) for dataset in found.values()}
    if len(lengths) != 1:
        shown = ", ".join(f"{name} {dataset.shape}" for name, dataset in zip(layout["fields"], found.values()))
        raise FormatError(f"the event fields of /{layout['group']} are not four lists of one length ({shown})")
    return found


def _one_number(dtype, shown: str):
    """An event field is one integer, float or bool: not text, a sub-array or a compound."""
    if dtype.names or dtype.shape or not (np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating) or dtype == bool):
        raise FormatError(f"{shown} holds {dtype}, not one number per event")


def _check_stored(field: str, dataset):
    """Refuse what HDF5 would read as something else, or from elsewhere: a codec it cannot load, values
    kept in raw files beside this one, or whole chunks declared and never written (it fills them with
    the fill value, silently)."""
    import h5py

    plist = dataset.id.get_create_plist()
    for index in range(plist.get_nfilters()):
        code, _, _, name = plist.get_filter(index)
        if not h5py.h5z.filter_avail(code):
            if code == ECF_FILTER:
                raise FormatError("the events are compressed with Prophesee's ECF codec, which HDF5 loads as a plugin: "
                                  "put the hdf5_ecf plugin on HDF5_PLUGIN_PATH, or convert the file with "
                                  "metavision_file_to_raw (EVT 3.0) or metavision_file_to_dat")
            label = name.decode(errors="replace") if isinstance(name, bytes) else str(name)
            raise FormatError(f"the events are compressed with HDF5 filter {code} ({label or 'unnamed'}), which this "
                              "installation cannot load: install its plugin (hdf5plugin has most) or rewrite the file uncompressed")
    if plist.get_external_count():
        raise FormatError(f"the {field} field keeps its values in raw files beside this one (HDF5 external storage): "
                          "they would depend on the folder it is read from and escape this file's hash; rewrite it as one file")
    if not len(dataset):
        return
    if dataset.chunks:
        expected = -(-len(dataset) // dataset.chunks[0])
        written = dataset.id.get_num_chunks()
    else:  # contiguous storage is allocated when written; compact storage lives in the header
        expected = 1
        written = 1 if plist.get_layout() == h5py.h5d.COMPACT or dataset.id.get_storage_size() > 0 else 0
    if written < expected:
        raise FormatError(f"the {field} field declares {len(dataset):,} events but only {written} of its {expected} "
                          "blocks were written (a recording cut short, or a file still being written): HDF5 would "
                          "fill the rest with made-up values")


def _offset(handle) -> int:
    """DSEC's `t_offset`: one whole number of µs at the root, added to every t."""
    if "t_offset" not in handle:
        return 0
    value = handle["t_offset"]
    if not hasattr(value, "dtype") or value.size != 1 or not np.issubdtype(value.dtype, np.integer):
        shown = (f"{value.dtype} of shape {value.shape}" if value.shape is not None else "no value") if hasattr(value, "dtype") else "a group"
        raise FormatError(f"t_offset holds {shown}; DSEC's is one whole number of µs")
    offset = int(np.asarray(value[()]).ravel()[0])
    if abs(offset) >= LARGEST_US:
        raise FormatError(f"t_offset of {offset} µs is not a time a camera writes")
    return offset


def _time_unit(layout, dataset, count: int) -> tuple[bool, str | None]:
    """(float times are seconds, a note on their resolution). Metavision writes integer µs only;
    e2vid float seconds, evlib float whole µs: told apart by fractions in the head, middle and tail
    (each slice checks it again, `_slice`)."""
    if not np.issubdtype(dataset.dtype, np.floating):
        return False, None
    if layout["compound"]:
        raise FormatError("the compound events hold float times; Metavision writes whole µs (int64)")
    if not count:
        return True, None
    middle = count // 2
    sample = np.concatenate([np.asarray(dataset[a:b]) for a, b in ((0, 4096), (max(0, middle - 2048), middle + 2048),
                                                                   (max(0, count - 4096), count))])
    largest = float(np.nanmax(np.abs(sample))) if np.isfinite(sample).any() else 0.0
    whole = bool(np.all(sample[np.isfinite(sample)] == np.round(sample[np.isfinite(sample)])))
    if whole and float(np.spacing(dataset.dtype.type(largest))) >= 1:
        raise FormatError(f"the times are {dataset.dtype} whole numbers up to {largest:g}, a size at which that type holds "
                          "no fractions, so whether they are seconds or µs cannot be told: write them as integer µs")
    seconds = not whole
    note = None
    if seconds and dataset.dtype.itemsize < 8:
        last = abs(float(dataset[count - 1]))
        step = float(np.spacing(np.float32(last))) * 1e6
        if step > 1.0:
            note = (f"the times are stored as 32-bit floats, which near the recording's end ({last:g} s) tell apart "
                    f"only {step:,.0f} µs: finer times were lost when the file was written")
    return seconds, note


def _declared_sensor(handle, layout) -> tuple[int, int] | None:
    for node in (handle, handle[layout["group"]] if layout["group"] else handle):
        attrs = node.attrs
        if "geometry" in attrs:
            text = attrs["geometry"]
            text = text.decode(errors="replace") if isinstance(text, bytes) else str(text)
            try:
                return parse_size(text)
            except NeurotacError as error:
                raise FormatError(f"the geometry attribute: {error}") from None
        if "width" in attrs and "height" in attrs:
            values = [np.asarray(attrs[name]).ravel() for name in ("width", "height")]
            if any(v.size != 1 or not np.issubdtype(v.dtype, np.integer) for v in values):
                shown = [str(v.tolist()[0] if v.size == 1 else v.tolist()) for v in values]
                raise FormatError(f"the width and height attributes hold {shown[0]} and {shown[1]}, not whole numbers of pixels")
            width, height = int(values[0][0]), int(values[1][0])
            if width <= 0 or height <= 0:
                raise FormatError(f"the file's attributes declare a {width}x{height} sensor")
            return width, height
    return None


def _slice(datasets: dict, layout, start: int, stop: int, offset: int, seconds: bool):
    """(t µs, x, y, p) of events [start, stop)."""
    if layout["compound"]:
        rows = datasets["t"][start:stop]
        x, y, t, p = (rows[name] for name in "xytp")
    else:
        x, y, t, p = (datasets[field][start:stop] for field in "xytp")
    t = np.asarray(t)
    if np.issubdtype(t.dtype, np.floating):
        if not seconds and not np.all(t[np.isfinite(t)] == np.round(t[np.isfinite(t)])):
            raise FormatError(f"the times among events {start}-{stop - 1} have fractions where those read first were "
                              "whole µs: seconds or µs cannot be told; write them as integer µs")
        t = t.astype(np.float64) * (1e6 if seconds else 1.0)
        if not np.isfinite(t).all() or (len(t) and np.abs(t).max() >= LARGEST_US):
            bad = t[~(np.isfinite(t) & (np.abs(t) < LARGEST_US))][0]
            raise FormatError(f"a timestamp of {bad:.6g} µs among events {start}-{stop - 1} is not a time a camera writes")
        t = np.round(t).astype(np.int64)
    elif len(t) and (t.max() >= LARGEST_US or (np.issubdtype(t.dtype, np.signedinteger) and t.min() <= -LARGEST_US)):
        raise FormatError(f"a timestamp among events {start}-{stop - 1} is beyond what a clock in µs holds")
    t = t.astype(np.int64) + offset
    coordinates = []
    for name, values in (("x", np.asarray(x)), ("y", np.asarray(y))):
        if len(values) and np.issubdtype(values.dtype, np.floating) and not np.all(values == np.round(values)):
            raise FormatError(f"coordinate {name}={values[values != np.round(values)][0]:g} is not a whole pixel")
        if len(values) and (values.min() < 0 or values.max() > 0xFFFF):
            raise FormatError(f"coordinate {name}={int(values.min() if values.min() < 0 else values.max())} lies outside any sensor")
        coordinates.append(values.astype(np.uint16))
    p = np.asarray(p)
    if np.issubdtype(p.dtype, np.floating) and not np.isfinite(p).all():
        raise FormatError(f"a polarity among events {start}-{stop - 1} is not a number")
    return t, coordinates[0], coordinates[1], (p > 0).astype(np.uint8)
