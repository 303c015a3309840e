"""``couture export-foxglove``: originals copied unchanged, foxglove.* protobuf
channels added with the right geometry, strain colours, frames and logs."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from couture.mesh import grid_sheet
from couture.recording import SessionWriter
from couture.recording.foxglove import (
    MANNEQUIN_OBJ,
    Y_UP_TO_Z_UP,
    export_foxglove,
    strain_colors,
    strain_scale,
    triangle_list,
    vertex_strain,
)
from schemas import DrapeMsg, PatternMsg, StatusMsg, encode
from schemas.convert import mesh_to_msg

STRETCH = 1.05
GREEN = 0.5 * (STRETCH**2 - 1)  # = 0.05 (1 + 0.05/2) = 0.05125
T0 = 1_700_000_000_000_000_000


def stretched(X: np.ndarray) -> np.ndarray:
    """The flat sheet stretched 5 % along x, lifted to y = 1 m (couture is y up)."""
    return np.column_stack([STRETCH * X[:, 0], X[:, 1] + 1.0, np.zeros(len(X))])


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    d = tmp_path_factory.mktemp("fox")
    fine = grid_sheet(0.4, 0.3, 9, 7)
    fine.level = "fine"
    coarse = grid_sheet(0.4, 0.3, 5, 4)
    coarse.level = "coarse"
    assert len(coarse.X) != len(fine.X)
    msgs = [
        ("pattern", PatternMsg(name="sheet", generation=1)),
        ("mesh/coarse", mesh_to_msg(coarse, generation=1, mesh_generation=1)),
        ("mesh/fine", mesh_to_msg(fine, generation=1, mesh_generation=1)),
        ("status/solver-kinetic", StatusMsg(node="solver-kinetic")),
        ("drape/coarse", DrapeMsg(level="coarse", x=stretched(coarse.X), generation=1, mesh_generation=1)),
        ("drape/fine", DrapeMsg(level="fine", x=fine.x0, generation=1, mesh_generation=1, final=False)),
        ("status/solver-kinetic", StatusMsg(node="solver-kinetic", last_error="boom")),
        ("drape/fine", DrapeMsg(level="fine", x=stretched(fine.X), generation=1, mesh_generation=1, converged=True)),
        ("status/solver-kinetic", StatusMsg(node="solver-kinetic", last_error="boom")),
        (
            "drape/predicted",
            DrapeMsg(level="predicted", mesh_level="coarse", x=stretched(coarse.X), generation=1, mesh_generation=1),
        ),
        ("drape/fine", DrapeMsg(level="fine", x=stretched(fine.X), generation=2, mesh_generation=7)),  # no such mesh
        ("status/solver-kinetic", StatusMsg(node="solver-kinetic", last_error="")),
    ]
    src = d / "in.mcap"
    w = SessionWriter(str(src))
    w.add_metadata("couture", {"session": "t"})
    for i, (topic, m) in enumerate(msgs):
        m.seq, m.stamp_ns = i + 1, T0 + i * 1_000_000
        w.write(f"couture/t/{topic}", encode(m), log_time=T0 + i * 1_000_000 + 500)
    w.close()
    dst = d / "out.mcap"
    stats = export_foxglove(src, dst)
    return {"src": src, "dst": dst, "stats": stats, "fine": fine, "coarse": coarse, "n_msgs": len(msgs)}


def raw_messages(path, foxglove: bool):
    with open(path, "rb") as f:
        r = make_reader(f)
        return [
            (
                ch.topic,
                ch.message_encoding,
                sch.name if sch else "",
                sch.encoding if sch else "",
                m.log_time,
                m.publish_time,
                m.sequence,
                m.data,
            )
            for sch, ch, m in r.iter_messages(log_time_order=False)
            if ch.topic.startswith("/foxglove/") == foxglove
        ]


def decoded(path, topic):
    with open(path, "rb") as f:
        r = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(m.log_time, p) for _, _, m, p in r.iter_decoded_messages(topics=[topic], log_time_order=False)]


def test_original_messages_unchanged(session):
    orig = raw_messages(session["src"], foxglove=False)
    assert len(orig) == session["n_msgs"]
    assert raw_messages(session["dst"], foxglove=False) == orig
    assert session["stats"].copied == len(orig)
    with open(session["dst"], "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["couture"] == {"session": "t"}
    assert "0.1" in meta["couture/export-foxglove"]["strain_scale"]


def test_strain_of_uniform_stretch(session):
    fine = session["fine"]
    np.testing.assert_allclose(vertex_strain(fine.X, stretched(fine.X), fine.tris), GREEN, atol=1e-12)
    np.testing.assert_allclose(vertex_strain(fine.X, fine.x0, fine.tris), 0.0, atol=1e-12)


def test_drape_scene_update_geometry_and_colour(session):
    fine = session["fine"]
    ups = decoded(session["dst"], "/foxglove/drape/fine")
    assert len(ups) == 2  # the third drape/fine names a mesh_generation with no mesh
    assert session["stats"].drapes_without_mesh == 1
    flat_t, flat = ups[0]
    t, upd = ups[1]
    assert upd.DESCRIPTOR.full_name == "foxglove.SceneUpdate"
    (ent,) = upd.entities
    assert ent.id == "drape/fine" and ent.frame_id == "couture" and ent.timestamp.ToNanoseconds() == t
    assert dict((kv.key, kv.value) for kv in ent.metadata)["converged"] == "True"
    (prim,) = ent.triangles
    n = len(fine.X)
    assert len(prim.points) == n and len(prim.colors) == n
    np.testing.assert_array_equal(np.array(prim.indices).reshape(-1, 3), fine.tris)
    xyz = np.array([(p.x, p.y, p.z) for p in prim.points])
    np.testing.assert_allclose(xyz, stretched(fine.X), atol=1e-12)

    rgba = np.array([(c.r, c.g, c.b, c.a) for c in prim.colors])
    scale = strain_scale()
    assert (scale.lo, scale.hi) == (0.0, 0.10)
    want = np.append(scale.band_colors()[scale.band_of(np.array([GREEN]))][0] / 255.0, 1.0)
    np.testing.assert_allclose(rgba, np.broadcast_to(want, rgba.shape), atol=1e-9)
    # the unstretched drape is coloured differently (strain 0: the bottom band)
    rest = np.array([(c.r, c.g, c.b, c.a) for c in flat.entities[0].triangles[0].colors])
    np.testing.assert_allclose(rest, np.broadcast_to(strain_colors(np.zeros(1))[0], rest.shape), atol=1e-9)
    assert np.abs(rest[0] - want).max() > 0.1


def test_coarse_and_predicted_use_their_mesh(session):
    coarse = session["coarse"]
    for level in ("coarse", "predicted"):
        ((_, upd),) = decoded(session["dst"], f"/foxglove/drape/{level}")
        (ent,) = upd.entities
        assert ent.id == f"drape/{level}"
        prim = ent.triangles[0]
        assert len(prim.points) == len(coarse.X)
        np.testing.assert_array_equal(np.array(prim.indices).reshape(-1, 3), coarse.tris)


def test_body_once_and_frame_transform(session):
    body = decoded(session["dst"], "/foxglove/body")
    assert len(body) == 1
    (ent,) = body[0][1].entities
    assert ent.id == "body" and ent.frame_id == "couture"
    pts = np.array([(p.x, p.y, p.z) for p in ent.triangles[0].points])
    assert pts.shape == (12272, 3)
    assert len(ent.triangles[0].indices) == 3 * 24540
    (tf,) = [p for _, p in decoded(session["dst"], "/foxglove/tf")]
    assert (tf.parent_frame_id, tf.child_frame_id) == ("world", "couture")
    # the rotation takes couture's up (+y) to Foxglove's up (+z)
    qx, qy, qz, qw = tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w
    assert (qx, qy, qz, qw) == pytest.approx(Y_UP_TO_Z_UP)
    u = np.array([qx, qy, qz])
    v = np.array([0.0, 1.0, 0.0])
    rotated = v + 2 * qw * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))
    np.testing.assert_allclose(rotated, [0, 0, 1], atol=1e-12)
    # the body stands on its feet in world: height along couture y is about 1.67 m
    assert 1.5 < np.ptp(pts[:, 1]) < 1.8


def test_pattern_flat_beside_body(session):
    pats = decoded(session["dst"], "/foxglove/pattern")
    assert len(pats) == 2  # mesh/coarse (no fine yet), then mesh/fine
    (ent,) = pats[-1][1].entities
    assert ent.id == "pattern"
    prim = ent.triangles[0]
    pts = np.array([(p.x, p.y, p.z) for p in prim.points])
    np.testing.assert_allclose(pts, np.column_stack([session["fine"].X, np.zeros(len(pts))]))
    body = decoded(session["dst"], "/foxglove/body")[0][1].entities[0].triangles[0]
    body_xmax = max(p.x for p in body.points)
    assert prim.pose.position.x + pts[:, 0].min() > body_xmax  # beside, not inside, the body


def test_logs_on_last_error_changes(session):
    logs = [p for _, p in decoded(session["dst"], "/foxglove/log")]
    assert [(e.level, e.name) for e in logs] == [(4, "solver-kinetic"), (2, "solver-kinetic")]  # ERROR, INFO
    assert logs[0].message == "boom"


def test_fast_triangle_list_matches_protobuf_api():
    from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive

    rng = np.random.default_rng(1)
    pts, cols, tris = rng.normal(size=(5, 3)), rng.random((5, 4)), np.array([[0, 1, 2], [2, 3, 4]])
    slow = TriangleListPrimitive()
    slow.pose.position.SetInParent()
    slow.pose.orientation.w = 1.0
    for p in pts:
        slow.points.add(x=p[0], y=p[1], z=p[2])
    for c in cols:
        slow.colors.add(r=c[0], g=c[1], b=c[2], a=c[3])
    slow.indices.extend(tris.ravel().tolist())
    assert triangle_list(pts, tris, colors=cols) == slow


def test_truncated_recording_exports_what_is_whole(session, tmp_path):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(session["src"].read_bytes()[: int(session["src"].stat().st_size * 0.9)])
    stats = export_foxglove(cut, tmp_path / "out.mcap", body=None)
    assert not stats.body
    assert stats.copied <= session["n_msgs"]
    assert raw_messages(tmp_path / "out.mcap", foxglove=False) == raw_messages(session["src"], False)[: stats.copied]


def test_cli(session, tmp_path):
    out = tmp_path / "cli.mcap"
    r = subprocess.run(
        [sys.executable, "-m", "couture.cli", "export-foxglove", str(session["src"]), str(out), "--strain-max", "0.2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    assert "copied 12 messages" in r.stdout and "/foxglove/drape/fine: 2" in r.stdout
    assert len(decoded(out, "/foxglove/body")) == 1
    assert MANNEQUIN_OBJ.exists()
