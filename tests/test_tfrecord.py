"""TFRecord framing and its CRC32C (``fogsim.readers.waymo.tfrecord``): round trip, damaged
lengths and data, the numpy fallback against the byte loop (and the compiled module when present)."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.readers.waymo import tfrecord
from fogsim.readers.waymo.tfrecord import crc32c_python, index_tfrecord, masked_crc32c, read_record, write_tfrecord


def test_crc32c_known_answer():
    assert crc32c_python(b"123456789") == 0xE3069283
    assert crc32c_python(b"") == 0


def test_tfrecord_round_trip_and_index(tmp_path):
    records = [b"", b"hello", bytes(range(256)) * 40]
    path = tmp_path / "x.tfrecord"
    write_tfrecord(path, records)
    index = index_tfrecord(path)
    assert index == [(12, 0), (28, 5), (49, 10240)]
    assert [read_record(path, o, n) for o, n in index] == records
    raw = path.read_bytes()
    assert struct.unpack("<I", raw[8:12])[0] == masked_crc32c(raw[:8])
    assert struct.unpack("<I", raw[33:37])[0] == masked_crc32c(b"hello")


def test_corrupt_length_crc_names_file_and_record(tmp_path):
    path = tmp_path / "bad.tfrecord"
    write_tfrecord(path, [b"a", b"bb"])
    raw = bytearray(path.read_bytes())
    raw[17 + 8] ^= 0xFF  # length CRC of record 1 (record 0 takes 12 + 1 + 4 bytes)
    path.write_bytes(bytes(raw))
    with pytest.raises(InputError, match="length CRC") as err:
        index_tfrecord(path)
    assert err.value.source == f"{path}#record 1"


def test_corrupt_data_crc(tmp_path, crc_impl):
    path = tmp_path / "bad.tfrecord"
    write_tfrecord(path, [b"abc", bytes(range(256)) * 400])
    raw = bytearray(path.read_bytes())
    raw[13] ^= 0xFF
    raw[-100] ^= 0x01  # one bit in the big record's data
    path.write_bytes(bytes(raw))
    (o0, n0), (o1, n1) = index_tfrecord(path)  # the headers are intact
    for offset, length, record in ((o0, n0, 0), (o1, n1, 1)):
        with pytest.raises(InputError, match="data CRC mismatch") as err:
            read_record(path, offset, length, f"{path}#record {record}")
        assert err.value.source == f"{path}#record {record}"
    assert read_record(path, o1, n1, verify=False)[-96] == (bytes(range(256)) * 400)[-96] ^ 0x01


@pytest.mark.parametrize("n", [0, 1, 9, 4095, 32767, 32768, 32769, 65536 + 7, 1 << 20, 3 * (1 << 20) + 5])
def test_crc32c_numpy_matches_the_byte_loop(n):
    data = np.random.default_rng(n).integers(0, 256, n, dtype=np.uint8).tobytes()
    if n <= 65536 + 7:
        assert tfrecord.crc32c_numpy(data) == crc32c_python(data)
    else:  # the byte loop is slow: split, since crc(A‖B) continues from crc(A)
        reg = tfrecord._register(data[:n // 2], 0xFFFFFFFF)
        assert tfrecord.crc32c_numpy(data) == tfrecord._register(data[n // 2:], reg) ^ 0xFFFFFFFF
    if tfrecord._FAST_CRC32C is not None:
        assert tfrecord.crc32c_numpy(data) == tfrecord._FAST_CRC32C(data)
    assert tfrecord.crc32c_numpy(b"123456789") == 0xE3069283


def test_crc32c_fallback_is_vectorised():
    """A Waymo frame is a few MB and is read twice per camera: the fallback must not loop over its
    bytes in Python (seconds per frame). Counted, not timed (a test must not depend on the machine's
    speed): the Python lines it runs for 4 MiB stay far below one per byte."""
    import sys

    data = np.random.default_rng(0).integers(0, 256, 4 << 20, dtype=np.uint8).tobytes()
    lines = 0

    def count(frame, event, arg):
        nonlocal lines
        lines += event == "line"
        return count

    sys.settrace(count)
    try:
        crc = tfrecord.crc32c_numpy(data)
    finally:
        sys.settrace(None)
    assert lines < 20_000, f"{lines} Python lines for {len(data)} bytes: a loop over the bytes?"
    assert crc == tfrecord.crc32c_numpy(data[: len(data) // 2] + data[len(data) // 2:])
