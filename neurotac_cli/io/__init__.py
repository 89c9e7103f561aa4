"""Camera files in (AEDAT 2.0/3.1/4.0, Prophesee EVT 2.0/2.1/3.0 and DAT, Event Stream, HDF5, text) and force logs.

    read_events(path, sensor=None) -> (schema, batches)   decoded chunk by chunk
    read_events_table(path, sensor=None) -> pa.Table
    is_table(path) -> bool                                 Arrow/Parquet by magic bytes
"""

from neurotac_cli.io.camera import FORMATS, detect_format, is_table
from neurotac_cli.io.events import import_files, read_events, read_events_table

__all__ = ["FORMATS", "detect_format", "import_files", "is_table", "read_events", "read_events_table"]
