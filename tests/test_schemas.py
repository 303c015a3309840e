"""Message schemas: round trips, validation errors that name schema and field,
random bytes, runtime-readable field types, mesh <-> GarmentMesh."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from msg_examples import messages, minimal

from couture.mesh import grid_sheet
from schemas import (
    MESSAGE_TYPES,
    REGISTRY,
    AdjustMsg,
    AdjustStatusMsg,
    Array,
    Design,
    DrapeMsg,
    EditMsg,
    MeshMsg,
    Message,
    PatternMsg,
    PsiMsg,
    SchemaError,
    SolveRequestMsg,
    SolveResultMsg,
    StatusMsg,
    TryOnMsg,
    decode,
    encode,
    type_for_topic,
)
from schemas.convert import mesh_to_msg, msg_to_mesh
from schemas.design import Sloper, Stroke
from schemas.topics import TOPICS, key_intersects, topic_spec

finite = st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e6, max_value=1e6)
ints = st.integers(min_value=0, max_value=2**40)
text = st.text(max_size=8)


def _arr(draw, shape, dtype=np.float64):
    n = int(np.prod(shape))
    vals = draw(st.lists(finite, min_size=n, max_size=n))
    return np.array(vals, dtype=dtype).reshape(shape)


@st.composite
def headers(draw):
    return dict(seq=draw(ints), stamp_ns=draw(ints), generation=draw(ints))


@st.composite
def mesh_msgs(draw):
    n = draw(st.integers(3, 6))
    m = draw(st.integers(0, 4))
    k = draw(st.integers(0, 3))
    tris = np.array(
        draw(st.lists(st.lists(st.integers(0, n - 1), min_size=3, max_size=3), min_size=m, max_size=m)), np.int32
    ).reshape(m, 3)
    return MeshMsg(
        **draw(headers()),
        level=draw(st.sampled_from(["coarse", "fine"])),
        mesh_generation=draw(ints),
        X=_arr(draw, (n, 2)),
        x0=_arr(draw, (n, 3)),
        tris=tris,
        tri_panel=np.zeros(m, np.int32),
        panel_names=["front"],
        seam_emitters=np.arange(k, dtype=np.int32) % n,
        seam_edges=np.zeros((k, 2), np.int32),
        seam_weights=_arr(draw, (k,)),
        pinned=np.array([0], np.int32),
    )


@st.composite
def drape_msgs(draw):
    n = draw(st.integers(0, 5))
    return DrapeMsg(
        **draw(headers()),
        level=draw(st.sampled_from(["coarse", "fine", "predicted"])),
        x=_arr(draw, (n, 3), draw(st.sampled_from([np.float32, np.float64]))),
        residual=draw(finite),
        iterations=draw(ints),
        solver=draw(text),
        method=draw(text),
        wall_time_s=draw(finite),
        converged=draw(st.booleans()),
        diagnosis=draw(text),
        d=draw(st.one_of(st.none(), st.just(np.array([0.1, -0.2])))),
        error_estimate=draw(st.one_of(st.none(), finite)),
    )


def _edit(draw, h):
    return EditMsg(
        **h,
        edit_id=draw(text),
        phase=draw(st.sampled_from(["press", "drag", "release"])),
        element=draw(text),
        dofs=["x"],
        d=_arr(draw, (2,)),
        view_proj=draw(st.one_of(st.none(), st.just(np.eye(4)))),
        viewport_px=[640, 480],
    )


def _tryon(draw, h):
    return TryOnMsg(
        **h,
        op_id=draw(text),
        op=draw(st.sampled_from(["start", "move", "rotate", "drag", "fix", "unfix", "sew", "unsew"])),
        panel="gore" + draw(text),
        vector=_arr(draw, (3,)),
        angle=draw(finite),
        seam=draw(st.integers(-1, 20)),
        sewn=draw(st.booleans()),
    )


def _adjust(draw, h):
    return AdjustMsg(
        **h,
        request_id=draw(text),
        edit="waist",
        amount=draw(st.floats(0.001, 0.5)),
        design=Design(sloper=Sloper(kind="skirt", params={"length": draw(finite)})),
        vertices=draw(st.sampled_from([0, 50, 400])),
        max_iters=draw(st.one_of(st.none(), st.integers(0, 10))),
    )


def _pattern(draw, h):
    strokes = [Stroke(id=draw(text), kind="curve", params={"t": draw(finite)})]
    return PatternMsg(**h, design=Design(strokes=strokes), source=draw(text))


def _solve_request(draw, h):
    mm = draw(mesh_msgs())
    return SolveRequestMsg(
        **h,
        request_id=draw(text),
        mesh=mm,
        x_warm=draw(st.one_of(st.none(), st.just(mm.x0.numpy()))),
        tol=draw(finite),
    )


HAND_WRITTEN = {
    PatternMsg: _pattern,
    EditMsg: _edit,
    TryOnMsg: _tryon,
    AdjustMsg: _adjust,
    SolveRequestMsg: _solve_request,
}
"""types whose interesting or valid values the field types alone do not say
(strokes, a mesh with faces, a nonzero amount, a panel for the op); every
other registered type is drawn from its schema (msg_examples.messages)"""


def of_type(cls):
    if cls is MeshMsg:
        return mesh_msgs()
    if cls is DrapeMsg:
        return drape_msgs()
    if cls in HAND_WRITTEN:
        return st.composite(lambda draw: HAND_WRITTEN[cls](draw, draw(headers())))()
    return messages(cls)


any_msgs = st.sampled_from(MESSAGE_TYPES).flatmap(of_type)


def _same(a, b) -> bool:
    return msgspec.msgpack.encode(a) == msgspec.msgpack.encode(b)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(any_msgs)
def test_every_type_round_trips(msg):
    data = encode(msg)
    back = decode(data, type(msg))
    assert type(back) is type(msg)
    assert back.schema == type(msg).TYPE
    assert _same(msg, back)


@pytest.mark.parametrize("cls", MESSAGE_TYPES, ids=lambda c: c.TYPE)
@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_every_registered_type_round_trips(cls, data):
    """Every type of the registry, hand-written strategy or not, with its minimal message too."""
    assert REGISTRY[cls.TYPE] is cls and cls.TYPE.startswith("couture/") and cls.TYPE.endswith("/v1")
    for msg in (data.draw(of_type(cls)), minimal(cls)):
        back = decode(encode(msg), cls)
        assert type(back) is cls and back.schema == cls.TYPE and _same(msg, back)


def test_registry_is_the_list_of_types():
    assert set(REGISTRY.values()) == set(MESSAGE_TYPES) and len(REGISTRY) == len(MESSAGE_TYPES)
    import schemas

    exported = {
        v for v in vars(schemas).values() if isinstance(v, type) and issubclass(v, Message) and v is not Message
    }
    assert exported == set(MESSAGE_TYPES), "schemas/__init__ exports every registered type, no other"


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=300))
def test_random_bytes_only_raise_schema_error(data):
    try:
        decode(data)
    except SchemaError:
        pass


@settings(max_examples=200, deadline=None)
@given(drape_msgs(), st.integers(0, 10_000), st.integers(0, 255))
def test_corrupted_payload_only_raises_schema_error(msg, pos, byte):
    data = bytearray(encode(msg))
    data[pos % len(data)] = byte
    for candidate in (bytes(data), bytes(data[: pos % len(data)])):
        try:
            decode(candidate)
        except SchemaError:
            pass


def test_every_field_has_a_runtime_readable_type():
    for cls in MESSAGE_TYPES:
        info = msgspec.inspect.type_info(cls)
        assert isinstance(info, msgspec.inspect.StructType)
        for f in info.fields:
            assert not isinstance(f.type, msgspec.inspect.AnyType), f"{cls.TYPE}.{f.name} has no runtime type"
        assert cls.__doc__ and "->" in cls.__doc__, f"{cls.TYPE} docstring must say who sends it to whom"


def _drape(n=4, **kw):
    return DrapeMsg(x=np.zeros((n, 3)), generation=1, **kw)


def _raw(msg) -> dict:
    return msgspec.msgpack.decode(msgspec.msgpack.encode(msg))


def _err(d: dict) -> str:
    with pytest.raises(SchemaError) as e:
        decode(msgspec.msgpack.encode(d))
    return str(e.value)


def test_wrong_type_names_schema_and_field():
    d = _raw(_drape())
    d["iterations"] = "many"
    msg = _err(d)
    assert "couture/drape/v1" in msg and "$.iterations" in msg


def test_missing_field_names_it():
    d = _raw(_drape())
    del d["x"]
    msg = _err(d)
    assert "couture/drape/v1" in msg and "x" in msg


def test_unknown_schema_and_version_say_what_is_accepted():
    d = _raw(_drape())
    d["schema"] = "couture/drape/v7"
    d["version"] = 7
    msg = _err(d)
    assert "couture/drape/v7" in msg and "v1" in msg and "accepted" in msg
    d["schema"] = "couture/nonsense/v1"
    assert "unknown schema" in _err(d)
    assert "schema" in _err({"x": 1})


@pytest.mark.parametrize("bad", [0.0, -0.5, float("nan"), float("inf")])
def test_scene_stiffness_factor_must_be_positive_and_finite(bad):
    d = _raw(PatternMsg(design=Design()))
    d["design"]["scene"]["contact_stiffness_scale"] = bad
    msg = _err(d)
    assert "couture/pattern/v1" in msg and "$.design.scene.contact_stiffness_scale" in msg


def test_nan_in_positions_rejected_with_index():
    x = np.zeros((3, 3))
    x[2, 1] = np.nan
    d = _raw(_drape())
    d["x"] = _raw(Array.from_numpy(x))
    msg = _err(d)
    assert "$.x" in msg and "non-finite" in msg and "7" in msg
    mm = _raw(mesh_to_msg(grid_sheet(1, 1, 4, 4)))
    X = np.zeros((mm["X"]["shape"][0], 2))
    X[0, 0] = np.inf
    mm["X"] = _raw(Array.from_numpy(X))
    assert "$.X" in _err(mm)


def test_shape_bytecount_dtype_checked():
    d = _raw(_drape())
    d["x"]["data"] = d["x"]["data"][:-8]
    assert "byte count" in _err(d)
    d = _raw(_drape())
    d["x"] = _raw(Array.from_numpy(np.zeros((4, 2))))
    assert "shape" in _err(d) and "$.x" in _err(d)
    d = _raw(_drape())
    d["x"] = _raw(Array.from_numpy(np.zeros((4, 3), np.int32)))
    assert "dtype int32 not allowed" in _err(d)
    d["x"]["dtype"] = "complex128"
    assert "complex128" in _err(d)


def test_mesh_dimensions_consistent_and_indices_in_range():
    mm = _raw(mesh_to_msg(grid_sheet(1, 1, 4, 4)))
    mm["x0"] = _raw(Array.from_numpy(np.zeros((2, 3))))
    msg = _err(mm)
    assert "$.x0" in msg and "n=" in msg
    mm = _raw(mesh_to_msg(grid_sheet(1, 1, 4, 4)))
    tris = np.zeros((mm["tris"]["shape"][0], 3), np.int32)
    tris[0, 0] = 10_000
    mm["tris"] = _raw(Array.from_numpy(tris))
    assert "$.tris" in _err(mm) and "outside" in _err(mm)


def test_expected_type_mismatch_is_schema_error():
    with pytest.raises(SchemaError, match="expected couture/mesh/v1"):
        decode(encode(_drape()), MeshMsg)


def test_truncated_payload_is_schema_error():
    data = encode(_drape(100))
    for cut in (1, 10, len(data) // 2, len(data) - 1):
        with pytest.raises(SchemaError):
            decode(data[:cut])


def test_encode_rejects_bad_message_at_sender():
    with pytest.raises(SchemaError, match=r"\$\.x"):
        encode(DrapeMsg(x=np.full((2, 3), np.nan)))


def test_numpy_scalars_become_plain_numbers():
    msg = DrapeMsg(
        x=np.zeros((1, 3), np.float32), generation=np.int64(3), residual=np.float32(0.5), iterations=np.int32(7)
    )
    raw = msgspec.msgpack.decode(encode(msg))
    assert raw["generation"] == 3 and type(raw["generation"]) is int
    assert raw["residual"] == 0.5 and type(raw["residual"]) is float
    back = decode(encode(msg))
    assert back.x.numpy().dtype == np.float32


def test_arrays_are_little_endian_raw_bytes():
    a = np.arange(6, dtype=">f8").reshape(2, 3)
    arr = Array.from_numpy(a)
    assert arr.dtype == "float64" and arr.shape == [2, 3]
    assert arr.data == np.arange(6, dtype="<f8").tobytes()
    np.testing.assert_array_equal(arr.numpy(), a)


def test_mesh_message_round_trips_garment_mesh():
    g = grid_sheet(0.5, 0.3, 6, 5)
    g.seam_emitters = np.array([0, 1], np.int32)
    g.seam_edges = np.array([[2, 3], [3, 4]], np.int32)
    g.seam_weights = np.array([0.25, 0.5])
    g.pinned = np.array([5], np.int32)
    g.panel_names = ["front"]
    g.level, g.generation = "coarse", 4
    msg = decode(encode(mesh_to_msg(g, mesh_generation=2)), MeshMsg)
    assert msg.level == "coarse" and msg.generation == 4 and msg.mesh_generation == 2
    back = msg_to_mesh(msg)
    for name in ("X", "x0", "tris", "tri_panel", "seam_emitters", "seam_edges", "seam_weights", "pinned"):
        np.testing.assert_array_equal(getattr(back, name), getattr(g, name), err_msg=name)
        assert getattr(back, name).dtype == getattr(g, name).dtype
    assert back.panel_names == ["front"] and back.level == "coarse" and back.generation == 4
    back.X[0, 0] = 1.0  # writable copy, not a view of the message bytes


def test_every_message_type_has_a_topic_and_every_topic_a_known_type():
    table_types = {t.msg_type for t in TOPICS}
    assert table_types == set(MESSAGE_TYPES), "each message type needs a row in schemas.topics.TOPICS"
    keys = [t.key for t in TOPICS]
    assert len(keys) == len(set(keys))
    for t in TOPICS:
        assert not (t.replayed and t.compared), f"{t.key} is either an input or an output"
        assert not (t.replayed or t.compared) or t.recorded, f"{t.key}: replay and compare read recordings"
        # DROP may lose large fragmented samples (Zenoh 1.10): never for state a late joiner resumes from
        assert not (t.delivery.drop and t.delivery.history), t.key


def test_key_expressions_intersect_like_zenoh():
    assert key_intersects("mesh/*", "mesh/fine")
    assert key_intersects("**", "solve/result/*")
    assert key_intersects("solve/**", "solve/result/*")
    assert key_intersects("status/*", "status/ui")
    assert not key_intersects("solve/*", "solve/result/*")
    assert not key_intersects("drape/*", "drape/fine/extra")
    assert not key_intersects("mesh/*", "mesh")
    assert topic_spec("status/solver-kinetic").msg_type is StatusMsg
    assert topic_spec("bench/done") is None


def test_topic_types():
    assert type_for_topic("drape/fine") is DrapeMsg
    assert type_for_topic("mesh/coarse") is MeshMsg
    assert type_for_topic("psi/fine") is PsiMsg and type_for_topic("psi/coarse") is PsiMsg
    assert type_for_topic("solve/result/newton") is SolveResultMsg
    assert type_for_topic("solve/request") is SolveRequestMsg
    assert type_for_topic("status/ui") is StatusMsg
    assert type_for_topic("drape/fine/extra") is None


def test_tryon_message_names_a_missing_panel_and_a_bad_angle():
    with pytest.raises(SchemaError, match=r"tryon/v1.*\$\.panel.*needs a panel"):
        decode(encode(TryOnMsg(op="drag", angle=0.1)), TryOnMsg)
    with pytest.raises(SchemaError, match=r"\$\.angle"):
        encode(TryOnMsg(op="rotate", panel="a", angle=float("inf")))
    with pytest.raises(SchemaError, match=r"\$\.vector"):
        encode(TryOnMsg(op="move", panel="a", vector=np.array([0.0, np.nan, 0.0])))
    ok = decode(encode(TryOnMsg(op="sew")), TryOnMsg)
    assert ok.seam == -1 and ok.vector.numpy().shape == (3,)


def test_adjust_request_names_a_bad_amount_and_bad_sizes():
    ok = decode(encode(AdjustMsg(edit="waist", amount=0.04, vertices=400)), AdjustMsg)
    # max_iters unnamed: the adjust node's settings (couture.adjust.settings.DEFAULTS), as `couture adjust`'s
    assert ok.edit == "waist" and ok.amount == 0.04 and ok.max_iters is None
    assert decode(encode(AdjustMsg(edit="waist", amount=0.04, max_iters=3)), AdjustMsg).max_iters == 3
    # a request recorded before (max_iters always sent, 2 by default) still decodes, its value kept
    old = {"schema": "couture/adjust/v1", "version": 1, "edit": "hem", "amount": -0.1, "max_iters": 2}
    assert decode(msgspec.msgpack.encode(old), AdjustMsg).max_iters == 2
    assert decode(encode(AdjustMsg(edit="hem", amount=0.1)), AdjustMsg).amount == 0.1  # lengthening
    for kw, words in (
        ({"edit": "waist", "amount": float("nan")}, "not a finite nonzero"),
        ({"edit": "waist", "amount": 0.0}, "not a finite nonzero"),
        ({"edit": "hem", "amount": -3.0}, "beyond"),
        ({"edit": "hem", "amount": -0.1, "vertices": 10}, "$.vertices"),
        ({"edit": "hem", "amount": -0.1, "max_iters": 50}, "$.max_iters"),
        ({"edit": "hem", "amount": -0.1, "max_iters": -1}, "$.max_iters"),
    ):
        with pytest.raises(SchemaError, match="couture/adjust/v1") as e:
            encode(AdjustMsg(**kw))
        assert words in str(e.value)
    data = msgspec.msgpack.encode({"schema": "couture/adjust/v1", "version": 1, "edit": "sleeve", "amount": 0.1})
    with pytest.raises(SchemaError, match=r"\$\.edit"):
        decode(data, AdjustMsg)


def test_adjust_status_recorded_before_the_verdict_decodes_as_not_judged():
    """A done status without the verdict's fields (recordings before them) decodes: goal_met None, no reasons."""
    import math

    old = {"schema": "couture/adjust_status/v1", "version": 1, "state": "done", "text": "hem -0.100 m", "iteration": 2}
    was = decode(msgspec.msgpack.encode(old), AdjustStatusMsg)
    assert was.goal_met is None and was.reasons == [] and was.solves == 0 and math.isnan(was.stretch)
    new = AdjustStatusMsg(state="done", goal_met=False, reasons=["Hausdorff 1.20 % > 1 %: at the hem"], solves=4)
    back = decode(encode(new), AdjustStatusMsg)
    assert back.goal_met is False and back.reasons == new.reasons and back.solves == 4


def test_psi_message_names_its_gesture_and_matches_its_shape():
    psi = np.zeros((5, 2, 2))
    psi[:, 0, 0] = 1.0
    ok = decode(encode(PsiMsg(level="fine", mesh_generation=3, edit_id="e1", psi=psi)), PsiMsg)
    np.testing.assert_array_equal(ok.psi.numpy(), psi)
    assert ok.schema == "couture/psi/v1" and ok.mesh_generation == 3
    with pytest.raises(SchemaError, match=r"psi/v1.*\$\.edit_id"):
        encode(PsiMsg(edit_id="", psi=psi))
    with pytest.raises(SchemaError, match=r"\$\.psi.*shape"):
        encode(PsiMsg(edit_id="e1", psi=np.zeros((5, 2))))
    bad = psi.copy()
    bad[2, 1, 0] = np.nan
    with pytest.raises(SchemaError, match=r"\$\.psi.*non-finite"):
        encode(PsiMsg(edit_id="e1", psi=bad))
    # the mesh carries Ψ no more: a payload that still names it decodes to the mesh alone
    raw = _raw(mesh_to_msg(grid_sheet(1, 1, 3, 3)))
    raw |= {"psi": _raw(Array.from_numpy(np.zeros((9, 2, 2)))), "psi_edit_id": "e1", "unchanged": True}
    m = decode(msgspec.msgpack.encode(raw), MeshMsg)
    assert not hasattr(m, "psi") and not hasattr(m, "unchanged")
