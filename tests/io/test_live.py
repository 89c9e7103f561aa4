"""Live input: a camera file followed while it is written, pipes and FIFOs decoded as they arrive,
and replay at the recorded speed."""

import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pyarrow as pa
import pytest

from neurotac_cli import schema as sch
from neurotac_cli.io import live, read_events_table
from neurotac_cli.tables import read
from tests.conftest import real_file

FOLLOWED = ["davis240c_rotdisk.aedat", "prophesee_vga_faery.evt2.raw", "prophesee_hd_expelliarmus.evt3.raw", "davis346_aestream.aedat4"]
PIPED = FOLLOWED + ["dvxplorer_tonic.aedat4", "atis_ncars_loris.es", "atis_ncars_loris.dat", "header_only_tonic.aedat"]


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> pathlib.Path:
    """One simulated grasp as the rig writes it (AEDAT 2.0)."""
    out = tmp_path_factory.mktemp("sim")
    done = subprocess.run(["neurotac", "simulate", "--preset", "ch4", "--trials", "1", "--seed", "3", "--out", str(out)],
                          capture_output=True)
    assert done.returncode == 0, done.stderr
    return out / "steel-bolt8-01.aedat"


def write_in_pieces(data: bytes, path, pieces: int = 9, pause: float = 0.02, stop=None) -> threading.Thread:
    """Write `data` to `path` from a thread, in pieces whose sizes (a multiple of none of the record
    sizes) end mid-record, pausing between them as a camera's writer does (until `stop` is set)."""
    step = len(data) // pieces + 7
    stop = stop or threading.Event()

    def run():
        try:
            with open(path, "wb", buffering=0) as sink:
                for start in range(0, len(data), step):
                    if stop.is_set():
                        return
                    sink.write(data[start : start + step])
                    time.sleep(pause)
        except BrokenPipeError:
            return  # the reader refused the stream and closed its end, as a test may expect

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def events(table: pa.Table) -> pa.Table:
    return table.select(["t", "x", "y", "p"])


def collect(stream: live.Stream) -> tuple[pa.Table, int]:
    batches = list(stream.batches)
    return pa.Table.from_batches(batches, schema=stream.schema), len(batches)


class Reads:
    """A feed that gives these reads, then ends."""

    shrunk = None
    replaced = rewritten = False

    def __init__(self, *reads):
        self.reads = list(reads)

    def read(self):
        return self.reads.pop(0) if self.reads else None


@pytest.mark.parametrize("cut", [3, 8 * 500 + 5])
def test_a_record_cut_between_reads_waits_for_its_rest(cut):
    data = real_file("davis240c_rotdisk.aedat").read_bytes()
    header = live.header_length("aedat2", data, True)
    body = data[header : header + 8 * 1000]
    schema, notes = sch.events_schema(240, 180), []
    batches = live._batches("cam", "aedat2", Reads(body[cut:]), bytearray(body[:cut]), live._decoder("aedat2", data[:header], None),
                            (240, 180), schema, notes, lambda: None)
    table = pa.Table.from_batches(list(batches), schema=schema)
    expected = live._decoder("aedat2", data[:header], None).decode(body)
    assert [table[c].to_numpy().tolist() for c in "txyp"] == [a.tolist() for a in expected] and notes == []


@pytest.mark.parametrize("name", FOLLOWED + ["simulated"])
def test_following_a_file_written_in_pieces_gives_the_finished_files_events(tmp_path, name, simulated):
    source = simulated if name == "simulated" else real_file(name)
    path = tmp_path / source.name
    path.write_bytes(b"")
    writer = write_in_pieces(source.read_bytes(), path)
    table, batches = collect(live.open_stream(str(path), follow=True, idle_timeout=0.5))
    writer.join()
    whole = read_events_table(source)
    assert events(table).equals(events(whole))
    assert sch.sensor_of(table.schema) == sch.sensor_of(whole.schema)
    assert batches > 1  # the events went on as they arrived, not at the end


def test_a_followed_file_that_the_camera_creates_later_is_waited_for(tmp_path, simulated):
    path = tmp_path / "cam.aedat"
    later = threading.Timer(0.4, lambda: write_in_pieces(simulated.read_bytes(), path))
    later.start()
    table, _ = collect(live.open_stream(str(path), follow=True, idle_timeout=1))
    later.join()
    assert events(table).equals(events(read_events_table(simulated)))


def test_a_followed_file_that_never_appears_is_one_line_after_the_timeout(tmp_path):
    start = time.monotonic()
    done = subprocess.run(["neurotac", "import", "--follow", "--idle-timeout", "300ms", str(tmp_path / "cam.raw")], capture_output=True)
    lines = done.stderr.decode().strip().splitlines()
    assert done.returncode == 1 and len(lines) == 1 and "no such file after waiting 0.3 s" in lines[0], done.stderr
    assert time.monotonic() - start >= 0.3


def test_ctrl_c_while_waiting_for_a_followed_file_is_one_line(tmp_path):
    process = subprocess.Popen(["neurotac", "import", "--follow", "--idle-timeout", "20s", str(tmp_path / "cam.raw")],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=20)
    lines = stderr.decode().strip().splitlines()
    assert process.returncode == 1 and len(lines) == 1 and "stopped before the file appeared" in lines[0], stderr


def test_a_file_that_stops_growing_ends_after_the_idle_timeout(tmp_path):
    source = real_file("prophesee_vga_faery.evt2.raw")
    data = source.read_bytes()
    path = tmp_path / "cam.raw"
    path.write_bytes(data[: len(data) // 2 + 1])  # the camera stopped mid-word
    stream = live.open_stream(str(path), follow=True, idle_timeout=0.3)
    start = time.monotonic()
    table, _ = collect(stream)
    waited = time.monotonic() - start
    assert 0.3 <= waited < 10  # ends after the timeout, not at once and not never (a loaded machine is slow)
    assert table.num_rows > 0 and len(stream.notes) == 1 and "cut short" in stream.notes[0]
    assert events(table).equals(events(read_events_table(source)).slice(0, table.num_rows))


def _followed_then(tmp_path, change):
    """Follow a file of 400,002 bytes of the real EVT 2.0 recording, read its first batch, then
    `change(path, data)`: (the stream, the rows read in all, seconds from the change to the end)."""
    data = real_file("prophesee_vga_faery.evt2.raw").read_bytes()
    path = tmp_path / "cam.raw"
    path.write_bytes(data[:400_002])
    stream = live.open_stream(str(path), follow=True, idle_timeout=5)
    batches = iter(stream.batches)
    first = next(batches)
    change(path, data)
    start = time.monotonic()
    rows = first.num_rows + sum(b.num_rows for b in batches)
    return stream, rows, time.monotonic() - start


def test_a_followed_file_cut_shorter_while_read_ends_with_a_note(tmp_path):
    """A recorder that rewrites its file from the start never grows it past what was read: said, not
    waited out in silence with the new recording left out."""
    stream, rows, waited = _followed_then(tmp_path, lambda path, data: path.write_bytes(data[:1_000]))  # a new recording begun
    assert waited < 4 and rows > 0  # ended when seen, not after the idle timeout
    assert any("shrank from 400,002 to 1,000 bytes while it was followed" in note for note in stream.notes), stream.notes


def test_a_followed_file_rewritten_past_what_was_read_ends_with_a_note(tmp_path):
    """Truncated and written again beyond the offset between two polls, the file only ever looks
    larger: its new bytes must not be decoded as the first recording's continuation."""
    def rewrite(path, data):
        with open(path, "r+b") as handle:  # in place and at once, so no poll sees it shorter
            handle.write(data[:1_000] + data[100_000:700_000])
            handle.truncate()
    stream, rows, waited = _followed_then(tmp_path, rewrite)
    assert waited < 4 and rows > 0
    assert any("rewritten while it was followed" in note for note in stream.notes), stream.notes


def test_a_followed_file_replaced_by_another_ends_with_a_note_and_one_renamed_away_is_followed_on(tmp_path):
    """A recorder that renames a new file over the old name: the open file never grows again and the
    new one is never read, so waiting would end in silence; a file renamed away is still the camera's."""
    def replace(path, data):
        (tmp_path / "new.raw").write_bytes(data)
        os.replace(tmp_path / "new.raw", path)

    stream, rows, waited = _followed_then(tmp_path, replace)
    assert waited < 4 and rows > 0  # ended when seen, not after the idle timeout
    assert any("another file was renamed over it while it was followed" in note for note in stream.notes), stream.notes
    data = real_file("prophesee_vga_faery.evt2.raw").read_bytes()
    path = tmp_path / "cam.raw"
    path.write_bytes(data[:400_002])
    stream = live.open_stream(str(path), follow=True, idle_timeout=0.5)
    os.replace(path, tmp_path / "moved.raw")
    with open(tmp_path / "moved.raw", "ab") as handle:
        handle.write(data[400_002:])
    whole = read_events_table(real_file("prophesee_vga_faery.evt2.raw"))
    assert sum(batch.num_rows for batch in stream.batches) == whole.num_rows and not stream.notes


@pytest.mark.parametrize("number", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_ends_following_cleanly_with_the_output_complete(tmp_path, number):
    source = real_file("davis240c_rotdisk.aedat")
    path = tmp_path / "cam.aedat"
    path.write_bytes(b"")
    stop = threading.Event()
    writer = write_in_pieces(source.read_bytes(), path, pieces=80, pause=0.1, stop=stop)
    process = subprocess.Popen(["neurotac", "import", "--follow", str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = process.stdout.read1(1 << 16)  # events are flowing
    process.send_signal(number)
    rest, stderr = process.communicate(timeout=20)
    stop.set()
    writer.join()
    assert process.returncode == 0, stderr
    assert b"Traceback" not in stderr
    table = pa.ipc.open_stream(first + rest).read_all()
    whole = read_events_table(source)
    assert 0 < table.num_rows < whole.num_rows
    assert events(table).equals(events(whole).slice(0, table.num_rows))


def test_ctrl_c_to_a_whole_pipe_whose_reader_lags_ends_every_verb_complete(tmp_path):
    """Ctrl-C reaches every process of a pipe; the camera's end closes the stream, and the verbs after
    it read on to that end. The signal comes while import's write waits on a full pipe."""
    source = real_file("davis240c_rotdisk.aedat")
    path = tmp_path / "cam.aedat"
    path.write_bytes(b"")
    stop = threading.Event()
    writer = write_in_pieces(source.read_bytes(), path, pieces=40, pause=0.05, stop=stop)
    lagging = ("import os, signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); time.sleep(1.5); "
               "signal.signal(signal.SIGINT, signal.SIG_DFL); os.execvp('neurotac', ['neurotac', 'frame', '--window', '10ms'])")
    pipe = f"neurotac import --follow {path} | {sys.executable} -c \"{lagging}\" > {tmp_path / 'f.arrows'}"
    process = subprocess.Popen(["bash", "-c", pipe + "; echo ${PIPESTATUS[*]}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               start_new_session=True)
    time.sleep(1.0)
    os.killpg(process.pid, signal.SIGINT)
    out, stderr = process.communicate(timeout=30)
    stop.set()
    writer.join()
    assert out.split() == [b"0", b"0"], stderr
    frames = read([str(tmp_path / "f.arrows")])
    assert frames.num_rows > 0 and sum(sch.counts_numpy(frames.column("counts")).sum(axis=(1, 2, 3))) > 0


def test_a_write_a_signal_cuts_short_is_carried_to_its_last_byte():
    from neurotac_cli.tables import _WholeWrites

    class Short:
        closed, data = False, b""

        def write(self, view):
            self.data += bytes(view[:3])
            return min(3, len(view))

        def flush(self):
            pass

    sink = Short()
    whole = _WholeWrites(sink)
    assert whole.write(b"abcdefgh") == 8 and sink.data == b"abcdefgh" and whole.tell() == 8


@pytest.mark.parametrize("number", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_ends_an_import_of_a_fifo_nobody_writes_to(tmp_path, number):
    """Opening a FIFO waits for its writer; the stop request must still end that wait."""
    os.mkfifo(tmp_path / "cam.fifo")
    process = subprocess.Popen(["neurotac", "import", str(tmp_path / "cam.fifo")], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(1.0)
    process.send_signal(number)
    try:
        _, stderr = process.communicate(timeout=10)
    finally:
        process.kill()
    lines = stderr.decode().strip().splitlines()
    assert process.returncode == 1 and len(lines) == 1 and "stopped before anything wrote" in lines[0], stderr


def test_a_followed_fifo_nobody_opens_ends_after_the_idle_timeout(tmp_path):
    """--idle-timeout covered a file that did not appear or stopped growing, not a FIFO no writer opened."""
    os.mkfifo(tmp_path / "cam.fifo")
    done = subprocess.run(["neurotac", "import", "--follow", "--idle-timeout", "0.3s", str(tmp_path / "cam.fifo")],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=30)
    lines = done.stderr.decode().strip().splitlines()
    assert done.returncode == 1 and len(lines) == 1 and "nothing was written into the FIFO in 0.3 s" in lines[0], lines


def test_a_piped_file_read_whole_that_fails_closes_only_its_own_descriptor(tmp_path, monkeypatch):
    """The pipe is closed once copied: the error's clean-up must not close its number again, by then
    another file's (a chunk reader's, which the error left open, shown as a traceback at exit)."""
    from neurotac_cli.errors import FormatError
    from neurotac_cli.io import camera

    held = []

    def failing(local, name, sensor=None, fmt=None, cleanup=lambda: None):
        held.append(open(local, "rb"))
        cleanup()
        raise FormatError("damaged")

    monkeypatch.setattr(camera, "read_local", failing)
    with pytest.raises(FormatError):
        live.open_stream(fifo_of(tmp_path, b"t,x,y,p\n1,2,3,1\n"))
    os.fstat(held[0].fileno())
    held[0].close()


@pytest.mark.parametrize("failure", [KeyboardInterrupt(), OSError(28, "No space left on device")])
def test_a_piped_file_whose_copy_is_cut_short_leaves_no_temporary_copy(tmp_path, monkeypatch, failure):
    """Text from a pipe is copied whole first: an endless one (/dev/zero) fills the disk, and the copy
    a second Ctrl-C or the full disk cut short must be removed, not left to fill it."""
    from neurotac_cli.errors import InputError

    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))
    reads = []
    real = live.Feed.read

    def read(self):
        reads.append(1)
        if len(reads) > 2:
            raise failure
        return real(self)

    monkeypatch.setattr(live.Feed, "read", read)
    with pytest.raises(InputError if isinstance(failure, OSError) else KeyboardInterrupt) as raised:
        live.open_stream(fifo_of(tmp_path, b"t,x,y,p\n" + b"1,2,3,1\n" * 100000))
    assert os.listdir(tmp_path / "tmp") == []
    if isinstance(failure, OSError):
        assert "no space left on the device" in str(raised.value) and "TMPDIR" in str(raised.value)


def test_a_camera_file_on_stdin_that_fills_the_disk_is_one_line_with_advice_and_leaves_no_copy(tmp_path, monkeypatch):
    """A regular file redirected to stdin is copied whole, like a pipe, and says the same on a full disk."""
    import io

    from neurotac_cli.errors import InputError
    from neurotac_cli.io import camera

    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(b"t,x,y,p\n1,2,3,1\n")))

    def full(source, sink, size):
        sink.write(b"t,x,y,p\n")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("shutil.copyfileobj", full)
    with pytest.raises(InputError) as raised:
        camera.local_path("-")
    assert str(raised.value).startswith(f"stdin: cannot copy it to {tmp_path / 'tmp'} (no space left on the device)")
    assert "TMPDIR" in str(raised.value) and os.listdir(tmp_path / "tmp") == []


@pytest.mark.parametrize("reader", ["live.open_stream('-').batches", "camera.read_local(*camera.local_path('-'))[1]"])
def test_the_copy_of_a_piped_file_whose_events_are_never_read_is_removed_at_exit(tmp_path, reader):
    """A generator that never starts runs no `finally`: an output refused before the first batch left
    the piped file's copy in the temporary folder."""
    (tmp_path / "tmp").mkdir()
    code = (f"from neurotac_cli.io import camera, live\nevents = {reader}\n"
            "import os\nprint(len(os.listdir(os.environ['TMPDIR'])))\n")
    done = subprocess.run([sys.executable, "-c", code], input=b"t,x,y,p\n" + b"1,2,3,1\n" * 100, capture_output=True,
                          env={**os.environ, "TMPDIR": str(tmp_path / "tmp")}, timeout=60)
    assert done.returncode == 0, done.stderr.decode()
    assert done.stdout.decode().strip() == "1"  # the copy, while the process runs
    assert os.listdir(tmp_path / "tmp") == []


def test_ctrl_c_before_the_header_is_one_line(tmp_path):
    (tmp_path / "cam.raw").write_bytes(b"")
    process = subprocess.Popen(["neurotac", "import", "--follow", str(tmp_path / "cam.raw")], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=20)
    lines = stderr.decode().strip().splitlines()
    assert process.returncode in (1, 130) and len(lines) == 1 and "Traceback" not in stderr.decode(), stderr


def test_an_empty_followed_file_is_one_line_after_the_timeout(tmp_path):
    (tmp_path / "cam.raw").write_bytes(b"")
    done = subprocess.run(["neurotac", "import", "--follow", "--idle-timeout", "200ms", str(tmp_path / "cam.raw")], capture_output=True)
    lines = done.stderr.decode().strip().splitlines()
    assert done.returncode == 1 and len(lines) == 1 and "empty" in lines[0] and lines[0].startswith("neurotac import: error:")


def test_formats_that_need_the_whole_file_are_refused_when_followed(tmp_path):
    (tmp_path / "e.csv").write_text("t,x,y,p\n1,2,3,1\n")
    dat = real_file("atis_ncars_loris.dat")  # no sensor size in its header
    for path, hint in ((tmp_path / "e.csv", "without --follow"), (dat, "--sensor")):
        done = subprocess.run(["neurotac", "import", "--follow", "--idle-timeout", "200ms", str(path)], capture_output=True)
        lines = done.stderr.decode().strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1 and hint in lines[0], done.stderr


@pytest.mark.parametrize("name", PIPED + ["simulated"])
def test_a_fifo_gives_the_files_events(tmp_path, name, simulated):
    source = simulated if name == "simulated" else real_file(name)
    fifo = tmp_path / "cam.fifo"
    os.mkfifo(fifo)
    writer = write_in_pieces(source.read_bytes(), fifo, pause=0.005)
    table = read_events_table(str(fifo))
    writer.join()
    whole = read_events_table(source)
    assert events(table).equals(events(whole))
    assert sch.sensor_of(table.schema) == sch.sensor_of(whole.schema)


def test_stdin_and_process_substitution_give_the_files_events(tmp_path):
    source = real_file("prophesee_hd_expelliarmus.evt3.raw")
    whole = events(read_events_table(source))
    for command in (f"cat {source} | neurotac import - -o {tmp_path}/a.arrows", f"neurotac import <(cat {source}) -o {tmp_path}/a.arrows"):
        done = subprocess.run(["bash", "-c", command], capture_output=True)
        assert done.returncode == 0, done.stderr
        assert events(read([f"{tmp_path}/a.arrows"])).equals(whole)


def fifo_of(tmp_path, data: bytes) -> str:
    fifo = tmp_path / "cam.fifo"
    os.mkfifo(fifo)
    write_in_pieces(data, fifo, pause=0.005)
    return str(fifo)


@pytest.mark.parametrize("name", ["davis240c_rotdisk.aedat", "prophesee_hd_expelliarmus.evt3.raw", "davis346_aestream.aedat4"])
def test_a_stream_cut_anywhere_gives_a_prefix_of_the_events_or_one_error(tmp_path, name):
    from neurotac_cli.errors import NeurotacError

    data = real_file(name).read_bytes()
    whole = events(read_events_table(real_file(name)))
    for i, cut in enumerate(np.random.default_rng(5).integers(1, len(data), 4).tolist() + [100]):
        (tmp_path / f"{i}").mkdir()
        try:
            table = events(read_events_table(fifo_of(tmp_path / f"{i}", data[:cut])))
        except NeurotacError as error:
            assert "cut short" in str(error) and cut < 200_000, (cut, error)  # only a header can be cut so short
            continue
        assert table.equals(whole.slice(0, table.num_rows)), cut


@pytest.mark.parametrize("name", ["davis346_aestream.aedat4", "dvxplorer_tonic.aedat4"])
def test_an_aedat4_file_cut_mid_packet_reads_as_the_same_bytes_piped(tmp_path, name):
    """A recording stopped mid-write: its whole packets are read from the path as from a pipe, and the
    cut bytes are kept in the table's source."""
    data = real_file(name).read_bytes()
    for i, cut in enumerate([len(data) - 20_000, len(data) // 2]):
        path = tmp_path / f"{i}.aedat4"
        path.write_bytes(data[:cut])
        (tmp_path / f"{i}").mkdir()
        table = read_events_table(str(path))
        assert events(table).equals(events(read_events_table(fifo_of(tmp_path / f"{i}", data[:cut]))))
        assert 0 < table.num_rows and 0 < sch.camera_sources(table.schema)[0]["cut_bytes"] < 200_000  # one packet at most


def test_an_empty_pipe_is_one_error(tmp_path):
    from neurotac_cli.errors import InputError

    with pytest.raises(InputError, match="empty"):
        read_events_table(fifo_of(tmp_path, b""))


def test_a_text_stream_is_read_whole(tmp_path):
    rows = "t,x,y,p\n" + "".join(f"{10 * i},{i % 7},{i % 5},{i % 2}\n" for i in range(50))
    table = read_events_table(fifo_of(tmp_path, rows.encode()))
    assert table["t"].to_pylist() == [10 * i for i in range(50)] and sch.sensor_of(table.schema) == (7, 5)


def test_a_streams_triggers_are_counted_in_a_note(tmp_path):
    words = np.array([0x8000 | 5, 0x6000 | 7, 0xA000 | (2 << 8) | 1, 0x0000 | 1, 0x2000 | 3], dtype="<u2")
    stream = live.open_stream(fifo_of(tmp_path, b"% evt 3.0\n% geometry 1280x720\n" + words.tobytes()))
    table, _ = collect(stream)
    assert table.num_rows == 1 and len(stream.notes) == 1 and "1 external trigger events were not kept" in stream.notes[0]


def fake_clock():
    now = [100.0]
    return (lambda: now[0]), (lambda seconds: now.__setitem__(0, now[0] + seconds)), now


@pytest.mark.parametrize("speed", [1.0, 8.0])
def test_a_replay_releases_no_event_before_its_time_and_each_within_a_slice(speed):
    clock, sleep, now = fake_clock()
    t = np.sort(np.random.default_rng(1).integers(5_000_000, 5_400_000, 3000))
    schema = sch.events_schema(10, 10)
    zeros = np.zeros(len(t), np.uint16)
    batches = [sch.events_batch(t[i : i + 700], zeros[i : i + 700], zeros[i : i + 700], zeros[i : i + 700].astype(np.uint8), schema)
               for i in range(0, len(t), 700)]
    released = []
    for batch in live.replay(iter(batches), speed, clock=clock, sleep=sleep):
        released.append((now[0] - 100.0, batch.column("t").to_numpy()))
    assert sum(len(b) for _, b in released) == len(t)
    for wall, times in released:
        camera = (times - t[0]) / 1e6 / speed
        assert np.all(camera <= wall + 1e-9)  # never early
        assert np.all(wall - camera <= live.REPLAY_SLICE_US / 1e6 / speed + 1e-9)  # late by at most one slice
    assert released[-1][0] == pytest.approx((t[-1] - t[0]) / 1e6 / speed, abs=live.REPLAY_SLICE_US / 1e6 / speed)


def test_a_replay_whose_clock_steps_back_paces_what_follows_from_there():
    """A camera clock reset 2 s back: the 2 s after it went out at once, unpaced, without a word."""
    clock, sleep, now = fake_clock()
    schema = sch.events_schema(10, 10)

    def replayed(t, size):
        zeros = np.zeros(len(t), np.uint16)
        batches = [sch.events_batch(t[i : i + size], zeros[i : i + size], zeros[i : i + size], zeros[i : i + size].astype(np.uint8), schema)
                   for i in range(0, len(t), size)]
        notes, released, now[0] = [], [], 100.0
        for batch in live.replay(iter(batches), 1.0, clock=clock, sleep=sleep, notes=notes):
            released.append((now[0] - 100.0, batch.column("t").to_numpy()))
        return released, notes

    t = np.concatenate([np.arange(0, 2_000_000, 1000), np.arange(0, 2_000_000, 1000)]) + 7_000_000
    released, notes = replayed(t, 300)
    assert np.concatenate([b for _, b in released]).tolist() == t.tolist()  # every event, its time kept
    assert released[-1][0] == pytest.approx(4.0, abs=0.01)
    paced = np.concatenate([np.arange(2000), 1999 + np.arange(2000)]) / 1000  # s: the reset's events follow on
    last = np.cumsum([len(times) for _, times in released]) - 1
    assert all(paced[k] <= wall + 1e-9 <= paced[k] + 0.002 for (wall, _), k in zip(released, last))  # none early, none late
    assert len(notes) == 1 and "steps back 1.999 s at t 7000000 µs" in notes[0]
    # the events that stay back counted across batches (30 in one, 70 in the next): the same reset
    released, notes = replayed(t, 70)
    assert released[-1][0] == pytest.approx(4.0, abs=0.05) and len(notes) == 1 and "steps back" in notes[0]
    # one stray time far back (a damaged word) is no reset: it goes out with its slice, the pace unchanged
    stray = np.arange(7_000_000, 9_000_000, 1000)
    stray[500] = 0
    released, notes = replayed(stray, 300)
    assert sum(len(times) for _, times in released) == len(stray)
    assert released[-1][0] == pytest.approx(2.0, abs=0.01) and notes == []


def test_realtime_replays_at_the_recorded_pace(tmp_path):
    source = real_file("davis240c_rotdisk.aedat")  # 3.17 s of events
    start = time.monotonic()
    done = subprocess.run(["neurotac", "import", "--realtime", "--speed", "4", str(source), "-o", str(tmp_path / "r.arrows")],
                          capture_output=True)
    took = time.monotonic() - start
    assert done.returncode == 0, done.stderr
    assert took >= 3.17 / 4
    assert events(read([str(tmp_path / "r.arrows")])).equals(events(read_events_table(source)))


def test_a_replay_stopped_before_its_first_event_does_not_call_the_file_empty(tmp_path):
    source = real_file("davis240c_rotdisk.aedat")
    process = subprocess.Popen(["neurotac", "import", "--realtime", "--speed", "0.000001", str(source), "-o", str(tmp_path / "r.arrows")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    time.sleep(1.5)  # started and waiting for the first millisecond, due in 1000 s
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=20)
    assert process.returncode == 0, stderr
    assert stderr.decode().count("\n") == 1 and "stopped before any event was passed on" in stderr.decode(), stderr
    assert b"no events in the file" not in stderr


@pytest.mark.parametrize("args", [["--speed", "2"], ["--realtime", "--speed", "0"], ["--realtime", "--speed", "nan"], ["--realtime", "--speed", "inf"], ["--follow", "a", "b"], ["--follow", "--idle-timeout", "0s"]])
def test_live_usage_errors_exit_2(args, tmp_path):
    done = subprocess.run(["neurotac", "import", *args, str(tmp_path / "x.raw")], capture_output=True)
    assert done.returncode == 2, done.stderr


def test_a_stream_refused_after_its_decoder_is_built_leaves_no_temporary_file(tmp_path, monkeypatch):
    """AEDAT 4.0's live decoder keeps a temporary file; a refusal after it is built removes it."""
    import tempfile

    from neurotac_cli.errors import FormatError

    def refuse(size):
        raise FormatError("a sensor this test refuses")

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(live, "check_sensor", refuse)
    (tmp_path / "fifo").mkdir()
    with pytest.raises(FormatError, match="refuses"):
        read_events_table(fifo_of(tmp_path / "fifo", real_file("davis346_aestream.aedat4").read_bytes()))
    assert not list(tmp_path.glob(".neurotac-aedat4-*"))


def test_an_empty_camera_file_is_named_by_its_path_as_given():
    from neurotac_cli.errors import InputError

    with pytest.raises(InputError, match=r"^/dev/null is empty \(0 bytes\)"):
        for _ in live.open_stream("/dev/null")[1]:
            pass
