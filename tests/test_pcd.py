"""The PCD codec (fogsim.lidar.pcd) against PCL's file-format spec, written here from the spec's text."""
from __future__ import annotations

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.lidar.bounds import MAX_SCAN_POINTS
from fogsim.lidar.pcd import encode_pcd, read_pcd, read_pcd_header, write_pcd


def _records(n=5):
    rng = np.random.default_rng(3)
    r = np.zeros(n, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("label", "<u2"),
                     ("outcome", "i1"), ("t", "<f8")])
    for name in ("x", "y", "z", "intensity"):
        r[name] = rng.normal(size=n)
    r["label"], r["outcome"], r["t"] = np.arange(n) * 7, np.arange(n) % 4 - 1, rng.normal(size=n)
    return r


def _spec_header(text: bytes) -> dict:
    """The header as the spec describes it: KEY value… lines up to DATA, comments skipped."""
    out = {}
    for line in text.split(b"\n"):
        line = line.decode()
        if line.startswith("#") or not line:
            continue
        key, *vals = line.split()
        out[key] = vals
        if key == "DATA":
            break
    return out


@pytest.mark.parametrize("data", ["binary", "ascii"])
def test_round_trip_and_header_per_spec(tmp_path, data):
    rec = _records()
    path = tmp_path / "a.pcd"
    write_pcd(path, rec, data=data)
    raw = path.read_bytes()
    h = _spec_header(raw)
    assert h["VERSION"] == ["0.7"] and h["FIELDS"] == ["x", "y", "z", "intensity", "label", "outcome", "t"]
    assert h["SIZE"] == ["4", "4", "4", "4", "2", "1", "8"] and h["TYPE"] == ["F", "F", "F", "F", "U", "I", "F"]
    assert h["COUNT"] == ["1"] * 7 and h["WIDTH"] == ["5"] and h["HEIGHT"] == ["1"] and h["POINTS"] == ["5"]
    assert h["DATA"] == [data]
    if data == "binary":  # the body is the packed little-endian records, right after the DATA line
        body = raw[raw.index(b"DATA binary\n") + len(b"DATA binary\n"):]
        assert body == rec.tobytes()
    head, back = read_pcd(path)
    assert head.points == 5 and head.fields == rec.dtype.names
    for name in rec.dtype.names:
        np.testing.assert_array_equal(back[name], rec[name])  # ascii: %.9g / %.17g round-trip exactly


def test_count_above_one_and_empty(tmp_path):
    rec = np.zeros(3, [("xyz", "<f4", (3,)), ("id", "<i4")])
    rec["xyz"] = np.arange(9).reshape(3, 3)
    rec["id"] = [-1, 0, 5]
    write_pcd(tmp_path / "c.pcd", rec, data="ascii")
    assert read_pcd_header(tmp_path / "c.pcd").dtype["xyz"].shape == (3,)
    _, back = read_pcd(tmp_path / "c.pcd")
    np.testing.assert_array_equal(back["xyz"], rec["xyz"])
    write_pcd(tmp_path / "e.pcd", rec[:0])
    assert len(read_pcd(tmp_path / "e.pcd")[1]) == 0


def _header(points, data="binary", fields="x y z", size="4 4 4", type_="F F F", width=None):
    width = points if width is None else width
    return (f"VERSION 0.7\nFIELDS {fields}\nSIZE {size}\nTYPE {type_}\nCOUNT 1 1 1\nWIDTH {width}\nHEIGHT 1\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n").encode()


@pytest.mark.parametrize("raw, words", [
    (_header(4_000_000_000) + bytes(64), "exceeds the bound"),
    (_header(1000) + bytes(64), "header lies"),
    (_header(3, width=4), "WIDTH 4"),
    (_header(2, data="zip"), "DATA 'zip'"),
    (_header(2, size="4 4 3"), "SIZE 3"),
    (_header(2, fields="x y"), "one entry per field"),
    (b"hello\n" * 3, "unknown key"),
    (b"VERSION 0.7\n", "no DATA line"),
    (_header(2, data="ascii") + b"1 2 3\n", "2 points, the ASCII body has 1"),
    (_header(1, data="ascii") + b"1 2 x\n", "not numbers"),
    (_header(1, data="ascii", type_="F F U", size="4 4 1") + b"1 2 300\n", "outside its type"),
])
def test_bad_files_are_named(tmp_path, raw, words):
    path = tmp_path / "bad.pcd"
    path.write_bytes(raw)
    with pytest.raises(InputError, match=words) as info:
        read_pcd(path)
    assert str(path) in str(info.value)


def test_bound_is_checked_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "big.pcd"
    path.write_bytes(_header(11) + bytes(11 * 12))
    assert len(read_pcd(path)[1]) == 11
    monkeypatch.setenv("FOGSIM_MAX_SCAN_POINTS", "10")
    with pytest.raises(InputError, match="bound of 10 points"):
        read_pcd(path)
    assert MAX_SCAN_POINTS >= 1_000_000


def test_encode_refuses_what_pcd_cannot_hold():
    with pytest.raises(ValueError, match="structured"):
        encode_pcd(np.zeros((3, 3), np.float32))
    with pytest.raises(ValueError, match="float32/64 or an integer"):
        encode_pcd(np.zeros(2, [("x", "<f2")]))
