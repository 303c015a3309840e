"""Export a couture recording with Foxglove-viewable channels added.

The Foxglove app cannot decode couture's msgpack channels, so
:func:`export_foxglove` copies every original schema, channel, message,
attachment and metadata record unchanged and adds channels of the official
``foxglove.*`` protobuf schemas (package ``foxglove-schemas-protobuf``, whose
FileDescriptorSets are written as the MCAP schemas):

============================  =======================  ==========================================
channel                       schema                   content
============================  =======================  ==========================================
``/foxglove/tf``              foxglove.FrameTransform  once: ``world`` (z up) -> ``couture`` (y up)
``/foxglove/body``            foxglove.SceneUpdate     once: the mannequin, entity ``body``
``/foxglove/drape/<level>``   foxglove.SceneUpdate     per drape message (coarse, fine, predicted):
                                                       the drape coloured by strain, entity
                                                       ``drape/<level>``
``/foxglove/pattern``         foxglove.SceneUpdate     per mesh/fine message (mesh/coarse until a
                                                       fine one is seen): the flat pattern beside
                                                       the body, entity ``pattern``
``/foxglove/log``             foxglove.Log             whenever a node's status ``last_error``
                                                       changes (ERROR; INFO when it clears)
============================  =======================  ==========================================

Frames: couture works in metres with y up (the mannequin OBJ, the drapes);
Foxglove's 3D panel is z up. Positions are written untouched in frame
``couture`` and one ``FrameTransform`` rotates it +90° about x into ``world``
(couture +y -> world +z, couture +z -> world -y), so values read back from the
export equal those in the recording.

Strain colours: the maximum principal Green strain of each triangle
(:func:`couture.ui.colormaps.principal_strain`, the function the 3D view
uses), averaged to vertices weighted by rest area, painted with the UI's
banded viridis scale over a *fixed* range, by default 0 to 0.10 in 10 bands of
0.01 (compression and anything above 10 % clamp to the end bands). The scale
is fixed, not fitted per message, so colours compare across messages and
sessions.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.KeyValuePair_pb2 import KeyValuePair
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from mcap.records import Attachment, Channel, Header, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from couture.recording.mcapio import split_key
from couture.ui.colormaps import ColorScale, principal_strain
from schemas.messages import DrapeMsg, MeshMsg, SchemaError, StatusMsg, decode

log = logging.getLogger("couture.foxglove")

MANNEQUIN_OBJ = Path(__file__).resolve().parents[1] / "assets" / "mannequin" / "body_a_pose.obj"

WORLD_FRAME = "world"
"""Foxglove's display frame, z up"""
COUTURE_FRAME = "couture"
"""couture's frame: metres, y up (mannequin, drapes)"""
Y_UP_TO_Z_UP = (np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5))
"""quaternion (x, y, z, w) of +90° about x: couture frame -> world frame"""

STRAIN_RANGE = (0.0, 0.10)
"""fixed colour range of max principal Green strain (dimensionless): 0 to 10 %"""
STRAIN_BANDS = 10
"""colour bands over STRAIN_RANGE (0.01 strain each)"""

DRAPE_LEVELS = ("coarse", "fine", "predicted")
PATTERN_GAP = 0.3
"""[m] between the body's side (max x) and the pattern's left edge"""
BODY_RGBA = (0.80, 0.78, 0.76, 1.0)
PATTERN_RGBA = (0.85, 0.62, 0.52, 1.0)


def strain_scale(strain_max: float = STRAIN_RANGE[1], n_bands: int = STRAIN_BANDS) -> ColorScale:
    """The fixed strain colour scale of the export (the UI's banded viridis)."""
    return ColorScale(0.0, float(strain_max), n_bands, diverging=False, unit="", label="max principal Green strain")


def vertex_strain(X: np.ndarray, x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Max principal Green strain per vertex (dimensionless), shape (n,): the
    per-triangle value averaged over incident triangles, weighted by rest area.
    ``X`` rest positions [m] (n, 2); ``x`` draped positions [m] (n, 3); ``tris`` (m, 3).
    Vertices in no triangle get 0."""
    X = np.asarray(X, np.float64)
    tris = np.asarray(tris, np.int64)
    e_tri = principal_strain(X, x, tris)[:, 1]
    e1 = X[tris[:, 1]] - X[tris[:, 0]]
    e2 = X[tris[:, 2]] - X[tris[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    num = np.zeros(len(X))
    den = np.zeros(len(X))
    for k in range(3):
        np.add.at(num, tris[:, k], area * e_tri)
        np.add.at(den, tris[:, k], area)
    return np.divide(num, den, out=np.zeros_like(num), where=den > 0)


def strain_colors(strain: np.ndarray, scale: ColorScale | None = None) -> np.ndarray:
    """RGBA in 0..1, shape (n, 4), float64, of per-vertex strains on ``scale``
    (default :func:`strain_scale`)."""
    scale = scale or strain_scale()
    rgb = scale.band_colors()[scale.band_of(strain)].astype(np.float64) / 255.0
    return np.column_stack([rgb, np.ones(len(rgb))])


def load_obj(path: str | Path = MANNEQUIN_OBJ) -> tuple[np.ndarray, np.ndarray]:
    """Vertices [m] (n, 3) and triangles (m, 3) of an OBJ (quads split)."""
    import trimesh

    m = trimesh.load_mesh(str(path), process=False)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


# --- protobuf building -------------------------------------------------------


def _repeated_doubles_bytes(field_number: int, values: np.ndarray) -> bytes:
    """Wire bytes of a repeated message field whose message holds only double
    fields numbered 1..k (foxglove.Point3, foxglove.Color), one row per element.
    Building these with numpy instead of one ``add()`` per vertex makes a
    10k-vertex drape take milliseconds; the bytes are parsed back by protobuf
    (``MergeFromString``), so a wrong encoding fails loudly."""
    v = np.ascontiguousarray(values, dtype="<f8")
    n, k = v.shape
    assert field_number < 16 and 9 * k < 128  # single-byte tag and length
    dt = np.dtype([("tag", "u1"), ("len", "u1")] + [f for j in range(k) for f in ((f"k{j}", "u1"), (f"v{j}", "<f8"))])
    rec = np.empty(n, dt)
    rec["tag"] = (field_number << 3) | 2
    rec["len"] = 9 * k
    for j in range(k):
        rec[f"k{j}"] = ((j + 1) << 3) | 1
        rec[f"v{j}"] = v[:, j]
    return rec.tobytes()


_F_POINTS = TriangleListPrimitive.DESCRIPTOR.fields_by_name["points"].number
_F_COLORS = TriangleListPrimitive.DESCRIPTOR.fields_by_name["colors"].number
assert [f.number for f in Point3.DESCRIPTOR.fields] == [1, 2, 3]
assert [f.number for f in Color.DESCRIPTOR.fields] == [1, 2, 3, 4]


def triangle_list(
    points: np.ndarray,
    tris: np.ndarray,
    *,
    colors: np.ndarray | None = None,
    color: tuple[float, float, float, float] | None = None,
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> TriangleListPrimitive:
    """A foxglove.TriangleListPrimitive: ``points`` [m] (n, 3), ``tris`` (m, 3)
    as indices, per-vertex ``colors`` RGBA 0..1 (n, 4) or one ``color``, the
    whole list translated by ``offset`` [m] (its pose)."""
    prim = TriangleListPrimitive()
    prim.pose.position.x, prim.pose.position.y, prim.pose.position.z = (float(c) for c in offset)
    prim.pose.orientation.w = 1.0
    raw = _repeated_doubles_bytes(_F_POINTS, np.asarray(points, np.float64).reshape(-1, 3))
    if colors is not None:
        raw += _repeated_doubles_bytes(_F_COLORS, np.asarray(colors, np.float64).reshape(-1, 4))
    prim.MergeFromString(raw)
    if color is not None:
        prim.color.r, prim.color.g, prim.color.b, prim.color.a = (float(c) for c in color)
    prim.indices.extend(np.asarray(tris, np.uint32).ravel().tolist())
    return prim


def scene_update(
    entity_id: str, frame_id: str, t_ns: int, prim: TriangleListPrimitive, metadata: dict[str, str] | None = None
) -> SceneUpdate:
    """A SceneUpdate with one entity (replacing any earlier one of the same id)."""
    upd = SceneUpdate()
    ent: SceneEntity = upd.entities.add()
    ent.timestamp.FromNanoseconds(int(t_ns))
    ent.frame_id = frame_id
    ent.id = entity_id
    for k, v in (metadata or {}).items():
        ent.metadata.append(KeyValuePair(key=k, value=v))
    ent.triangles.append(prim)
    return upd


def frame_transform(t_ns: int) -> FrameTransform:
    tf = FrameTransform(parent_frame_id=WORLD_FRAME, child_frame_id=COUTURE_FRAME)
    tf.timestamp.FromNanoseconds(int(t_ns))
    tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = Y_UP_TO_Z_UP
    return tf


# --- export ------------------------------------------------------------------


@dataclass
class ExportStats:
    copied: int = 0
    """original messages copied unchanged"""
    drapes: int = 0
    """SceneUpdates written on /foxglove/drape/*"""
    drapes_without_mesh: int = 0
    """drape messages skipped: no mesh of that level and mesh_generation (or vertex count differs)"""
    patterns: int = 0
    logs: int = 0
    body: bool = False
    undecodable: int = 0
    """couture messages on drape/mesh/status topics that did not decode"""
    by_topic: dict[str, int] = field(default_factory=dict)
    """messages written per added Foxglove topic"""

    def text(self) -> str:
        added = ", ".join(f"{t}: {n}" for t, n in sorted(self.by_topic.items())) or "none"
        s = f"copied {self.copied} messages; added {added}"
        if self.drapes_without_mesh:
            s += f"; {self.drapes_without_mesh} drape messages had no matching mesh (skipped)"
        if self.undecodable:
            s += f"; {self.undecodable} undecodable couture messages"
        return s


class _FoxgloveChannels:
    """Registers foxglove schemas/channels on first use and writes messages."""

    def __init__(self, writer: Writer, stats: ExportStats):
        self.w = writer
        self.stats = stats
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[str, int] = {}

    def write(self, topic: str, msg, log_time: int, publish_time: int) -> None:
        cid = self._channels.get(topic)
        if cid is None:
            name = msg.DESCRIPTOR.full_name
            if name not in self._schemas:
                self._schemas[name] = register_schema(self.w, type(msg))
            cid = self.w.register_channel(topic=topic, message_encoding="protobuf", schema_id=self._schemas[name])
            self._channels[topic] = cid
        seq = self._seq.get(topic, 0) + 1
        self._seq[topic] = seq
        self.w.add_message(
            channel_id=cid, log_time=log_time, publish_time=publish_time, data=msg.SerializeToString(), sequence=seq
        )
        self.stats.by_topic[topic] = self.stats.by_topic.get(topic, 0) + 1


MESHES_KEPT_PER_LEVEL = 8
"""mesh_generations remembered per (session, level) for drapes that arrive late"""


def export_foxglove(
    src: str | Path,
    dst: str | Path,
    *,
    strain_max: float = STRAIN_RANGE[1],
    n_bands: int = STRAIN_BANDS,
    body: str | Path | None = MANNEQUIN_OBJ,
    pattern: bool = True,
) -> ExportStats:
    """Copy recording ``src`` into ``dst`` unchanged and add Foxglove channels
    (module docstring). ``strain_max``: top of the fixed strain colour range
    (Green strain, dimensionless); ``body``: OBJ (y up, metres) to show, None
    for none; ``pattern``: add /foxglove/pattern. A truncated ``src`` (SIGKILL)
    is read up to its last whole record. Returns counts."""
    scale = strain_scale(strain_max, n_bands)
    stats = ExportStats()
    body_vt = load_obj(body) if body is not None else None
    pattern_offset_x = (float(body_vt[0][:, 0].max()) if body_vt is not None else 0.0) + PATTERN_GAP
    pattern_center_y = float(body_vt[0][:, 1].mean()) if body_vt is not None else 0.0

    meshes: dict[tuple[str, str], dict[int, MeshMsg]] = {}  # (session, level) -> mesh_generation -> latest mesh
    fine_pattern_seen: set[str] = set()
    last_error: dict[str, str] = {}
    schema_ids: dict[int, int] = {}  # src schema id -> dst
    channels: dict[int, Channel] = {}
    channel_ids: dict[int, int] = {}  # src channel id -> dst
    started = False

    with open(src, "rb") as fin, open(dst, "wb") as fout:
        reader = StreamReader(fin, record_size_limit=1 << 31)
        opened: tuple[Writer, _FoxgloveChannels] | None = None

        def start(profile: str) -> tuple[Writer, _FoxgloveChannels]:
            w = Writer(fout, compression=CompressionType.ZSTD)
            w.start(profile=profile, library="couture export-foxglove")
            return w, _FoxgloveChannels(w, stats)

        def first_message(fox: _FoxgloveChannels, t: int) -> None:
            fox.write("/foxglove/tf", frame_transform(t), t, t)
            if body_vt is not None:
                prim = triangle_list(body_vt[0], body_vt[1], color=BODY_RGBA)
                fox.write("/foxglove/body", scene_update("body", COUTURE_FRAME, t, prim, {"source": str(body)}), t, t)
                stats.body = True

        it = iter(reader.records)
        while True:
            try:
                rec = next(it)
            except StopIteration:
                break
            except Exception as e:  # truncated tail: keep what was whole
                log.warning("%s: stopped reading at a damaged or truncated record (%s)", src, e)
                break
            if isinstance(rec, Header):
                opened = start(rec.profile)
                continue
            if opened is None:
                opened = start("")
            w, fox = opened
            if isinstance(rec, Schema):
                if rec.id in schema_ids:  # the summary section repeats schemas and channels
                    continue
                schema_ids[rec.id] = w.register_schema(name=rec.name, encoding=rec.encoding, data=rec.data)
            elif isinstance(rec, Channel):
                if rec.id in channels:
                    continue
                channels[rec.id] = rec
                channel_ids[rec.id] = w.register_channel(
                    topic=rec.topic,
                    message_encoding=rec.message_encoding,
                    schema_id=schema_ids.get(rec.schema_id, 0),
                    metadata=dict(rec.metadata),
                )
            elif isinstance(rec, McapMessage):
                ch = channels.get(rec.channel_id)
                if ch is None:
                    continue
                if not started:
                    started = True
                    first_message(fox, rec.log_time)
                w.add_message(
                    channel_id=channel_ids[rec.channel_id],
                    log_time=rec.log_time,
                    data=rec.data,
                    publish_time=rec.publish_time,
                    sequence=rec.sequence,
                )
                stats.copied += 1
                _derive(
                    ch,
                    rec,
                    fox,
                    stats,
                    scale,
                    meshes,
                    fine_pattern_seen,
                    last_error,
                    (pattern_offset_x, pattern_center_y) if pattern else None,
                )
            elif isinstance(rec, Attachment):
                w.add_attachment(
                    create_time=rec.create_time,
                    log_time=rec.log_time,
                    name=rec.name,
                    media_type=rec.media_type,
                    data=rec.data,
                )
            elif isinstance(rec, Metadata):
                w.add_metadata(rec.name, dict(rec.metadata))
        w, fox = opened if opened is not None else start("")
        if not started and body_vt is not None:
            first_message(fox, 0)
        w.add_metadata(
            "couture/export-foxglove",
            {
                "source": str(src),
                "strain_scale": f"max principal Green strain, {scale.lo:g}..{scale.hi:g}, "
                f"{scale.n_bands} bands, viridis",
                "frames": f"{COUTURE_FRAME} (y up) -> {WORLD_FRAME} (z up): +90 deg about x",
            },
        )
        w.finish()
    return stats


def _derive(
    ch: Channel,
    rec: McapMessage,
    fox: _FoxgloveChannels,
    stats: ExportStats,
    scale: ColorScale,
    meshes: dict,
    fine_pattern_seen: set,
    last_error: dict,
    pattern_place: tuple[float, float] | None,
) -> None:
    """The Foxglove messages one original message gives rise to."""
    session, topic = split_key(ch.topic)
    kind = topic.split("/", 1)[0]
    if kind not in ("mesh", "drape", "status") or ch.message_encoding != "msgpack":
        return
    try:
        msg = decode(rec.data)
    except SchemaError:
        stats.undecodable += 1
        return
    t = rec.log_time
    if isinstance(msg, MeshMsg):
        gens = meshes.setdefault((session, msg.level), {})
        gens.pop(msg.mesh_generation, None)
        gens[msg.mesh_generation] = msg
        while len(gens) > MESHES_KEPT_PER_LEVEL:
            gens.pop(next(iter(gens)))
        if msg.level == "fine":
            fine_pattern_seen.add(session)
        if pattern_place is not None and (msg.level == "fine" or session not in fine_pattern_seen):
            X = msg.X.numpy()
            pts = np.column_stack([X, np.zeros(len(X))])
            off = (pattern_place[0] - X[:, 0].min(), pattern_place[1] - 0.5 * (X[:, 1].min() + X[:, 1].max()), 0.0)
            prim = triangle_list(pts, msg.tris.numpy(), color=PATTERN_RGBA, offset=off)
            fox.write(
                "/foxglove/pattern",
                scene_update(
                    "pattern",
                    COUTURE_FRAME,
                    t,
                    prim,
                    {
                        "level": msg.level,
                        "generation": str(msg.generation),
                        "mesh_generation": str(msg.mesh_generation),
                        "panels": ", ".join(msg.panel_names),
                    },
                ),
                t,
                rec.publish_time,
            )
            stats.patterns += 1
    elif isinstance(msg, DrapeMsg):
        if msg.level not in DRAPE_LEVELS:
            return
        mesh_level = msg.mesh_level if msg.level == "predicted" else msg.level
        mesh = meshes.get((session, mesh_level), {}).get(msg.mesh_generation)
        x = msg.x.numpy()
        if mesh is None or mesh.X.shape[0] != x.shape[0]:
            stats.drapes_without_mesh += 1
            return
        tris = mesh.tris.numpy()
        e = vertex_strain(mesh.X.numpy(), x, tris)
        prim = triangle_list(x, tris, colors=strain_colors(e, scale))
        meta = {
            "generation": str(msg.generation),
            "mesh_level": mesh_level,
            "mesh_generation": str(msg.mesh_generation),
            "residual": f"{msg.residual:.3g}",
            "iterations": str(msg.iterations),
            "solver": msg.solver,
            "method": msg.method,
            "converged": str(msg.converged),
            "final": str(msg.final),
            "strain_max": f"{float(e.max()) if e.size else 0.0:.4g}",
            "strain_scale": f"max principal Green strain {scale.lo:g}..{scale.hi:g}, {scale.n_bands} bands",
        }
        if msg.diagnosis:
            meta["diagnosis"] = msg.diagnosis
        fox.write(
            f"/foxglove/drape/{msg.level}",
            scene_update(f"drape/{msg.level}", COUTURE_FRAME, t, prim, meta),
            t,
            rec.publish_time,
        )
        stats.drapes += 1
    elif isinstance(msg, StatusMsg):
        node = f"{session}/{msg.node}" if session else msg.node
        before = last_error.get(node, "")
        if msg.last_error == before:
            return
        last_error[node] = msg.last_error
        entry = Log(name=msg.node, file=ch.topic)
        entry.timestamp.FromNanoseconds(int(t))
        if msg.last_error:
            entry.level = Log.ERROR
            entry.message = msg.last_error
        else:
            entry.level = Log.INFO
            entry.message = f"{msg.node}: error cleared (state {msg.state})"
        fox.write("/foxglove/log", entry, t, rec.publish_time)
        stats.logs += 1
