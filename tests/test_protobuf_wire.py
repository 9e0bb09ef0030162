"""The protobuf wire format reader and writer (``fogsim.readers.waymo.protobuf_wire``)."""
from __future__ import annotations

import pytest

from fogsim.errors import InputError
from fogsim.readers.waymo import protobuf_wire as pw


def test_protobuf_wire_round_trip():
    msg = (pw.varint_field(1, -5) + pw.packed_doubles(2, [1.5, 2.5]) + pw.double_field(2, 3.5)
           + pw.bytes_field(3, "naïve") + pw.varint_field(1, 7))
    fields = pw.decode_fields(msg)
    assert pw.integer(fields, 1) == 7  # last one wins
    assert pw.integer(pw.decode_fields(pw.varint_field(1, -5)), 1) == -5
    assert pw.doubles(fields, 2) == [1.5, 2.5, 3.5]
    assert pw.string(fields, 3) == "naïve"
    assert pw.integer(fields, 9, default=4) == 4 and pw.submessage(fields, 9) == {}


@pytest.mark.parametrize("data, problem", [
    (b"\x0b", "wire type 3"),                # start group
    (b"\x12\x05ab", "runs past the end"),    # length beyond the buffer
    (b"\x08\xff", "varint"),                 # unterminated varint
])
def test_protobuf_wire_rejects_malformed(data, problem):
    with pytest.raises(InputError, match=problem):
        pw.decode_fields(data, "m.pb")


def test_protobuf_wire_type_mismatch():
    with pytest.raises(InputError, match="wire type"):
        pw.string(pw.decode_fields(pw.varint_field(1, 3)), 1, "m.pb")
