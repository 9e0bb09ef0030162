"""A minimal protobuf wire-format decoder and encoder (no generated code, no protobuf package).

Decoding returns a message's fields by number: ``{number: [value, ...]}`` in file order, where
a value is an ``int`` for varints (wire type 0, unsigned; :func:`integer` signs it), ``bytes`` of
length 8 or 4 for fixed64/fixed32 (wire types 1 and 5), and a ``memoryview`` into the input for
length-delimited fields (wire type 2: bytes, strings, sub-messages, packed repeated scalars),
so large payloads are not copied until used. Groups (wire types 3/4) are rejected. The typed
accessors (:func:`integer`, :func:`string`, :func:`doubles`, ...) check the wire type.
The encoder writes the same wire types; it exists mainly to build test fixtures.
"""
from __future__ import annotations

import struct
from typing import Iterable

from fogsim.errors import InputError

VARINT, FIXED64, LEN, FIXED32 = 0, 1, 2, 5
_FIXED_SIZE = {FIXED64: 8, FIXED32: 4}

Fields = dict[int, list]


# ----------------------------------------------------------------------------- decoding
def _read_varint(buf: memoryview, pos: int, source: str) -> tuple[int, int]:
    """Decode a base-128 varint at ``pos``; return (value, position after it)."""
    value = shift = 0
    while pos < len(buf) and shift < 70:
        byte = buf[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, pos
        shift += 7
    raise InputError(source, "malformed protobuf (truncated or overlong varint)")


def decode_fields(data: bytes | memoryview, source: str = "protobuf message") -> Fields:
    """Split a serialized message into ``{field number: [values]}`` (see the module doc)."""
    buf = memoryview(data).cast("B")
    fields: Fields = {}
    pos = 0
    while pos < len(buf):
        tag, pos = _read_varint(buf, pos, source)
        number, wire = tag >> 3, tag & 7
        if number == 0:
            raise InputError(source, "malformed protobuf (field number 0)")
        if wire == VARINT:
            value, pos = _read_varint(buf, pos, source)
        else:
            if wire == LEN:
                size, pos = _read_varint(buf, pos, source)
            elif wire in _FIXED_SIZE:
                size = _FIXED_SIZE[wire]
            else:
                raise InputError(source, f"unsupported protobuf wire type {wire} (field {number})")
            end = pos + size
            if end > len(buf):
                raise InputError(source, f"malformed protobuf (field {number} runs past the end)")
            value = buf[pos:end] if wire == LEN else bytes(buf[pos:end])
            pos = end
        fields.setdefault(number, []).append(value)
    return fields


_WIRE_WORDS = {int: "a varint (a number)", memoryview: "length-delimited (a message, string or bytes)",
               bytes: "a fixed-size number"}


def _values(fields: Fields, number: int, kind: type, source: str) -> list:
    values = fields.get(number, [])
    wrong = next((v for v in values if not isinstance(v, kind)), None)
    if wrong is not None:
        raise InputError(source, f"malformed protobuf: field {number} has the wrong wire type, "
                                 f"{_WIRE_WORDS[type(wrong)]} where {_WIRE_WORDS[kind]} belongs")
    return values


def integer(fields: Fields, number: int, default: int = 0, source: str = "protobuf message") -> int:
    """A singular int32/int64/enum field as a signed integer (last value wins, as in protobuf)."""
    values = _values(fields, number, int, source)
    if not values:
        return default
    return values[-1] - (1 << 64) if values[-1] >= 1 << 63 else values[-1]


def blob(fields: Fields, number: int, source: str = "protobuf message") -> bytes | None:
    """A singular bytes field, or None when absent."""
    values = _values(fields, number, memoryview, source)
    return bytes(values[-1]) if values else None


def string(fields: Fields, number: int, source: str = "protobuf message") -> str:
    """A singular string field ("" when absent; undecodable UTF-8 replaced)."""
    data = blob(fields, number, source)
    return "" if data is None else data.decode("utf-8", errors="replace")


def submessages(fields: Fields, number: int, source: str = "protobuf message") -> list[Fields]:
    """A repeated message field, each entry decoded with :func:`decode_fields`."""
    return [decode_fields(v, source) for v in _values(fields, number, memoryview, source)]


def submessage(fields: Fields, number: int, source: str = "protobuf message") -> Fields:
    """A singular message field ({} when absent; repeated occurrences merge, as in protobuf)."""
    merged: Fields = {}
    for message in submessages(fields, number, source):
        for key, values in message.items():
            merged.setdefault(key, []).extend(values)
    return merged


def doubles(fields: Fields, number: int, source: str = "protobuf message") -> list[float]:
    """A ``repeated double`` field, accepting both packed (LEN) and unpacked (fixed64) entries."""
    out: list[float] = []
    for value in fields.get(number, ()):
        if isinstance(value, int) or len(value) % 8:
            raise InputError(source, f"malformed protobuf (field {number} is not doubles)")
        out.extend(struct.unpack(f"<{len(value) // 8}d", value))
    return out


# ----------------------------------------------------------------------------- encoding
def encode_varint(value: int) -> bytes:
    """Base-128 varint; negative numbers are written as 10-byte two's complement (int64)."""
    value &= (1 << 64) - 1
    out = bytearray()
    while value >= 0x80:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def _tag(number: int, wire: int) -> bytes:
    return encode_varint((number << 3) | wire)


def varint_field(number: int, value: int) -> bytes:
    """An int32/int64/uint/bool/enum field."""
    return _tag(number, VARINT) + encode_varint(int(value))


def bytes_field(number: int, value: bytes | str) -> bytes:
    """A bytes/string/sub-message field (``str`` is encoded as UTF-8)."""
    data = value.encode() if isinstance(value, str) else bytes(value)
    return _tag(number, LEN) + encode_varint(len(data)) + data


def double_field(number: int, value: float) -> bytes:
    """One ``double`` (fixed64) entry; repeat it for an unpacked repeated field."""
    return _tag(number, FIXED64) + struct.pack("<d", value)


def packed_doubles(number: int, values: Iterable[float]) -> bytes:
    """A packed ``repeated double`` field."""
    values = list(values)
    return bytes_field(number, struct.pack(f"<{len(values)}d", *values))
