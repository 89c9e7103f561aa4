"""Decoders of camera streams read as their bytes arrive (see io/live.py), one class per format.

Each is built from the format's complete header and the --sensor option, and has: `sensor` (declared
by the header, or None), `meta` (as the file reader gives it), `complete(pending)` (how many leading
bytes of what has arrived are whole records), `decode(block)` (whole records -> t, x, y, p),
`finished` (the data is over: AEDAT 4.0's index table has begun), `triggers` (external trigger events
seen, which a stream cannot keep), `settled(pending, at_end)` (whether `meta` is complete, or the
decoder needs more of the data first: it goes out with the stream's schema) and `close()`. The
decoding itself is the file readers'.
"""

import os
import struct
import tempfile

import numpy as np

from neurotac_cli.errors import FormatError


class _Records:
    """Fixed-size records decoded by a function of the block alone (plus carried state)."""

    record = 1
    finished = False
    triggers = 0
    meta: dict = {}

    def complete(self, pending) -> int:
        return len(pending) - len(pending) % self.record

    def held(self) -> int:
        """Bytes of a record begun and kept in the decoder's own state, not in the pending bytes."""
        return 0

    def settled(self, pending: bytearray, at_end: bool) -> bool:
        return True

    def close(self):
        pass


class Words(_Records):
    """Prophesee EVT 3.0 (2-byte words), EVT 2.0 (4-byte words) or EVT 2.1 (8-byte words, in the order `legacy`)."""

    def __init__(self, header: bytes, sensor, word_bytes: int, legacy: bool | None = None):
        from neurotac_cli.io import prophesee

        _, fields = prophesee.header_of(None, header)
        self.sensor, self.meta, self.record = prophesee.sensor_of_header(fields), prophesee._meta(fields), word_bytes
        self._decode, self._find, fresh, self.dtype = prophesee.word_kernels(word_bytes, legacy)
        self.state, self.trigger_state = fresh(), fresh()
        self.t0 = prophesee.time_origin(fields)

    def decode(self, block: bytes):
        from neurotac_cli.io import prophesee

        words = np.frombuffer(block, dtype=self.dtype)
        self.triggers += len(self._find(words, self.trigger_state)[0])
        return prophesee.shifted(self._decode(words, self.state), self.t0)


class Evt21(Words):
    """Prophesee EVT 2.1 (8-byte words); the word order from the header, or from the first words that
    hold a TIME_HIGH (the words before it have no time base, so nothing of them is lost)."""

    def __init__(self, header: bytes, sensor):
        from neurotac_cli.io import prophesee

        _, fields = prophesee.header_of(None, header)
        self.legacy = prophesee.evt21_order_of_header(fields)
        super().__init__(header, sensor, 8, self.legacy)
        if self.legacy is not None:
            prophesee.note_evt21_order(self.meta, self.legacy)

    def settled(self, pending: bytearray, at_end: bool) -> bool:
        """Settled once the word order is known, so that `evt21_order` goes out in the stream's
        metadata as in a file's. Whole words that come before any TIME_HIGH decode to nothing, and are
        dropped from `pending` as they arrive; a stream that ends before one has OpenEB's default
        order (little), as a file has."""
        if self.legacy is None:
            whole = len(pending) - len(pending) % self.record
            if not whole and not at_end:  # the header alone: no word has come to tell the order
                return False
            if not self._order_from(bytes(pending[:whole])):
                if not at_end:
                    del pending[:whole]
                    return False
                self._set_order(False)
        return True

    def decode(self, block: bytes):
        from neurotac_cli.io import kernels

        if self.legacy is None and not self._order_from(block):
            return kernels.event_arrays(0)  # no TIME_HIGH yet: nothing before one has a time base
        return super().decode(block)

    def _order_from(self, block: bytes) -> bool:
        """Whether `block`'s words tell the order (they hold a TIME_HIGH); if so, it is taken."""
        from neurotac_cli.io import prophesee

        legacy = prophesee.evt21_order_of_words(np.frombuffer(block, dtype="<u4").reshape(-1, 2))
        if legacy is not None:
            self._set_order(legacy)
        return legacy is not None

    def _set_order(self, legacy: bool):
        from neurotac_cli.io import prophesee

        self.legacy = legacy
        fresh = prophesee.word_kernels(8, legacy)[2]
        self.state, self.trigger_state = fresh(), fresh()
        prophesee.note_evt21_order(self.meta, legacy)


class Davis(_Records):
    """AEDAT 2.0 (jAER) 8-byte records: DAVIS chips, or DVS128."""

    record = 8

    def __init__(self, header: bytes, sensor):
        from neurotac_cli.io import aedat2

        chip = aedat2.chip_of(header)
        self.dvs128 = aedat2.is_dvs128(chip)
        self.sensor = (128, 128) if self.dvs128 else aedat2.declared_sensor(header, chip, sensor)
        self.meta = {"source": {"camera": chip}} if chip else {}
        self.given = sensor
        # a file that names no chip nor size: its first records tell DVS128 from DAVIS, as a file's do
        self.undecided = chip is None and self.sensor is None
        self.height = None if self.dvs128 or self.undecided else aedat2.flip_height(chip, self.sensor, sensor)
        self.state = {"last": None, "loop": 0}

    def settled(self, pending: bytearray, at_end: bool) -> bool:
        from neurotac_cli.io import aedat2

        if not self.undecided:
            return True
        told = aedat2.dvs128_records(bytes(pending))
        if told is None and not at_end:
            return False
        self.undecided = False
        if told:
            self.dvs128, self.sensor, self.meta = True, (128, 128), {"source": {"camera": aedat2.TOLD_DVS128}}
        else:
            self.height = aedat2.flip_height(None, None, self.given)
        return True

    def decode(self, block: bytes):
        from neurotac_cli.io import aedat2

        return aedat2.decode(block, self.dvs128, self.height, self.state)


class Aedat3(_Records):
    """AEDAT 3.1 packets, decoded once whole (a packet's events share its header's timestamp overflow)."""

    def __init__(self, header: bytes, sensor):
        from neurotac_cli.io import aedat3

        self.sensor, camera, source = aedat3.sensor_of_header(header)
        self.meta = {"source": {"camera": camera}} if camera else {}
        self.packets = aedat3.Packets(source)

    def complete(self, pending) -> int:
        from neurotac_cli.io import aedat3

        return aedat3.whole_packets(pending, len(pending))

    def decode(self, block: bytes):
        found = len(self.packets.triggers)
        events = self.packets.decode(block)
        self.triggers += len(self.packets.triggers) - found
        return events


class EventStream(_Records):
    """Event Stream 2.x bytes (the kernel carries an event cut between reads in its state)."""

    def __init__(self, header: bytes, sensor):
        from neurotac_cli.io import eventstream, kernels

        decoded = eventstream.open_es(None, header, sensor)
        self.sensor, self.meta = decoded.sensor, decoded.meta
        self.atis = header[15] == 2
        self.state = kernels.es_state()

    def decode(self, block: bytes):
        from neurotac_cli.io import kernels

        width, height = self.sensor
        t, x, y, p, outside = kernels.decode_es(np.frombuffer(block, dtype=np.uint8), width, height, self.atis, self.state)
        if outside:
            raise FormatError(f"an event lies outside the declared {width}x{height} sensor (damaged stream)")
        return t, x, (height - 1 - y.astype(np.int64)).astype(np.uint16), p

    def held(self) -> int:
        from neurotac_cli.io import kernels

        return kernels.es_pending(self.state)


class Dat(_Records):
    """Prophesee DAT 8-byte CD records (the header ends with the event type and size bytes)."""

    record = 8

    def __init__(self, header: bytes, sensor):
        from neurotac_cli.io import prophesee

        typed = not header.endswith(b"\n")  # the type and size bytes follow the lines (not in a file with no events)
        _, fields = prophesee.header_of(None, header[:-2] if typed else header)
        if typed:
            prophesee.check_dat_kind(header[-2:])
        self.sensor, self.meta = prophesee.sensor_of_header(fields), prophesee._meta(fields)
        self.state, self.t0 = prophesee.dat_state(fields), prophesee.time_origin(fields)

    def decode(self, block: bytes):
        from neurotac_cli.io import prophesee

        return prophesee.shifted(prophesee.decode_dat(block, self.state), self.t0)


class Aedat4:
    """AEDAT 4.0 packets (stream id, size, compressed flatbuffer): the whole packets of each read are
    decoded by the `aedat` library from a temporary file holding the header and those packets. A
    packet of no declared stream is the index table a finished file ends with: the data is over."""

    finished = False
    triggers = 0

    def __init__(self, header: bytes, sensor):
        from neurotac_cli.io import aedat4

        self.header = _without_table_position(header)
        handle, self.path = tempfile.mkstemp(prefix=".neurotac-aedat4-", suffix=".aedat4")
        with os.fdopen(handle, "wb") as sink:
            sink.write(self.header)
        try:
            packets = aedat4._packets(self.path)
            streams = next(packets)
            packets.close()
            self.events_id, self.sensor, others = aedat4.events_stream(streams, header, "stream")
        except BaseException:
            self.close()
            raise
        self.known = set(streams)
        self.meta = {"source": others} if others else {}
        # a finished file piped in states where its index table is; a file still being written does not yet (-1)
        self.table, self.offset, self.packets = aedat4.table_position(header), len(header), 0

    def complete(self, pending) -> int:
        from neurotac_cli.io import aedat4

        count, end, self.finished = aedat4.walk_packets(lambda offset, n: pending[offset:offset + n], len(pending), self.known)
        self.packets += count
        if self.finished:
            aedat4.check_table(self.offset + end, self.table, self.packets)
        self.offset += end  # the caller takes the whole packets at once
        return end

    def held(self) -> int:
        return 0  # a packet is decoded whole or left pending

    def settled(self, pending: bytearray, at_end: bool) -> bool:
        return True

    def decode(self, block: bytes):
        from neurotac_cli.io import aedat4

        with open(self.path, "wb") as sink:
            sink.write(self.header)
            sink.write(block)
        events = []
        for packet in aedat4._packets(self.path, skip_streams=True):
            if "triggers" in packet:
                self.triggers += int(np.isin(packet["triggers"]["source"], list(aedat4.TRIGGER_TYPES)).sum())
            elif packet.get("stream_id") == self.events_id and "events" in packet:
                events.append(packet["events"])
        return aedat4._columns(events)

    def close(self):
        if os.path.exists(self.path):
            os.unlink(self.path)


def _without_table_position(header: bytes) -> bytes:
    """The AEDAT 4.0 header with its index-table position set to -1 (none): the `aedat` library seeks
    to that table, which lies beyond the packets it is given."""
    from neurotac_cli.io import aedat4

    data = bytearray(header)
    offset = aedat4.table_offset(header)
    if offset is not None:
        struct.pack_into("<q", data, offset, -1)
    return bytes(data)


DECODERS = {
    "evt2": lambda header, sensor: Words(header, sensor, 4),
    "evt3": lambda header, sensor: Words(header, sensor, 2),
    "evt21": Evt21,
    "aedat2": Davis,
    "aedat3": Aedat3,
    "es": EventStream,
    "dat": Dat,
    "aedat4": Aedat4,
}
