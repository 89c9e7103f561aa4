"""Text events: CSV with a t,x,y,p header and whitespace `t x y p` with seconds; bad rows by line number."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from neurotac_cli import schema as sch
from neurotac_cli.errors import FormatError
from neurotac_cli.io import read_events_table


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def events_of(table):
    return [tuple(row.values()) for row in table.to_pylist()]


def test_csv_with_header_in_microseconds(tmp_path):
    table = read_events_table(write(tmp_path, "a.csv", "t,x,y,p\n10,1,2,1\n20,3,4,0\n"))
    assert events_of(table) == [(10, 1, 2, 1), (20, 3, 4, 0)]
    assert sch.sensor_of(table.schema) == (4, 5)


@pytest.mark.parametrize("header, factor", [("t_ms", 1000), ("t_s", 1_000_000), ("t_us", 1), ("timestamp", 1)])
def test_csv_time_unit_comes_from_the_header(tmp_path, header, factor):
    table = read_events_table(write(tmp_path, "a.csv", f"{header},x,y,p\n1,1,2,1\n2,3,4,0\n"))
    assert table["t"].to_pylist() == [factor, 2 * factor]


def test_csv_columns_in_any_order_and_polarity_minus_one(tmp_path):
    table = read_events_table(write(tmp_path, "a.csv", "x,y,polarity,t\n1,2,-1,5\n3,4,1,6\n"))
    assert events_of(table) == [(5, 1, 2, 0), (6, 3, 4, 1)]


def test_whitespace_text_is_seconds_with_optional_comments(tmp_path):
    text = "# events of a public dataset\n0.000010 1 2 1\n1.5 3 4 0\n"
    table = read_events_table(write(tmp_path, "events.txt", text), sensor=(240, 180))
    assert events_of(table) == [(10, 1, 2, 1), (1_500_000, 3, 4, 0)]
    assert sch.sensor_of(table.schema) == (240, 180)
    assert sch.get_meta(table.schema, "neurotac:source")["sensor_from"] == "option"


@pytest.mark.parametrize("name, text", [("a.csv", "t,x,y,p\n10,1,2,1\n20,3,4,0\n"), ("a.txt", "0.00001 1 2 1\n0.00002 3 4 0\n")])
def test_a_byte_order_mark_before_the_first_line_reads_as_a_plain_file(tmp_path, name, text):
    """A spreadsheet's "CSV UTF-8" export starts with one; the headerless text file's first row is data."""
    plain = read_events_table(write(tmp_path, name, text))
    marked = tmp_path / f"marked-{name}"
    marked.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert events_of(read_events_table(marked)) == events_of(plain) == [(10, 1, 2, 1), (20, 3, 4, 0)]


def test_tab_separated_text(tmp_path):
    table = read_events_table(write(tmp_path, "events.txt", "0.1\t1\t2\t1\n0.2\t3\t4\t0\n"))
    assert table["t"].to_pylist() == [100_000, 200_000]


@pytest.mark.parametrize("text", ["t\tx\ty\tp\n1000\t0\t0\t1\n2000\t1\t1\t0\n", "# log\ntime x y p\n5 1 2 1\n"])
def test_whole_numbers_under_a_plain_t_in_whitespace_text_are_refused(tmp_path, text):
    """Seconds there, µs in a CSV: whole numbers read as seconds would be a million times too late."""
    with pytest.raises(FormatError, match="name the column t_us, t_ms or t_s"):
        read_events_table(write(tmp_path, "events.csv", text))
    assert read_events_table(write(tmp_path, "e.txt", "t x y p\n0.5 1 2 1\n"))["t"].to_pylist() == [500_000]
    assert read_events_table(write(tmp_path, "g.txt", "t x y p\n0 1 2 1\n0.001 3 4 0\n"))["t"].to_pylist() == [0, 1000]  # %g
    assert read_events_table(write(tmp_path, "f.txt", "t_us x y p\n1000 1 2 1\n"))["t"].to_pylist() == [1000]


@pytest.mark.parametrize(
    "text, line",
    [
        ("t,x,y,p\n10,1,2,1\n20,3,x,0\n", 3),
        ("t,x,y,p\n10,1,2,1\n20,3,4\n", 3),
        ("t,x,y,p\n10,1,2,1\n11,1,2,1\n12,1,2,7\n", 4),
        ("# c\n0.1 1 2 1\n0.2 1 2 1\nnan 1 2 1\n", 4),
        ("t,x,y,p\n10,1,2,1\n10.5,1,2,1\n", 3),
        ("t,x,y,p\n10,-1,2,1\n", 2),
        ("t,x,y,p\n10,1,2,1\n12 34,1,2,1\n", 3),
        ("t,x,y,p\n10,1,2,1\n10,1 5,2,1\n", 3),
        ("t,x,y,p\n10,1,2,1\n10,1e ,2,1\n", 3),
    ],
)
def test_a_bad_row_is_reported_with_its_line_number(tmp_path, text, line):
    with pytest.raises(FormatError, match=rf"line {line}\b"):
        read_events_table(write(tmp_path, "bad.csv", text))


def test_csv_without_header_is_refused_with_a_hint(tmp_path):
    with pytest.raises(FormatError, match="header"):
        read_events_table(write(tmp_path, "a.csv", "10,1,2,1\n"))


def test_header_only_csv_is_an_empty_table(tmp_path):
    table = read_events_table(write(tmp_path, "a.csv", "t,x,y,p\n"))
    assert table.num_rows == 0


@settings(max_examples=30, deadline=None)
@given(
    rows=st.lists(
        st.tuples(st.integers(0, 2**40), st.integers(0, 2000), st.integers(0, 2000), st.integers(0, 1)), min_size=1, max_size=50
    )
)
def test_csv_round_trips_any_events(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("csv") / "e.csv"
    path.write_text("t,x,y,p\n" + "".join(f"{t},{x},{y},{p}\n" for t, x, y, p in rows))
    table = read_events_table(path)
    assert events_of(table) == rows


def test_large_text_is_read_in_several_batches(tmp_path, monkeypatch):
    from neurotac_cli.io import read_events, reader

    n = 20_000
    rng = np.random.default_rng(1)
    t = np.sort(rng.integers(0, 10**9, n))
    body = "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in zip(t, rng.integers(0, 240, n), rng.integers(0, 180, n), rng.integers(0, 2, n)))
    path = write(tmp_path, "big.csv", "t,x,y,p\n" + body)
    monkeypatch.setattr(reader, "CHUNK_BYTES", 1 << 14)
    schema, batches = read_events(path)
    parts = list(batches)
    assert len(parts) > 3
    assert sum(b.num_rows for b in parts) == n
    assert np.array_equal(np.concatenate([b.column("t").to_numpy() for b in parts]), t)


def test_times_are_scaled_exactly_from_their_digits(tmp_path):
    text = "1e-5 1 2 1\r\n2.5E-6   3  4 -1\r\n\r\n  0.0000015\t5 6 0\n1.0000004 0 0 1\n4.000001 0 0 1"
    table = read_events_table(write(tmp_path, "e.txt", text))
    # 2.5 µs and 1.5 µs round half up; 1.0000004 s rounds down; no float error on 4.000001 s
    assert table["t"].to_pylist() == [10, 3, 2, 1_000_000, 4_000_001]
    assert table["p"].to_pylist() == [1, 0, 0, 1, 1]


def test_unix_seconds_to_the_nanosecond_round_to_the_microsecond(tmp_path):
    """ROS exports write `secs.nsecs`: 19 or more significant digits, finer than the µs kept."""
    text = ("1468939993.067416019 34 145 0\n1468939993.0674165 1 1 1\n1468939993.067416499999999999 2 2 0\n"
            "1468939993.06741650000000001 3 3 1\n-1468939993.0674165001 4 4 1\n")
    table = read_events_table(write(tmp_path, "ros.txt", text))
    assert table["t"].to_pylist() == [1468939993067416, 1468939993067417, 1468939993067416, 1468939993067417, -1468939993067417]
    with pytest.raises(FormatError, match="line 1"):  # 20 digits before the µs: the time itself, not rounding
        read_events_table(write(tmp_path, "long.txt", "12345678901234567890.5 1 1 1\n"))


def test_extra_csv_columns_are_ignored_and_negative_times_kept(tmp_path):
    table = read_events_table(write(tmp_path, "e.csv", "t_ms,x,y,p,note\n1.5,1,2,1,abc\n-2,3,4,0,\n"))
    assert events_of(table) == [(1500, 1, 2, 1), (-2000, 3, 4, 0)]


@pytest.mark.parametrize("value", ["123456789012345678901", "1e30", "9223372036854775808"])
def test_times_too_large_are_a_clear_error(tmp_path, value):
    with pytest.raises(FormatError, match="line 2"):
        read_events_table(write(tmp_path, "e.csv", f"t,x,y,p\n{value},1,2,1\n"))


@pytest.mark.parametrize("name, text, said", [
    ("e.csv", "t,x,y,p\n1,2,3,1\n2,4,5,0\noops,1,1,1\n", "line 4: not a number: 'oops' "),
    ("e.csv", "t,x,y,p,note\n1,2,3,1,a\n2,1e,5,0,b\n", "line 3: not a number: '1e' "),
    ("e.csv", "t,x,y,p\n1,2,70000,1\n", "line 2: x and y must be whole numbers from 0 to 65535: '70000' "),
    ("e.csv", "t,x,y,p\n100,5.0,70000,1\n", "line 2: x and y must be whole numbers from 0 to 65535: '70000' "),
    ("e.csv", "t,x,y,p\n1,2,3,5\n", "line 2: polarity must be 0/1 or -1/1: '5' "),
    ("e.csv", "t,x,y,p\n1.5,2,3,1\n", "line 2: time is not a whole number of microseconds: '1.5' "),
    ("e.txt", "0.1 2 3 1\n0.2 x 3 1\n", "line 2: not a number: 'x' "),
    ("e.csv", "t,x,y,p\n1,2,3\n", "line 2: wrong number of fields: '1,2,3' "),
])
def test_a_bad_row_is_told_by_its_line_and_the_field_to_blame(tmp_path, name, text, said):
    with pytest.raises(FormatError) as error:
        read_events_table(write(tmp_path, name, text))
    assert said in str(error.value)


def test_nineteen_digit_times_that_int64_holds_read_back(tmp_path):
    """What `select -o x.csv` writes of an events table reads back, up to the largest int64."""
    table = read_events_table(write(tmp_path, "e.csv", "t,x,y,p\n1000000000000000000,1,2,1\n9223372036854775807,1,2,0\n"))
    assert table["t"].to_pylist() == [10**18, 2**63 - 1]


def test_long_numbers_with_only_zeros_beyond_int64_are_fine(tmp_path):
    table = read_events_table(write(tmp_path, "e.csv", "t_s,x,y,p\n0000000000000000001.50000000000000000000,1,2,1\n"))
    assert table["t"].to_pylist() == [1_500_000]


@settings(max_examples=150, deadline=None)
@given(
    rows=st.lists(
        st.tuples(
            st.decimals(min_value=-(10**6), max_value=10**6, allow_nan=False, allow_infinity=False, places=9),
            st.integers(0, 65535),
            st.integers(0, 65535),
            st.sampled_from([-1, 0, 1]),
        ),
        min_size=1,
        max_size=6,
    ),
    digits=st.sampled_from([3, 6]),
    style=st.sampled_from(["plain", "exponent"]),
    separator=st.sampled_from([",", " ", "\t", "  "]),
    end=st.sampled_from(["", "\n", "\r\n"]),
)
def test_text_times_equal_exact_decimal_arithmetic(rows, digits, style, separator, end):
    """The compiled parser against Python's Decimal: t scaled by 10**digits, rounded half away from zero."""
    from decimal import ROUND_HALF_UP, Decimal

    from neurotac_cli.io import kernels

    written = [(format(t, "E") if style == "exponent" else format(t, "f"), x, y, p) for t, x, y, p in rows]
    text = "\n".join(separator.join(map(str, row)) for row in written) + end
    t, x, y, p, count, status, _, _ = kernels.parse_text(np.frombuffer(text.encode(), np.uint8), np.arange(4), separator == ",", digits)
    expected = [int((Decimal(w[0]) * 10**digits).quantize(Decimal(1), rounding=ROUND_HALF_UP)) for w in written]
    assert status == kernels.TEXT_OK
    assert list(t) == expected
    assert list(x) == [r[1] for r in rows] and list(y) == [r[2] for r in rows]
    assert list(p) == [1 if r[3] == 1 else 0 for r in rows]


def test_a_coordinate_past_the_largest_sensor_is_refused_where_the_size_is_guessed(tmp_path):
    with pytest.raises(FormatError, match="x = 65535 would need a sensor 65536 pixels wide"):
        read_events_table(write(tmp_path, "e.csv", "t,x,y,p\n1,65535,0,1\n"))
    assert sch.sensor_of(read_events_table(write(tmp_path, "f.csv", "t,x,y,p\n1,65534,0,1\n")).schema) == (65535, 1)
