"""Tolerant TUM parsing, and every named bad input: FormatError naming file and line."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.core.errors import FormatError, IbiscapeWarning
from ibiscape_eval.io import read_gnss, read_trajectory

ROW = "0 0 0 0 0 0 1"


def _write(tmp_path, text, name="t.txt"):
    p = tmp_path / name
    p.write_bytes(text.encode() if isinstance(text, str) else text)
    return p


def _error(path, fmt="tum", **kw) -> FormatError:
    with pytest.raises(FormatError) as e:
        read_trajectory(path, fmt, **kw)
    assert str(path) in str(e.value)
    return e.value


def test_tum_tolerant_separators_comments_blanks(tmp_path):
    text = ("# header comment\n\n"
            "1.0  2 3\t4 0 0 0 1   # trailing comment\n"
            "2.0,2,3,4,0,0,0,1\n"
            "3.0 , 2 ,\t3 , 4, 0 ,0, 0,1   \n"
            "   \n\t\n"
            "4.0 2 3 4 0 0 0 1\r\n"
            "# the end\n")
    tr = read_trajectory(_write(tmp_path, text), "tum")
    assert tr.stamps_ns.tolist() == [1_000_000_000, 2_000_000_000, 3_000_000_000, 4_000_000_000]
    np.testing.assert_allclose(tr.pos_m, [[2, 3, 4]] * 4)


def test_tum_ns_stamps_recognised_by_magnitude(tmp_path):
    # ORB-SLAM3's EuRoC-named output: TUM order, ns as fixed point
    text = ("1403715273262142976.000000 1 2 3 0 0 0 1\n"
            "1403715273312143104.000000 1 2 3 0 0 0 1\n")
    tr = read_trajectory(_write(tmp_path, text), "tum")
    assert tr.stamps_ns.tolist() == [1403715273262142976, 1403715273312143104]


def test_basalt_scientific_ns(tmp_path):
    text = ("#timestamp [ns],tx,ty,tz,qw,qx,qy,qz\n"
            "1.403715273262143e+18,1,2,3,1,0,0,0\n1.403715273312143e+18,1,2,3,1,0,0,0\n")
    tr = read_trajectory(_write(tmp_path, text, "trajectory.csv"))
    assert tr.stamps_ns.tolist() == [1403715273262143000, 1403715273312143000]
    np.testing.assert_allclose(tr.quat_xyzw, [[0, 0, 0, 1]] * 2)


def test_euroc_extra_columns_ignored_and_order(tmp_path):
    text = ("#timestamp, p_x, p_y, p_z, q_w, q_x, q_y, q_z, v_x, v_y, v_z\n"
            "1000,1,2,3,0,1,0,0,9,9,9\n2000,1,2,3,0,0,1,0,abc,9,9\n")
    tr = read_trajectory(_write(tmp_path, text, "data.csv"))
    np.testing.assert_allclose(tr.quat_xyzw, [[1, 0, 0, 0], [0, 1, 0, 0]])


@pytest.mark.parametrize(("text", "line", "pattern"), [
    (f"1 {ROW}\n2 {ROW} 9\n", 2, r"expected 8 columns \(t x y z qx qy qz qw\), got 9"),
    (f"1 {ROW}\n\n# c\n2 0 0 0 0 0 1\n", 4, r"expected 8 columns .*got 7"),
    (f"1 {ROW}\n" * 11 + "12 0 abc 0 0 0 0 1\n", 12, r"column 3: 'abc' is not a number"),
    (f"1 {ROW}\n2 0 0 0 0 0 0 0\n", 2, r"quaternion norm is 0"),
    (f"1 {ROW}\n2 0 0 0 0 0 0 1.01\n", 2, r"quaternion norm is 1.01"),
    (f"1 {ROW}\n3 {ROW}\n2 {ROW}\n", 3, r"earlier than .*must not decrease"),
    (f"1 {ROW}\n".encode() + b"\x00\x01\x02garbage\n", 2, r"binary data"),
    (f"1 {ROW}\n".encode() + b"\xff\xfe\xfa 1 2 3 4 5 6 7\n", 2, r"binary or non-text"),
])
def test_tum_bad_input_names_line(tmp_path, text, line, pattern):
    p = _write(tmp_path, text)
    err = _error(p)
    assert err.line == line
    assert f"{p}:{line}:" in str(err)
    assert re.search(pattern, str(err)), str(err)


@pytest.mark.parametrize("text", ["", "   \n\n", "# only a header\n# and comments\n"])
def test_empty_or_header_only(tmp_path, text):
    err = _error(_write(tmp_path, text))
    assert "empty" in str(err) or "no data rows" in str(err)


def test_euroc_header_only(tmp_path):
    p = _write(tmp_path, "#timestamp [ns],p_x,p_y,p_z,q_w,q_x,q_y,q_z\n", "data.csv")
    assert "no data rows" in str(_error(p, "euroc"))


def test_nonexistent_path(tmp_path):
    with pytest.raises((FileNotFoundError, FormatError)):
        read_trajectory(tmp_path / "nope.txt")


def test_nan_rows_skipped_with_one_warning(tmp_path):
    rows = [f"{i} {ROW}" for i in range(1, 11)]
    for k in (2, 4, 5, 6, 7, 8, 9):  # 7 rows, lines 3, 5, 6, 7, 8, 9, 10
        rows[k] = f"{k + 1} nan 0 0 0 0 0 1" if k % 2 else f"{k + 1} 0 0 0 0 0 inf 1"
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        tr = read_trajectory(_write(tmp_path, "\n".join(rows) + "\n"))
    ours = [x for x in w if issubclass(x.category, IbiscapeWarning)]
    assert len(ours) == 1
    msg = str(ours[0].message)
    assert "t.txt" in msg and "lines 3, 5, 6, 7, 8 and 2 more" in msg
    assert len(tr) == 3


def test_duplicates_warn_and_keep_first(tmp_path):
    text = f"1 {ROW}\n2 1 1 1 0 0 0 1\n2 5 5 5 0 0 0 1\n3 {ROW}\n"
    with pytest.warns(IbiscapeWarning, match=r"duplicate timestamp at line 3;"):
        tr = read_trajectory(_write(tmp_path, text))
    assert len(tr) == 3
    np.testing.assert_allclose(tr.pos_m[1], [1, 1, 1])


def test_near_unit_quaternion_renormalised(tmp_path):
    tr = read_trajectory(_write(tmp_path, "1 0 0 0 0 0 0 1.0005\n"))
    np.testing.assert_allclose(np.linalg.norm(tr.quat_xyzw, axis=1), 1.0)


def test_kitti_reorthonormalised_and_rejected(tmp_path):
    eye = "1 0 0 0 0 1 0 0 0 0 1 0"
    near = "1.0005 0 0 1 0 1 0 2 0 0 0.9995 3"
    tr = read_trajectory(_write(tmp_path, f"{eye}\n{near}\n"), "kitti")
    np.testing.assert_allclose(tr.quat_xyzw[1], [0, 0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(tr.pos_m[1], [1, 2, 3])
    err = _error(_write(tmp_path, f"{eye}\n{eye}\n1.01 0 0 0 0 1 0 0 0 0 1 0\n"), "kitti")
    assert err.line == 3 and "not a rotation" in str(err)
    err = _error(_write(tmp_path, f"{eye}\n-1 0 0 0 0 1 0 0 0 0 1 0\n"), "kitti")
    assert err.line == 2  # a reflection
    err = _error(_write(tmp_path, f"{eye}\n1 0 0 0 0 1 0 0 0 0 1\n"), "kitti")
    assert err.line == 2 and "expected 12 columns" in str(err)


def test_kitti_times_mismatch(tmp_path):
    p = _write(tmp_path, "1 0 0 0 0 1 0 0 0 0 1 0\n" * 3)
    t = _write(tmp_path, "0.0\n0.1\n", "times.txt")
    with pytest.raises(FormatError, match=r"times.txt: has 2 times but .* has 3 poses"):
        read_trajectory(p, "kitti", times_path=t)


def test_ibiscape_wrong_columns(tmp_path):
    from ibiscape_eval.io.ibiscape import IBISCAPE_HEADER

    row = ",".join(["1.000000"] + ["0"] * 9 + ["1", "0", "0", "0"] + ["0"] * 3) + " \n"
    bad = ",".join(["2.000000"] + ["0"] * 15) + " \n"
    p = _write(tmp_path, IBISCAPE_HEADER + "\r\n" + row + bad, "groundtruth_sync.csv")
    err = _error(p, "ibiscape")
    assert err.line == 3 and "expected 17 columns" in str(err) and "got 16" in str(err)


def test_gnss_errors(tmp_path):
    p = _write(tmp_path, "#timestamp [ns],latitude,longitude,altitude\n1.000000,48.1,2.3,50 \n"
               "2.000000,148.1,2.3,50 \n", "gnss.csv")
    with pytest.raises(FormatError, match=r"gnss.csv:3: latitude 148.1"):
        read_gnss(p)
    p = _write(tmp_path, "#timestamp [ns],latitude,longitude,altitude\n5,48.1,2.3,50 \n"
               "4,48.1,2.3,50 \n", "gnss.csv")
    with pytest.raises(FormatError, match=r"gnss.csv:3: timestamp 4 ns is earlier"):
        read_gnss(p)


def test_unknown_format_and_misapplied_options(tmp_path):
    from ibiscape_eval.core.errors import IbiscapeError

    p = _write(tmp_path, f"1 {ROW}\n")
    with pytest.raises(IbiscapeError, match="unknown trajectory format"):
        read_trajectory(p, "xyz")
    with pytest.raises(IbiscapeError, match="topic"):
        read_trajectory(p, "tum", topic="/x")


@settings(max_examples=300, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False, width=64))
def test_number_writer_is_accurate_over_the_whole_float_range(x: float) -> None:
    """15 significant digits for every finite double, tiny and subnormal ones included (their
    scale factor 10**s overflows if applied in one step)."""
    import io

    from ibiscape_eval.io._text import write_table

    buf = io.BytesIO()
    write_table(buf, None, np.array([[x]]), stamp="none", sep=" ")
    back = float(buf.getvalue().decode())
    assert back == pytest.approx(x, rel=1e-14, abs=1e-323)
