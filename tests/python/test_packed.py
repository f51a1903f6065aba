"""The Python client's reader of packed FindNearestStream answers (gvd._packed), against
protobuf's own parser of the same bytes: random and edge values (indices of every varint
length, no site, infinities, negative zero), fields split over several records, and the
unpacked encoding another server may send. And its writers of point and segment sites
(gvd._client._array_sites) and of a query's fields, against protobuf's parse of what they
write. No server needed."""
import itertools

import numpy as np
import pytest

import gvd

from gvd import _client, _packed
from gvd._packed import PackedAnswers
from gvd.v1 import voronoi_pb2 as pb

EDGE_INDICES = [0, 1, 127, 128, 16383, 16384, 2**21 - 1, 2**21, 2**28, 2**32 - 1]


def message(rng, n, closest):
    p = pb.PackedNearest()
    p.site_ids.extend(f"site-{k}-ü" for k in range(5))
    p.site.extend((EDGE_INDICES * (n // len(EDGE_INDICES) + 1))[:n] if n % 2 else
                  rng.integers(0, 2**32, n).tolist())
    d = rng.random(n) * 10.0 ** rng.integers(-300, 300, n)
    d[: min(n, 3)] = [np.inf, -0.0, 5e-324][: min(n, 3)]
    p.distance.extend(d.tolist())
    p.error_bound.extend(rng.random(n).tolist())
    p.exact.extend((rng.random(n) < 0.5).tolist())
    p.feature_index.extend(rng.integers(0, 2**32, n).tolist())
    p.feature_kind.extend(rng.integers(0, 3, n).tolist())
    if closest:
        p.closest.extend(rng.random(2 * n).tolist())
        p.gradient.extend(rng.random(2 * n).tolist())
    return pb.FindNearestStreamResponse(packed=p, version=int(rng.integers(0, 2**63)),
                                  offset=int(rng.integers(0, 2**40)))


def check(a, r):
    p = r.packed
    assert a.version == r.version and a.offset == r.offset
    assert a.site_ids == list(p.site_ids)
    for number, values in ((_packed.SITE, p.site), (_packed.DISTANCE, p.distance),
                           (_packed.ERROR_BOUND, p.error_bound), (_packed.EXACT, p.exact),
                           (_packed.FEATURE_INDEX, p.feature_index),
                           (_packed.FEATURE_KIND, p.feature_kind),
                           (_packed.CLOSEST, p.closest), (_packed.GRADIENT, p.gradient)):
        got = a.get(number, "<f8")
        want = np.array(list(values), dtype=got.dtype if len(got) else "<f8")
        assert len(got) == len(values), number
        # Bitwise: the same doubles, signs of zero included.
        assert got.tobytes() == want.tobytes(), number


@pytest.mark.parametrize("n", [0, 1, 2, 7, 1000, 65537])
@pytest.mark.parametrize("closest", [False, True])
def test_packed_answers_equal_protobufs_reading(n, closest):
    rng = np.random.default_rng(n)
    r = message(rng, n, closest)
    # Read by the wire reader itself (FromString would fall back to protobuf on its failure).
    check(_packed._read_response(r.SerializeToString()), r)
    check(PackedAnswers.FromString(r.SerializeToString()), r)


def test_what_the_wire_reader_leaves_to_protobuf_is_read_or_refused_by_it():
    # A site id that is no UTF-8: protobuf refuses it, as the reader does.
    inner = bytes([1 << 3 | 2, 2, 0xFF, 0xFE])
    data = bytes([3 << 3 | 2, len(inner)]) + inner
    with pytest.raises(_packed._Unexpected):
        _packed._read_response(data)
    with pytest.raises(Exception):
        PackedAnswers.FromString(data)
    # The version sent as a fixed64: protobuf's to judge.
    data = bytes([2 << 3 | 1]) + bytes(8)
    with pytest.raises(_packed._Unexpected):
        _packed._read_response(data)


def test_a_field_split_over_records_is_joined():
    rng = np.random.default_rng(5)
    first, second = message(rng, 9, False), message(rng, 4, False)
    # Protobuf merges a message field given twice, appending its repeated fields.
    data = first.SerializeToString() + second.SerializeToString()
    r = pb.FindNearestStreamResponse.FromString(data)
    check(_packed._read_response(data), r)
    check(PackedAnswers.FromString(data), r)


def test_the_unpacked_encoding_is_read_by_protobuf():
    # distance (field 3) as one unpacked double, then a packed site: valid protobuf.
    inner = bytes([3 << 3 | 1]) + np.float64(2.5).tobytes() + bytes([2 << 3 | 2, 1, 0])
    data = bytes([3 << 3 | 2, len(inner)]) + inner + bytes([2 << 3, 7])
    r = pb.FindNearestStreamResponse.FromString(data)
    a = PackedAnswers.FromString(data)
    check(a, r)
    assert a.version == 7 and list(a.get(_packed.DISTANCE, "<f8")) == [2.5]


def chunks(rng, sizes, closest):
    """FindNearestStream messages answering sizes[k] points each, in order, with their site
    indices below their site_ids' length; and the call's answers as the test reads them."""
    out, offset = [], 0
    for n in sizes:
        r = message(rng, n, closest)
        r.offset = offset
        del r.packed.site[:]
        r.packed.site.extend(rng.integers(0, 6, n).tolist())  # 0: none; ids 1..5
        del r.packed.site_ids[:]
        r.packed.site_ids.extend(f"s{int(k)}" for k in rng.integers(0, 8, 5))
        out.append(r)
        offset += n
    return out


OPTIONAL = ("error_bound", "exact", "feature_index", "feature_kind")


def check_answers(got, messages, m, closest):
    """A call's result against its messages' fields as protobuf reads them, an omitted
    optional column read as proto3's default, zero."""
    names = [(r.packed.site_ids[i - 1] if i else None) for r in messages for i in r.packed.site]
    assert got.site_ids.tolist() == names
    assert [got.ids[i] if i >= 0 else None for i in got.site_indices] == names
    assert len(set(got.ids)) == len(got.ids)
    for field, column, dtype in (("distance", got.distances, np.float64),
                                 ("error_bound", got.error_bounds, np.float64),
                                 ("exact", got.exact, bool),
                                 ("feature_index", got.feature_indices, np.uint32),
                                 ("feature_kind", got.feature_kinds, np.int32)):
        want = [v for r in messages
                for v in (getattr(r.packed, field) or [0] * len(r.packed.distance))]
        assert column.tolist() == want, field
        assert column.dtype == dtype and column.shape == (m,), field
        assert column.flags.writeable, field  # the caller's arrays, not views of the bytes
        assert column.flags.aligned, field
    if closest:
        for field, column in (("closest", got.closest), ("gradient", got.gradient)):
            want = [v for r in messages for v in getattr(r.packed, field)]
            assert column.shape == (m, 2) and column.ravel().tolist() == want, field
    else:
        assert got.closest is None and got.gradient is None
    assert got.version == max((r.version for r in messages), default=0)


@pytest.mark.parametrize("sizes", [[1], [3, 0, 4], [1000, 1, 70000], [70000]])
@pytest.mark.parametrize("closest", [False, True])
@pytest.mark.parametrize("omitted", [(), OPTIONAL])
def test_a_calls_messages_are_joined_in_offset_order(sizes, closest, omitted):
    from gvd import _client  # pylint: disable=import-outside-toplevel
    rng = np.random.default_rng(len(sizes))
    messages = chunks(rng, sizes, closest)
    # A server may leave out the optional columns (every other message here).
    for r in messages[::2]:
        for field in omitted:
            r.packed.ClearField(field)
    # The messages in any order: each is placed by its offset.
    parts = [_client._Packed(PackedAnswers.FromString(r.SerializeToString()), 0)
             for r in reversed(messages)]
    check_answers(_client._join(parts, sum(sizes), 2, closest), messages, sum(sizes), closest)


@pytest.mark.parametrize("n", [0, 1, 2, 40, 1000])
@pytest.mark.parametrize("closest", [False, True])
@pytest.mark.parametrize("omitted", [(), OPTIONAL])
@pytest.mark.parametrize("distinct", [False, True])
def test_a_unary_answer_is_read_whole(n, closest, omitted, distinct):
    # One message answering every point, small (read straight from protobuf's parse where its
    # site ids are distinct) or not (4 KiB and more: the packed reader's), with site ids
    # named twice or not, optional columns omitted or not.
    from gvd import _client  # pylint: disable=import-outside-toplevel
    rng = np.random.default_rng(n)
    (r,) = chunks(rng, [n], closest)
    if distinct:
        del r.packed.site_ids[:]
        r.packed.site_ids.extend(f"s{k}" for k in range(5))
    for field in omitted:
        r.packed.ClearField(field)
    check_answers(_client._answer(r.SerializeToString(), n, 2, closest), [r], n, closest)


def key(number, wire):
    return _client._varint(number << 3 | wire)


def record(number, payload):
    return key(number, 2) + _client._varint(len(payload)) + payload


def packed_records(p):
    """(number, payload) of each of PackedNearest p's fields as the server writes them: the
    site ids one record each, each column of numbers packed in one record."""
    out = [(1, i.encode()) for i in p.site_ids]
    for number, field in ((2, "site"), (3, "distance"), (4, "error_bound"), (5, "exact"),
                          (6, "feature_index"), (7, "feature_kind"), (8, "closest"),
                          (9, "gradient")):
        values = getattr(p, field)
        if len(values):
            one = pb.PackedNearest()
            getattr(one, field).extend(values)
            out.append((number, _payload(one.SerializeToString())))
    return out


def _payload(data):
    """The payload of a message of one length-delimited record (a one-byte key)."""
    pos, n, shift = 1, 0, 0
    while True:
        b = data[pos]
        n |= (b & 0x7F) << shift
        pos += 1
        if b < 0x80:
            assert pos + n == len(data)
            return data[pos:]
        shift += 7


def encodings(r):
    """FindNearestStreamResponse r's answers in encodings that protobuf reads as r (or, for
    the last ones, as a message of its own): the server's, the fields in another order, a
    column split over two records, the packed answers in two messages (merged), numbers
    unpacked, a field no reader knows, and FindNearestResponse's results beside them."""
    p = r.packed
    top = key(2, 0) + _client._varint(r.version) + key(4, 0) + _client._varint(r.offset)
    recs = packed_records(p)
    server = b"".join(record(n, d) for n, d in recs)
    yield "server", record(3, server) + top
    yield "reversed", (key(4, 0) + _client._varint(r.offset)
                       + record(3, b"".join(record(n, d) for n, d in reversed(recs)))
                       + key(2, 0) + _client._varint(r.version))
    if p.distance:
        split = b"".join(record(n, d) if n != 3 else record(3, d[:8]) + record(3, d[8:])
                         for n, d in recs)
        yield "split", top + record(3, split)
    half = len(recs) // 2
    yield "merged", (record(3, b"".join(record(n, d) for n, d in recs[:half])) + top
                     + record(3, b"".join(record(n, d) for n, d in recs[half:])))
    unpacked = b"".join(record(n, d) for n, d in recs if n != 2) + b"".join(
        key(2, 0) + _client._varint(v) for v in p.site)
    yield "unpacked", top + record(3, unpacked)
    yield "unknown", top + record(3, server + key(15, 0) + b"\x07")
    yield "unknown top", top + record(3, server) + key(9, 0) + b"\x01"
    yield "results", top + record(3, server) + record(1, b"")


@pytest.mark.parametrize("n,closest", [(1, False), (1, True), (3, False), (3, True),
                                       (130, False)])
def test_a_small_answer_reads_as_protobuf_reads_it_in_any_encoding(n, closest):
    # The small answer's own reader (read_small) takes the server's encoding and leaves any
    # other to protobuf: each encoding's result is protobuf's reading of its bytes, or
    # refused (INTERNAL) where that reading is no answer to the call's n points. Site
    # indices past 127 (two-byte varints) and the largest feature index.
    rng = np.random.default_rng(n)
    (r,) = chunks(rng, [n], closest)
    del r.packed.site_ids[:]
    r.packed.site_ids.extend(f"s{k}" for k in range(n))
    del r.packed.site[:]
    r.packed.site.extend(rng.permutation(np.arange(1, n + 1)).tolist())
    del r.packed.feature_index[:]
    r.packed.feature_index.extend([2**32 - 1] + rng.integers(0, 128, n - 1).tolist())
    r.offset = 0
    for name, data in encodings(r):
        assert len(data) < _packed._SMALL
        parsed = pb.FindNearestStreamResponse.FromString(data)
        small = _packed.read_small(data)
        if name in ("server", "reversed"):  # the server's encoding, in any order
            assert small == (parsed.version, parsed.offset, list(parsed.packed.site_ids),
                             {n: d for n, d in packed_records(parsed.packed) if n != 1}), name
        else:
            assert small is None, name
        regular = not (len(parsed.packed.site) != n or
                       (closest and len(parsed.packed.closest) != 2 * n))
        if name == "merged":
            regular = True  # the halves' fields joined: the same answers
        if regular:
            check_answers(_client._answer(data, n, 2, closest), [parsed], n, closest)
        else:
            with pytest.raises(gvd.GvdError):
                _client._answer(data, n, 2, closest)


# protobuf warns of some damaged bytes it reads, and the general reader of a negative kind.
@pytest.mark.filterwarnings("ignore::RuntimeWarning", "ignore::DeprecationWarning")
def test_a_cut_or_damaged_small_answer_is_read_as_protobuf_reads_it():
    # Every prefix of a small answer, and every byte of it changed, read by _answer against
    # protobuf's parse of the same bytes, answered through the general reader (_join): the
    # same answers, or both refused.
    rng = np.random.default_rng(11)
    (r,) = chunks(rng, [3], True)
    del r.packed.site_ids[:]
    r.packed.site_ids.extend(["a", "b", "c"])
    del r.packed.site[:]
    r.packed.site.extend([3, 1, 2])
    data = r.SerializeToString()
    cases = [data[:k] for k in range(len(data))]
    # A version of ten bytes whose last carries bits past the 64th (protobuf keeps the low
    # 64), and one of eleven.
    for last in (b"\x01", b"\x02", b"\x7f", b"\x81\x00"):
        cases.append(data + b"\x10" + b"\x85" + b"\x80" * 8 + last)
    cases += [data[:k] + bytes([b]) + data[k + 1:] for k in range(len(data))
              for b in (0x00, 0x7F, 0x80, 0xFF, data[k] ^ 0x08)]
    for case in cases:
        try:
            want = _client._join([_client._Packed(_packed._from_message(
                pb.FindNearestStreamResponse.FromString(case)), 0)], 3, 2, True)
        except Exception:  # pylint: disable=broad-except
            want = None
        if want is None:
            with pytest.raises(gvd.GvdError):
                _client._answer(case, 3, 2, True)
            continue
        got = _client._answer(case, 3, 2, True)
        for field in ("version", "ids"):
            assert getattr(got, field) == getattr(want, field), case
        for field in ("site_ids", "site_indices", "distances", "error_bounds", "exact",
                      "feature_indices", "feature_kinds", "closest", "gradient"):
            a, b = getattr(got, field), getattr(want, field)
            assert a.dtype == b.dtype and a.shape == b.shape, (field, case)
            assert a.tobytes() == b.tobytes() if a.dtype != object else a.tolist() == b.tolist(), (
                field, case)


@pytest.mark.parametrize("offsets,m", [([0, 2], 7), ([0, 4], 7), ([1, 3], 7), ([0, 3], 6)])
def test_answers_that_do_not_cover_the_points_once_are_refused(offsets, m):
    from gvd import _client  # pylint: disable=import-outside-toplevel
    rng = np.random.default_rng(9)
    messages = chunks(rng, [3, 4], False)
    parts = []
    for r, offset in zip(messages, offsets):
        r.offset = offset
        parts.append(_client._Packed(PackedAnswers.FromString(r.SerializeToString()), 0))
    with pytest.raises(gvd.GvdError) as e:
        _client._join(parts, m, 2, False)
    assert e.value.code.name == "INTERNAL"


def test_a_missing_column_or_a_site_past_the_ids_is_refused():
    from gvd import _client  # pylint: disable=import-outside-toplevel
    rng = np.random.default_rng(3)
    for damage in ("error_bound", "site", "closest"):
        (r,) = chunks(rng, [5], True)
        if damage == "site":
            r.packed.site[2] = 6  # five ids
        else:
            del getattr(r.packed, damage)[-1]
        part = _client._Packed(PackedAnswers.FromString(r.SerializeToString()), 0)
        with pytest.raises(gvd.GvdError) as e:
            _client._join([part], 5, 2, True)
        assert e.value.code.name == "INTERNAL", damage
        with pytest.raises(gvd.GvdError) as e:
            _client._answer(r.SerializeToString(), 5, 2, True)
        assert e.value.code.name == "INTERNAL", damage


def test_a_unary_answer_that_is_not_the_calls_is_refused():
    from gvd import _client  # pylint: disable=import-outside-toplevel
    rng = np.random.default_rng(4)
    (r,) = chunks(rng, [3], False)
    del r.packed.site_ids[:]
    r.packed.site_ids.extend(f"s{k}" for k in range(5))
    for data, m in ((r.SerializeToString(), 4),  # three answers for four points
                    (b"\x1a\x02\x12", 1),  # cut short: not a message
                    (b"", 1)):  # no answers
        with pytest.raises(gvd.GvdError) as e:
            _client._answer(data, m, 2, False)
        assert e.value.code.name == "INTERNAL", (data, m)
    r.offset = 1  # the three answers of points 1 to 3 of three
    with pytest.raises(gvd.GvdError) as e:
        _client._answer(r.SerializeToString(), 3, 2, False)
    assert e.value.code.name == "INTERNAL"


EDGE_COORDINATES = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308,
                    -1.0, 0.1, 1e-300]


# The points of a site of each kind, and the longest id its encoding takes: a Site of 127
# bytes, its id's tag and length, then the geometry's tag and length, and each point's x, y
# [, z] (9 bytes each), wrapped in a tag and a length where the geometry has two points.
POINTS = {"point": 1, "segment": 2}


def longest_id(kind, dims):
    points = POINTS[kind]
    return 127 - 2 - 2 - points * 9 * dims - (2 * points if points > 1 else 0)


@pytest.mark.parametrize("kind", ["point", "segment"])
@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("n", [len(EDGE_COORDINATES), _client.FEW_SITES, 3000])
def test_array_sites_are_the_sites_given_as_protobuf_reads_them(kind, dims, n):
    # Written a site at a time up to FEW_SITES, with NumPy's steps past it.
    rng = np.random.default_rng(dims)
    letters = list("az09-_.éü漢🙂")  # up to 4 bytes each
    longest = longest_id(kind, dims)
    ids = ["".join(rng.choice(letters, size=int(rng.integers(0, longest // 4 + 1))))
           for _ in range(n)]
    ids[:3] = ["", "x" * longest, "é" * (longest // 2)]
    points = POINTS[kind]
    shape = (n, points, dims)
    ends = rng.standard_normal(shape) * 10.0 ** rng.integers(-300, 300, shape)
    ends[: len(EDGE_COORDINATES), 0, 0] = EDGE_COORDINATES
    ends[: len(EDGE_COORDINATES), points - 1, dims - 1] = EDGE_COORDINATES[::-1]
    request = pb.UpsertSitesRequest(scene_id="scène", durability=pb.DURABILITY_RELAXED)
    data = _client._array_sites(request.SerializeToString(), ids, kind, ends)
    r = pb.UpsertSitesRequest.FromString(data)
    assert r.scene_id == "scène" and r.durability == pb.DURABILITY_RELAXED
    assert [s.id for s in r.sites] == ids
    assert all(s.WhichOneof("geometry") == kind for s in r.sites)
    ends_read = [[s.point] if kind == "point" else [s.segment.a, s.segment.b] for s in r.sites]
    got = np.array([[[p.x, p.y, p.z][:dims] for p in site] for site in ends_read])
    assert got.tobytes() == ends.tobytes()  # bitwise: signs of zero, subnormals
    # The same message as protobuf makes it from the same values.
    want = pb.UpsertSitesRequest(scene_id="scène", durability=pb.DURABILITY_RELAXED)
    for sid, site in zip(ids, ends.tolist()):
        made = [pb.Point(**dict(zip("xyz", p))) for p in site]
        if kind == "point":
            want.sites.add(id=sid).point.CopyFrom(made[0])
        else:
            want.sites.add(id=sid).segment.CopyFrom(pb.Segment(a=made[0], b=made[1]))
    assert r == want


@pytest.mark.parametrize("kind", ["point", "segment"])
@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("n", [2, _client.FEW_SITES + 1])
def test_array_sites_leave_long_ids_to_protobuf(kind, dims, n):
    longest = longest_id(kind, dims)
    fields = pb.UpsertSitesRequest(scene_id="s").SerializeToString()
    ends = np.zeros((n, POINTS[kind], dims))
    short = ["a"] * (n - 1)
    assert _client._array_sites(fields, short + ["x" * (longest + 1)], kind, ends) is None
    assert _client._array_sites(fields, short + ["é" * (longest // 2 + 1)], kind, ends) is None
    assert _client._array_sites(fields, short + ["x" * longest], kind, ends) is not None


@pytest.mark.parametrize("stream", [False, True])
def test_query_fields_are_the_request_protobuf_reads(stream):
    kind = pb.FindNearestStreamRequest if stream else pb.FindNearestRequest
    every_field = set(pb.NearestField.values()) - {pb.NEAREST_FIELD_UNSPECIFIED}
    for version in (0, 1, 127, 128, 2**32, 2**63, 2**64 - 1):
        for exact, skip, closest in itertools.product((False, True), repeat=3):
            fields = _client._query_fields("scène", exact, skip, closest, stream)
            r = kind.FromString(fields + _client._version_field(version))
            assert (r.scene_id, r.min_version, r.exact, r.skip_refinement) == \
                ("scène", version, exact, skip)
            assert set(r.fields) == (every_field if closest else set())
            assert len(r.points) == len(r.xy) == 0
            if stream:
                assert r.chunk_size == _client.CHUNK_POINTS


@pytest.mark.parametrize("version", [-1, 2**64])
def test_a_version_out_of_range_is_refused(version):
    with pytest.raises(ValueError, match="min_version"):
        _client._version_field(version)
    with pytest.raises(TypeError):
        _client._version_field(1.0)


class _Recorder:
    """A transport that keeps each call's bytes and answers an upsert at version 7."""

    def __init__(self):
        self.bodies = []

    def unary(self, method, request, response, timeout, body=None):
        self.bodies.append(body if body is not None else request.SerializeToString())
        return response(version=7)


@pytest.mark.parametrize("durability", ["sync", "relaxed"])
def test_upsert_sites_writes_the_request_protobuf_reads(durability):
    sites = [pb.Site(id="p-é", point=pb.Point(x=-0.0, y=5e-324)),
             {"id": "s", "segment": {"a": {"x": 1, "y": 2}, "b": {"x": 3, "y": 4}}},
             pb.Site(id="L" * 300, bezier=pb.Bezier(control_points=[pb.Point(x=k, y=-k)
                                                                    for k in range(200)]))]
    client = gvd.Client.__new__(gvd.Client)
    client._transport, client.timeout = _Recorder(), None  # pylint: disable=protected-access
    assert client.upsert_sites("scène", sites, durability=durability) == 7
    [body] = client._transport.bodies  # pylint: disable=protected-access
    want = pb.UpsertSitesRequest(scene_id="scène", durability=pb.DURABILITY_SYNC if durability ==
                                 "sync" else pb.DURABILITY_RELAXED)
    want.sites.extend([sites[0], gvd._client.site_from_dict(sites[1]), sites[2]])
    assert pb.UpsertSitesRequest.FromString(body) == want
