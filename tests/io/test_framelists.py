"""The shared frame-list reader/writer: exact stamp parsers, round trips and errors naming the line."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io.framelists import (
    ns_digits,
    ns_integer,
    ns_number,
    read_stamped_rows,
    seconds_exact,
    write_stamped_list,
)


def test_stamp_parsers_are_exact() -> None:
    assert ns_digits("1403636579763555584") == 1403636579763555584
    assert ns_integer("-5") == -5
    # a float would give 1403636579763555584 for both; the decimal text is kept exactly
    assert ns_number("1403636579763555583.0") == 1403636579763555583
    assert ns_number("2.5") == 2 and ns_number("3.5") == 4 and ns_number("1e3") == 1000
    assert seconds_exact("1.000000001") == 1_000_000_001
    assert seconds_exact("12") == 12_000_000_000
    for parser, bad in ((ns_digits, "-1"), (ns_integer, "1.5"), (ns_number, "nan"),
                        (ns_number, "inf"), (seconds_exact, "1.0000000001"), (seconds_exact, "-1")):
        with pytest.raises(ValueError):
            parser(bad)


@given(st.lists(st.integers(0, 2**62), min_size=0, max_size=20, unique=True),
       st.sampled_from([",", ", ", " "]))
def test_write_read_round_trip(tmp_path_factory: pytest.TempPathFactory, stamps: list[int],
                               sep: str) -> None:
    stamps = sorted(stamps)
    f = tmp_path_factory.mktemp("fl") / "list.txt"
    write_stamped_list(f, "# header\n", stamps, [f"{t}.png" for t in stamps], sep=sep)
    back, rows = read_stamped_rows(f, expected="'t name'", sep=None if sep == " " else ",",
                                   increasing=True)
    assert back.tolist() == stamps and [r[1] for r in rows] == [f"{t}.png" for t in stamps]


@pytest.mark.parametrize(("text", "kw", "match"), [
    ("1,a\n2\n", {}, r"list\.csv:2: expected 't, name'"),
    ("1,a\nx,b\n", {"bad_stamp": "is not a stamp"}, r"list\.csv:2: timestamp 'x' is not a stamp"),
    ("2,a\n2,b\n", {"increasing": True}, r"list\.csv:2: timestamps must increase"),
    ("# only\n", {"nonempty": "no frames listed"}, "no frames listed"),
    ("1,\n", {"required": (1,)}, r"list\.csv:1"),
])
def test_errors_name_file_and_line(tmp_path: Path, text: str, kw: dict, match: str) -> None:
    f = tmp_path / "list.csv"
    f.write_text(text)
    with pytest.raises(FormatError, match=match):
        read_stamped_rows(f, expected="'t, name'", **kw)


def test_missing_file_and_bad_inputs(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="not here"):
        read_stamped_rows(tmp_path / "x.csv", expected="x", missing="not here")
    with pytest.raises(FileNotFoundError):
        read_stamped_rows(tmp_path / "x.csv", expected="x")
    with pytest.raises(FormatError, match="folder"):
        read_stamped_rows(tmp_path, expected="x")
    (tmp_path / "b.csv").write_bytes(b"1,\xff\n")
    with pytest.raises(FormatError, match="UTF-8"):
        read_stamped_rows(tmp_path / "b.csv", expected="x")
