"""HDF5 event files (`.h5`, `.hdf5`), read with h5py in slices of `SLICE_EVENTS` events.

Three layouts are in common use, each found by its names:

- Prophesee Metavision: a compound dataset `CD/events` of (x, y, p, t); t in µs. The SDK compresses
  it with its ECF codec, an HDF5 filter plugin that HDF5 loads from `HDF5_PLUGIN_PATH`; without it
  the data cannot be decoded, and the error says so.
- One dataset per field in a group (`events/` or the root): `x, y, t, p` (DSEC, TUM-VIE; DSEC adds
  a `t_offset` in µs at the root) or `xs, ys, ts, ps` (the e2vid convention, evlib).
- Time: integer timestamps are µs; floating-point ones are seconds (the e2vid convention). Polarity:
  above zero is ON, so 0/1, -1/1 and booleans all read the same.

The sensor size comes from a `geometry` attribute ("1280x720", as Metavision writes it) or
`width`/`height` attributes of the file or the events' group; otherwise from --sensor, else from the
events' extent, as for a DAT file without one. Compression other than ECF (gzip, and Blosc, LZ4 or
Zstd through hdf5plugin, which DSEC needs) is decoded where the plugin is installed.
"""

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import Decoded

SIGNATURE = b"\x89HDF\r\n\x1a\n"
SIGNATURE_OFFSETS = (0, 512, 1024, 2048)  # a user block before the superblock moves it to a power of two
SLICE_EVENTS = 1 << 20
FIELD_SETS = (("x", "y", "t", "p"), ("xs", "ys", "ts", "ps"))
GROUPS = ("events", "")
LARGEST_US = 2.0**62  # timestamps beyond it (about 146,000 years) are damage, and would overflow int64 µs
ECF_FILTER = 0x8ECF  # Prophesee's registered-by-itself filter code


def is_hdf5(head: bytes) -> bool:
    return any(head[offset:offset + len(SIGNATURE)] == SIGNATURE for offset in SIGNATURE_OFFSETS)


def open_hdf5(path: str, head: bytes, sensor) -> Decoded:
    import h5py

    try:
        import hdf5plugin  # noqa: F401 - registers Blosc, LZ4, Zstd, ... with HDF5 (DSEC is Blosc-compressed)
    except ImportError:
        pass
    with h5py.File(path, "r") as handle:
        layout = _layout(handle)
        declared = _declared_sensor(handle, layout)
        count = layout["count"](handle)
        for dataset in _datasets(handle, layout):
            _check_codecs(dataset)
    meta = {"source": {"hdf5_layout": layout["name"], "hdf5_events": int(count)}}

    def chunks():
        with h5py.File(path, "r") as handle:
            for start in range(0, count, SLICE_EVENTS):
                yield _slice(handle, layout, start, min(count, start + SLICE_EVENTS))

    return Decoded(sensor=declared, chunks=chunks, meta=meta)


def _layout(handle) -> dict:
    """How the events are stored, as the names of what to read."""
    cd = handle.get("CD/events")
    if cd is not None and getattr(cd, "dtype", None) is not None and cd.dtype.names:
        missing = {"x", "y", "p", "t"} - set(cd.dtype.names)
        if missing:
            raise FormatError(f"CD/events has no field {sorted(missing)[0]!r} (fields: {', '.join(cd.dtype.names)})")
        return {"name": "metavision", "group": "CD", "fields": ("x", "y", "t", "p"), "compound": "CD/events",
                "count": lambda h: len(h["CD/events"])}
    for group in GROUPS:
        node = handle.get(group) if group else handle
        if node is None or not hasattr(node, "keys"):
            continue
        for fields in FIELD_SETS:
            if all(name in node and hasattr(node[name], "shape") for name in fields):
                lengths = {int(node[name].shape[0]) if node[name].shape else -1 for name in fields}
                if len(lengths) != 1 or -1 in lengths:
                    shown = ", ".join(f"{name} {node[name].shape}" for name in fields)
                    raise FormatError(f"the event fields of /{group} are not four lists of one length ({shown})")
                for name in fields:
                    if node[name].ndim != 1 or not np.issubdtype(node[name].dtype, np.number) and node[name].dtype != bool:
                        raise FormatError(f"/{'/'.join(filter(None, (group, name)))} holds {node[name].dtype} "
                                          f"of shape {node[name].shape}, not one number per event")
                return {"name": "/".join(filter(None, (group, ",".join(fields)))), "group": group, "fields": fields,
                        "compound": None, "count": lambda h, g=group, f=fields[0]: int((h[g] if g else h)[f].shape[0])}
    raise FormatError("an HDF5 file without events in a layout this reader knows: CD/events (Metavision), "
                      "events/{x,y,t,p} (DSEC), events/{xs,ys,ts,ps} (e2vid); found "
                      f"{', '.join(sorted(handle.keys())[:8]) or 'nothing'} at the root")


def _datasets(handle, layout) -> list:
    if layout["compound"]:
        return [handle[layout["compound"]]]
    node = handle[layout["group"]] if layout["group"] else handle
    return [node[name] for name in layout["fields"]]


def _check_codecs(dataset):
    """Refuse, before reading, events compressed with a filter HDF5 cannot load (its own message is
    about a plugin directory, not the file)."""
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


def _declared_sensor(handle, layout) -> tuple[int, int] | None:
    for node in (handle, handle[layout["group"]] if layout["group"] else handle):
        attrs = node.attrs
        if "geometry" in attrs:
            text = attrs["geometry"]
            text = text.decode() if isinstance(text, bytes) else str(text)
            width, sep, height = text.lower().partition("x")
            if not sep or not width.strip().isdigit() or not height.strip().isdigit() or int(width) <= 0 or int(height) <= 0:
                raise FormatError(f"cannot read the geometry attribute {text!r} (expected WxH, e.g. 1280x720)")
            return int(width), int(height)
        if "width" in attrs and "height" in attrs:
            width, height = int(np.asarray(attrs["width"]).ravel()[0]), int(np.asarray(attrs["height"]).ravel()[0])
            if width <= 0 or height <= 0:
                raise FormatError(f"the file's attributes declare a {width}x{height} sensor")
            return width, height
    return None


def _slice(handle, layout, start: int, stop: int):
    """(t µs, x, y, p) of events [start, stop)."""
    if layout["compound"]:
        rows = handle[layout["compound"]][start:stop]
        x, y, t, p = (rows[name] for name in layout["fields"])
    else:
        node = handle[layout["group"]] if layout["group"] else handle
        x, y, t, p = (node[name][start:stop] for name in layout["fields"])
    t = np.asarray(t)
    if np.issubdtype(t.dtype, np.floating):
        t = t * 1e6
    if len(t) and not (np.isfinite(t).all() and t.min() > -LARGEST_US and t.max() < LARGEST_US):
        bad = t[~(np.isfinite(t) & (np.abs(t) < LARGEST_US))][0]
        raise FormatError(f"a timestamp of {bad:.6g} µs among events {start}-{stop} is not a time a camera writes")
    t = np.round(t).astype(np.int64) if np.issubdtype(t.dtype, np.floating) else t.astype(np.int64)
    if "t_offset" in handle:  # DSEC: the recording's start on the camera clock, in µs
        t = t + int(np.asarray(handle["t_offset"]).ravel()[0])
    x, y = np.asarray(x), np.asarray(y)
    for name, values in (("x", x), ("y", y)):
        if len(values) and (values.min() < 0 or values.max() > 0xFFFF):
            raise FormatError(f"coordinate {name}={int(values.min() if values.min() < 0 else values.max())} lies outside any sensor")
    return t, x.astype(np.uint16), y.astype(np.uint16), (np.asarray(p) > 0).astype(np.uint8)
