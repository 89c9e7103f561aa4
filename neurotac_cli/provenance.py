"""Where a table came from: the camera file's checksum, and the camera files and history that
`sync` carries from its inputs into the recordings it writes (DESIGN.md: any file tells how it was made)."""

import hashlib

import pyarrow as pa

from neurotac_cli import schema as sch

CHUNK_BYTES = 1 << 20


def file_sha256(path: str) -> str:
    """The SHA-256 of a file's bytes, as hex: the same camera file gives the same checksum wherever it is."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while chunk := handle.read(CHUNK_BYTES):
            digest.update(chunk)
    return digest.hexdigest()


def carry(table: pa.Table, inputs: list[pa.Schema]) -> pa.Table:
    """`table` with the camera file(s) of `inputs` (their neurotac:source) and, from a single input,
    its history (`import`'s step) in its metadata: one source stays a dict, several become a list."""
    cameras = []
    for schema in inputs:
        cameras += sch.camera_sources(schema)
    entries = {}
    if cameras:
        entries["source"] = cameras[0] if len(cameras) == 1 else cameras
    if len(inputs) == 1 and sch.get_meta(inputs[0], sch.HISTORY):
        entries["history"] = sch.get_meta(inputs[0], sch.HISTORY)
    if not entries:
        return table
    return table.replace_schema_metadata(sch.set_meta(table.schema, **entries).metadata)


def checksums(schema: pa.Schema) -> list[dict]:
    """[{file, sha256}] of the camera files behind a table, for a history entry."""
    return [{"file": camera.get("file"), "sha256": camera.get("sha256")} for camera in sch.camera_sources(schema)
            if isinstance(camera, dict)]
