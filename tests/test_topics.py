"""The bus, recorder, replay, compare and CLI take their topic lists from the
one table in schemas.topics: a row added to it (here at runtime) shows up in
what each of them does, and the README's table is the table's own rendering."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest
import zenoh
from msg_examples import minimal

from couture.bus.session import publisher_options
from couture.recording.compare import compare
from couture.recording.mcapio import SessionWriter, check_payload, read_session
from couture.recording.recorder import records
from couture.recording.replay import ReplayConfig
from schemas import DrapeMsg, encode, topics

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def dummy_topics(monkeypatch):
    """Two extra rows: an input that travels like a preview, an output with history."""
    extra = (
        topics.Topic(
            "dummy/in",
            DrapeMsg,
            topics.Delivery(express=True, drop=True),
            recorded=True,
            replayed=True,
            compared=False,
            publisher="test",
        ),
        topics.Topic(
            "dummy/out/*",
            DrapeMsg,
            topics.Delivery(history=3),
            recorded=True,
            replayed=False,
            compared=True,
            publisher="test",
        ),
        topics.Topic(
            "dummy/off", DrapeMsg, topics.PLAIN, recorded=False, replayed=False, compared=False, publisher="test"
        ),
    )
    monkeypatch.setattr(topics, "TOPICS", topics.TOPICS + extra)
    return extra


def test_bus_delivery_follows_the_table(dummy_topics):
    opts, history = publisher_options("dummy/in")
    assert opts["express"] and opts["congestion_control"] == zenoh.CongestionControl.DROP and history == 0
    opts, history = publisher_options("dummy/out/x")
    assert not opts["express"] and opts["congestion_control"] == zenoh.CongestionControl.BLOCK and history == 3
    assert topics.history_for_subscription("dummy/**") == 3
    assert topics.type_for_keyexpr("dummy/out/*") is DrapeMsg
    # what the running nodes rely on today
    assert publisher_options("drape/predicted")[0]["congestion_control"] == zenoh.CongestionControl.DROP
    assert publisher_options("pattern")[1] == 8 and publisher_options("mesh/fine")[1] == 1
    assert publisher_options("edit")[0]["express"] and publisher_options("status/ui")[1] == 0
    # Ψ waits for a node restarted mid-drag, and goes out at once
    assert publisher_options("psi/fine")[1] == 1 and publisher_options("psi/fine")[0]["express"]


def test_every_row_records_checks_and_reads_back_its_type(tmp_path):
    """Each row of the table, with a message of its type built from the schema
    alone (a new type needs no edit here): the recorder's check passes it on its
    key, refuses it on a key of another type, and it reads back as written."""
    path = tmp_path / "all.mcap"
    rows = {t.key.replace("*", "x"): t for t in topics.TOPICS}
    sent = {key: encode(minimal(t.msg_type)) for key, t in rows.items()}
    with contextlib.closing(SessionWriter(str(path))) as w:
        for i, (key, data) in enumerate(sent.items()):
            assert check_payload(key, data) == "", key
            other = next(k for k, t in rows.items() if t.msg_type is not rows[key].msg_type)
            assert "expected" in check_payload(other, data), (key, other)
            w.write(f"couture/s1/{key}", data, i + 1)
    back = {r.topic: r for r in read_session(str(path))}
    assert set(back) == set(sent)
    for key, r in back.items():
        assert r.data == sent[key] and r.schema == rows[key].msg_type.TYPE


def test_recorder_replay_compare_follow_the_table(dummy_topics):
    assert records("couture/s1/dummy/in") and records("couture/s1/dummy/out/newton")
    assert not records("couture/s1/dummy/off") and not records("couture/s1/bench/done")
    assert records("couture/s1/drape/fine") and records("couture/s1/status/ui")
    assert ReplayConfig(path="x.mcap").topics == ["pattern", "edit", "tryon", "dummy/in"]
    assert "dummy/out/*" in topics.compared_topics()


def test_compare_defaults_to_the_tables_outputs(dummy_topics, tmp_path):
    golden, actual = tmp_path / "golden.mcap", tmp_path / "actual.mcap"
    msg = DrapeMsg(level="fine", x=np.zeros((2, 3)), generation=1)
    with contextlib.closing(SessionWriter(str(golden))) as w:
        w.write("couture/s1/dummy/out/a", encode(msg), 1)
        w.write("couture/s1/dummy/in", encode(msg), 2)
    SessionWriter(str(actual)).close()
    rep = compare(str(golden), str(actual))
    assert set(rep.topics) == {"dummy/out/a"} and rep.topics["dummy/out/a"].missing


def test_cli_defaults_name_the_tables_topics(dummy_topics):
    from couture.cli import _parser

    for cmd, want in (("replay", "dummy/in"), ("compare", "dummy/out/*")):
        out = io.StringIO()
        with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
            _parser().parse_args([cmd, "--help"])
        assert want in out.getvalue()
    assert _parser().parse_args(["replay", "x.mcap"]).topics is None  # ReplayConfig's default then applies


def test_readme_topic_table_is_the_tables_rendering():
    readme = (ROOT / "README.md").read_text()
    assert topics.markdown_table() in readme, "README topic table is stale: paste schemas.topics.markdown_table()"
