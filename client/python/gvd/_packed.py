"""FindNearestStreamResponse's packed answers read from the wire straight into NumPy arrays.

Protobuf's Python objects hand a repeated field over one Python number at a time (some 60 ns
each), which for a million answers costs more than the server takes to find them. A packed
field of doubles is the array's own little-endian bytes, and one of varints decodes in a few
vectorised NumPy steps. So protobuf parses each message as a type of this module's own, whose
packed answers declare their site ids alone: its C++ parser makes the ids' strings (5 times
faster than a loop here) and keeps each packed field of numbers as one unknown field's bytes,
which become the arrays. Fields it does not expect in the form the server sends (packed)
make it fall back to protobuf's parser of the API's own type. A small message (a few dozen
answers, as interactive calls get) is protobuf's to read whole here (PackedAnswers); a unary
call's whole answer (the client's _answer) is read a byte at a time (read_small), in the one
encoding the server writes, anything else left to protobuf: an interactive call comes after
an idle wait, with protobuf's code and NumPy's out of the caches, and a one-point answer in
a stream of moves took 47-50 µs that way against 70 µs through protobuf's parse and a NumPy
array a column (in a loop of its own 12.8 against 13.9 µs, in 107 k instructions against 90
k: fewer of them are NumPy's and protobuf's, which miss the caches there).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.message import DecodeError

from gvd.v1 import voronoi_pb2 as pb  # generated when the package is built

# PackedNearest's field numbers (proto/gvd/v1/voronoi.proto).
SITE_IDS, SITE, DISTANCE, ERROR_BOUND, EXACT = 1, 2, 3, 4, 5
FEATURE_INDEX, FEATURE_KIND, CLOSEST, GRADIENT = 6, 7, 8, 9
_DOUBLES = (DISTANCE, ERROR_BOUND, CLOSEST, GRADIENT)
_VARINTS = (SITE, EXACT, FEATURE_INDEX, FEATURE_KIND)
# Messages shorter than this are read by protobuf's parser (or by read_small, for a unary
# call's answer: the module's docstring).
_SMALL = 4096


@dataclass
class PackedAnswers:
    """One FindNearestStream message's answers as arrays (absent fields empty; a column of
    varints uint8 or uint64, see _varints)."""
    version: int = 0
    offset: int = 0
    site_ids: List[str] = field(default_factory=list)
    arrays: Dict[int, np.ndarray] = field(default_factory=dict)

    def get(self, number: int, dtype: str) -> np.ndarray:
        a = self.arrays.get(number)
        return np.zeros(0, dtype=dtype) if a is None else a

    @property
    def count(self) -> int:
        return len(self.get(DISTANCE, "<f8"))

    @staticmethod
    def FromString(data: bytes) -> "PackedAnswers":  # pylint: disable=invalid-name
        """The transports' deserializer: bytes of a FindNearestStreamResponse."""
        if len(data) < _SMALL:
            return _from_message(pb.FindNearestStreamResponse.FromString(data))
        try:
            return _read_response(data)
        except _Unexpected:
            return _from_message(pb.FindNearestStreamResponse.FromString(data))


class _Unexpected(Exception):
    """The bytes hold something this reader leaves to protobuf."""


def _answer_type() -> type:
    """FindNearestStreamResponse (version 2, packed 3, offset 4) with PackedNearest's
    site_ids (1) as the packed answers' only declared field. A FindNearestResponse's bytes
    parse as it too (its results, field 1, are then unknown: not this reader's)."""
    t = descriptor_pb2.FieldDescriptorProto
    f = descriptor_pb2.FileDescriptorProto(name="gvd/_packed.proto", package="gvd._packed",
                                           syntax="proto3")
    f.message_type.add(name="SiteIds").field.add(name="site_ids", number=1,
                                                  type=t.TYPE_STRING, label=t.LABEL_REPEATED)
    answers = f.message_type.add(name="Answers")
    for name, number in (("version", 2), ("offset", 4)):
        answers.field.add(name=name, number=number, type=t.TYPE_UINT64, label=t.LABEL_OPTIONAL)
    answers.field.add(name="packed", number=3, type=t.TYPE_MESSAGE,
                      type_name=".gvd._packed.SiteIds", label=t.LABEL_OPTIONAL)
    pool = descriptor_pool.DescriptorPool()
    pool.Add(f)
    descriptor = pool.FindMessageTypeByName("gvd._packed.Answers")
    if hasattr(message_factory, "GetMessageClass"):  # newer protobuf, which drops the factory
        return message_factory.GetMessageClass(descriptor)
    return message_factory.MessageFactory(pool).GetPrototype(descriptor)  # Debian 12's 3.21


_Answers = _answer_type()

try:  # newer protobuf, whose messages drop UnknownFields()
    from google.protobuf.unknown_fields import UnknownFieldSet as _unknown_fields
except ImportError:  # Debian 12's 3.21
    def _unknown_fields(message):
        return message.UnknownFields()


def _read_response(data: bytes) -> PackedAnswers:
    try:
        r = _Answers.FromString(data)
    except DecodeError as e:  # a site id that is no UTF-8, a cut record: protobuf's to judge
        raise _Unexpected() from e
    if len(_unknown_fields(r)):
        raise _Unexpected()  # a field in a form this type does not declare, or results
    out = PackedAnswers(version=r.version, offset=r.offset, site_ids=list(r.packed.site_ids))
    parts: Dict[int, List[bytes]] = {}  # a field's records, in order
    for record in _unknown_fields(r.packed):
        number = record.field_number
        if number in _DOUBLES or number in _VARINTS:
            if record.wire_type != 2:
                raise _Unexpected()  # an unpacked number
            parts.setdefault(number, []).append(record.data)
        elif number == 1:
            raise _Unexpected()  # site ids in a wrong form
    for number, chunks in parts.items():
        raw = chunks[0] if len(chunks) == 1 else b"".join(chunks)
        if number in _DOUBLES:
            if len(raw) % 8:
                raise _Unexpected()
            out.arrays[number] = np.frombuffer(raw, dtype="<f8")
        else:
            out.arrays[number] = _varints(np.frombuffer(raw, dtype=np.uint8))
    return out


def _varints(b: np.ndarray) -> np.ndarray:
    """The values of a run of varints: uint8 when each is one byte (small indices, bools,
    enums), else uint64. Decoded a byte position at a time over the values that reach it,
    so that the steps' arrays are the values' size, not eight bytes for each byte read."""
    if len(b) == 0:
        return np.zeros(0, dtype=np.uint64)
    last = b < 0x80
    if not last[-1]:
        raise _Unexpected()
    if last.all():
        return b
    ends = np.flatnonzero(last)
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    lengths = ends - starts + 1
    width = int(lengths.max())
    if width > 10:
        raise _Unexpected()
    values = (b[starts] & 0x7F).astype(np.uint64)
    for k in range(1, width):
        reach = np.flatnonzero(lengths > k)
        values[reach] |= (b[starts[reach] + k] & 0x7F).astype(np.uint64) << np.uint64(7 * k)
    return values


def _uvarint(data: bytes, pos: int) -> Tuple[int, int]:
    """The varint at data[pos] and the position after it; IndexError where it is cut short,
    longer than ten bytes or past 64 bits (protobuf keeps the low 64 bits of such a one: its
    parser is left to read it)."""
    b = data[pos]
    if b < 0x80:
        return b, pos + 1
    value, shift = b & 0x7F, 7
    while True:
        pos += 1
        b = data[pos]
        if shift == 63 and b > 1:
            raise IndexError("a varint past 64 bits")
        value |= (b & 0x7F) << shift
        if b < 0x80:
            return value, pos + 1
        shift += 7


def uvarints(raw: bytes) -> List[int]:
    """The values of a packed field of varints (IndexError where one is cut short)."""
    out = []
    pos, end = 0, len(raw)
    while pos < end:
        value, pos = _uvarint(raw, pos)
        out.append(value)
    return out


# FindNearestStreamResponse's keys (a field's number and wire type): version, packed, offset.
_VERSION_KEY, _PACKED_KEY, _OFFSET_KEY = 2 << 3, 3 << 3 | 2, 4 << 3


def read_small(data: bytes) -> Optional[Tuple[int, int, List[str], Dict[int, bytes]]]:
    """The version, offset, site ids and each other packed field's bytes (by its number) of a
    FindNearestStreamResponse, or of a FindNearestResponse without results, as the server
    writes them: each top field once, each of the packed answers' numbers in one record.
    None for anything else (results, another encoding, a field this reader does not know, a
    site id that is no UTF-8, a cut record): protobuf's parser reads or refuses those."""
    version = offset = 0
    packed = None
    try:
        pos, end = 0, len(data)
        while pos < end:
            key, pos = _uvarint(data, pos)
            if key == _VERSION_KEY:
                version, pos = _uvarint(data, pos)
            elif key == _OFFSET_KEY:
                offset, pos = _uvarint(data, pos)
            elif key == _PACKED_KEY and packed is None:
                n, pos = _uvarint(data, pos)
                packed = (pos, pos + n)
                pos += n
            else:
                return None
        if pos != end:
            return None
        ids: List[str] = []
        fields: Dict[int, bytes] = {}
        pos, end = packed or (0, 0)
        while pos < end:
            key, pos = _uvarint(data, pos)
            n, pos = _uvarint(data, pos)
            number, stop = key >> 3, pos + n
            if key & 7 != 2 or stop > end:
                return None
            if number == SITE_IDS:
                ids.append(data[pos:stop].decode())
            elif SITE <= number <= GRADIENT and number not in fields:
                fields[number] = data[pos:stop]
            else:
                return None
            pos = stop
    except (IndexError, UnicodeDecodeError):
        return None
    return version, offset, ids, fields


def _from_message(r: pb.FindNearestStreamResponse) -> PackedAnswers:
    """The same from a parsed message (protobuf's reading, for any encoding)."""
    p = r.packed
    out = PackedAnswers(version=r.version, offset=r.offset, site_ids=list(p.site_ids))
    for number, values, dtype in ((SITE, p.site, np.uint64), (DISTANCE, p.distance, "<f8"),
                                  (ERROR_BOUND, p.error_bound, "<f8"),
                                  (EXACT, p.exact, np.uint64),
                                  (FEATURE_INDEX, p.feature_index, np.uint64),
                                  (FEATURE_KIND, p.feature_kind, np.uint64),
                                  (CLOSEST, p.closest, "<f8"), (GRADIENT, p.gradient, "<f8")):
        n = len(values)
        # fromiter takes half the time of np.array over a list of the field (np.array over
        # the field itself reads it one number at a time, slower still).
        if n:
            out.arrays[number] = np.fromiter(values, dtype=dtype, count=n)
    return out

