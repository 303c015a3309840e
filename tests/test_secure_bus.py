"""Secured sessions (couture.bus.secure, ``couture certs``, ``--tls DIR``)
over real Zenoh TLS links on loopback: a client without a certificate of
the session's CA cannot join; a node that the policy does not list as a
writer cannot change the design (the real remesher, started by the
supervisor, never meshes its pattern) and an unlisted solver cannot answer a
solve query, while listed ones can."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
import zenoh

from couture.bus import BusConfig, free_port, open_session
from couture.bus.secure import ROUTER_NAME, SecureError, make_certs, tls_config
from couture.client import Client
from schemas import EditMsg, PatternMsg, SolveRequestMsg, SolveResultMsg, StatusMsg
from schemas.messages import decode, encode

pytestmark = pytest.mark.timeout(90)

SKIRT = Path(__file__).resolve().parents[1] / "couture" / "pattern" / "examples" / "default_skirt.json"


class Collector:
    def __init__(self) -> None:
        self.items: list = []
        self.cond = threading.Condition()

    def __call__(self, *args) -> None:
        with self.cond:
            self.items.append(args[0] if len(args) == 1 else args)
            self.cond.notify_all()

    def wait(self, pred, timeout: float = 20.0):
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                hits = [i for i in self.items if pred(i)]
                if hits:
                    return hits[-1]
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"nothing matched; got {self.items[-5:]}")
                self.cond.wait(left)

    def matching(self, pred) -> list:
        with self.cond:
            return [i for i in self.items if pred(i)]


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> Path:
    """One CA: designer may publish designs, solver-trusted may answer solves;
    intruder and solver-rogue hold valid certificates of the same CA but are
    not listed."""
    d = tmp_path_factory.mktemp("secure")
    make_certs(
        d,
        ["remesher", "observer", "designer", "intruder", "solver-trusted", "solver-rogue"],
        writers=["designer"],
        solvers=["solver-trusted"],
    )
    return d


def secured(session: str, certs: Path, port: int, **kw) -> BusConfig:
    return BusConfig(session=session, connect=[f"tls/127.0.0.1:{port}"], tls=str(certs), **kw)


def router(session: str, certs: Path, port: int):
    return open_session(
        BusConfig(session=session, listen=[f"tls/127.0.0.1:{port}"], mode="router", tls=str(certs), tls_name="router"),
        name="supervisor",
    )


def test_certs_files_policy_and_clear_errors(certs, tmp_path):
    for name in (ROUTER_NAME, "remesher", "designer", "solver-rogue"):
        assert stat.S_IMODE(os.stat(certs / f"{name}.key").st_mode) == 0o600
        assert (certs / f"{name}.pem").read_bytes().startswith(b"-----BEGIN CERTIFICATE-----")
    assert stat.S_IMODE(os.stat(certs / "ca.key").st_mode) == 0o600
    assert json.loads((certs / "policy.json").read_text()) == {"writers": ["designer"], "solvers": ["solver-trusted"]}
    # the certificates chain to the CA, carry the node's name and are valid for loopback
    from cryptography import x509

    cert = x509.load_pem_x509_certificate((certs / "solver-trusted.pem").read_bytes())
    ca = x509.load_pem_x509_certificate((certs / "ca.pem").read_bytes())
    cert.verify_directly_issued_by(ca)
    assert cert.subject.rfc4514_string() == "CN=solver-trusted"
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert [str(ip) for ip in san.get_values_for_type(x509.IPAddress)] == ["127.0.0.1"]
    assert san.get_values_for_type(x509.DNSName) == ["localhost"]

    # a node without a certificate, or a tcp endpoint in a secured session, is a clear error before any link
    with pytest.raises(SecureError, match="no certificate for node 'stranger'.*couture certs"):
        tls_config(certs, "stranger")
    with pytest.raises(SecureError, match="endpoints must be tls/"):
        BusConfig(connect=["tcp/127.0.0.1:7447"], tls=str(certs)).zenoh_config("designer")

    # `couture certs` adds to an existing directory: same CA, the policy grows
    r = subprocess.run(
        [sys.executable, "-m", "couture", "certs", "--out", str(tmp_path), "--nodes", "remesher", "ui"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    ca_before = (tmp_path / "ca.pem").read_bytes()
    r = subprocess.run(
        [sys.executable, "-m", "couture", "certs", "--out", str(tmp_path), "--nodes", "bot", "--solvers", "bot"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "ca.pem").read_bytes() == ca_before
    assert json.loads((tmp_path / "policy.json").read_text()) == {"writers": ["ui"], "solvers": ["bot"]}

    # `couture drape` as a node the policy does not let publish: a clear error, not a timeout
    r = subprocess.run(
        [sys.executable, "-m", "couture", "drape", str(SKIRT), "--out", str(tmp_path / "out"), "--tls", str(certs)]
        + ["--name", "intruder", "--connect", "tls/127.0.0.1:1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "'intruder' may not publish patterns" in r.stderr, r.stderr


def test_client_without_a_valid_certificate_cannot_connect(certs, tmp_path):
    other = tmp_path / "other-ca"
    make_certs(other, ["designer"], writers=["designer"], solvers=[])  # same name, another CA
    session, port = f"s{uuid.uuid4().hex[:8]}", free_port()
    endpoint = f"tls/127.0.0.1:{port}"

    def raw(mode: str, connect: str, tls: dict | None) -> zenoh.Config:
        c = zenoh.Config()
        c.insert_json5("mode", json.dumps(mode))
        c.insert_json5("connect/endpoints", json.dumps([connect]))
        c.insert_json5("scouting/multicast/enabled", "false")
        if tls is not None:
            c.insert_json5("transport/link/tls", json.dumps(tls))
        return c

    no_cert = {"root_ca_certificate": str(certs / "ca.pem")}  # trusts the session, shows no certificate
    other_ca = dict(tls_config(other, "designer"), root_ca_certificate=str(certs / "ca.pem"))
    with router(session, certs, port):
        # a client-mode session that reaches no router fails to open
        for what, conf in {
            "no certificate": raw("client", endpoint, no_cert),
            "certificate of another CA": raw("client", endpoint, other_ca),
            "plain TCP": raw("client", f"tcp/127.0.0.1:{port}", None),
        }.items():
            print(f"joining with {what}")
            with pytest.raises(zenoh.ZError, match="Unable to connect"):
                zenoh.open(conf).close()  # a client with ``what`` joined the secured session

        # a peer (which opens even when its endpoint refuses it) stays alone and receives nothing
        outsider = zenoh.open(raw("peer", endpoint, other_ca))
        try:
            seen_outside = Collector()
            sub = outsider.declare_subscriber(f"couture/{session}/**", lambda s: seen_outside(str(s.key_expr)))
            with (
                open_session(secured(session, certs, port), name="observer") as observer,
                open_session(secured(session, certs, port), name="designer") as designer,
            ):
                seen = Collector()
                observer.subscribe("status/*", seen, StatusMsg)
                pub = designer.publisher("status/designer", StatusMsg)
                assert pub.wait_matching(10)
                pub.put(StatusMsg(node="designer"))
                seen.wait(lambda m: m.node == "designer")  # delivered inside the session
                pub.put(StatusMsg(node="designer"))
                seen.wait(lambda m: m.seq == 2)
            assert seen_outside.items == []
            assert list(outsider.info.routers_zid()) == [] and list(outsider.info.peers_zid()) == []
            sub.undeclare()
        finally:
            outsider.close()


def test_unlisted_node_cannot_change_the_design(certs):
    """The real remesher (started by the supervisor, secured) meshes the
    designer's patterns and never the intruder's, sent first; a node that
    joins late is not given the intruder's pattern from its history cache,
    and the intruder's edits reach nobody."""
    from couture import supervisor

    session = f"s{uuid.uuid4().hex[:8]}"
    nodes = [n for n in supervisor.default_nodes(ui=False) if n.name == "remesher"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tls/127.0.0.1:{free_port()}"], tls=str(certs)), nodes=nodes
    )
    with (
        supervisor.Supervisor(cfg) as sup,
        Client(bus=sup.child_bus, name="designer") as designer,
        Client(bus=sup.child_bus, name="intruder") as intruder,
    ):
        assert sup.endpoint.startswith("tls/") and sup.child_bus.tls == str(certs)
        designer.wait_nodes(["remesher"], timeout=60)
        edits = Collector()
        meshes = Collector()
        with open_session(sup.child_bus, name="observer") as observer:
            observer.subscribe("edit", edits, EditMsg)
            observer.subscribe("mesh/coarse", meshes)
            time.sleep(0.5)  # the observer's subscriptions reach the publishers
            bad = intruder.publish_pattern(SKIRT, name="intruder")
            bad_id = intruder.design_id_of(bad)
            intruder.send_edit(element="waist", d=(0.01, 0.0), phase="drag")
            designer.send_edit(element="hem", d=(0.0, 0.01), phase="drag")
            good = designer.publish_pattern(SKIRT, name="designer")
            good_id = designer.design_id_of(good)
            meshes.wait(lambda m: m.design_id == good_id, timeout=60)
            edits.wait(lambda m: m.element == "hem")
            # and once more, so the intruder's messages sent before have had every chance
            again = designer.design_id_of(designer.publish_pattern(SKIRT, name="designer-again"))
            meshes.wait(lambda m: m.design_id == again, timeout=60)
            assert meshes.matching(lambda m: m.design_id == bad_id) == []
            assert edits.matching(lambda m: m.element == "waist") == []
            # a late joiner fetches the patterns' history: the designer's, not the intruder's
            patterns = Collector()
            with open_session(sup.child_bus, name="observer") as late:
                late.subscribe("pattern", patterns, PatternMsg)
                patterns.wait(lambda m: m.design_id == again)
                patterns.wait(lambda m: m.design_id == good_id)
                # ask every history cache once more, to the end of the query: the
                # intruder's cache holds its pattern, its reply is dropped on receipt
                replies = late.zenoh.get(
                    late.key("pattern/@adv/**") + "?_anyke",
                    target=zenoh.QueryTarget.ALL,
                    consolidation=zenoh.ConsolidationMode.NONE,
                    timeout=10,
                )
                cached = [decode(r.ok.payload.to_bytes(), PatternMsg).design_id for r in replies if r.ok is not None]
            assert good_id in cached and again in cached and bad_id not in cached
            assert patterns.matching(lambda m: m.design_id == bad_id) == []
        with pytest.raises(TimeoutError):  # nobody numbered the intruder's design
            intruder.generation_of(bad, timeout=0)


def test_unlisted_solver_cannot_answer(certs):
    session, port = f"s{uuid.uuid4().hex[:8]}", free_port()
    calls: dict[str, int] = {"trusted": 0, "rogue": 0}

    def handler(who: str):
        def solve(req: SolveRequestMsg) -> SolveResultMsg:
            calls[who] += 1
            return SolveResultMsg(x=np.zeros((1, 3)), method=f"{who}-method", converged=True, residual=0.0)

        return solve

    with (
        router(session, certs, port),
        open_session(secured(session, certs, port), name="solver-trusted") as trusted,
        open_session(secured(session, certs, port), name="solver-rogue") as rogue,
        open_session(secured(session, certs, port), name="designer") as client,
        open_session(secured(session, certs, port), name="observer") as observer,
    ):
        results = Collector()
        observer.subscribe("solve/result/*", results, with_topic=True)
        trusted.serve_solve("newton", handler("trusted"))
        rogue.serve_solve("newton", handler("rogue"))  # the same name: an impostor
        rogue.serve_solve("rogue", handler("rogue"))
        fake = rogue.publisher("solve/result/newton", SolveResultMsg)
        time.sleep(0.5)
        for _ in range(3):  # whichever it would pick, only the listed solver answers
            res = client.solve(SolveRequestMsg(), solver="newton", timeout=20)
            assert res.method == "trusted-method"
        assert client.solve(SolveRequestMsg(), timeout=20).method == "trusted-method"  # any solver
        with pytest.raises(TimeoutError, match="no solver answered on .*solve/rogue"):
            client.solve(SolveRequestMsg(), solver="rogue", timeout=2.0)
        fake.put(SolveResultMsg(method="forged", solver="newton"))
        results.wait(lambda t: t[1].method == "trusted-method")
        res = client.solve(SolveRequestMsg(), solver="newton", timeout=20)  # after the forged mirror was sent
        results.wait(lambda t: t[1].request_id == res.request_id)
        assert results.matching(lambda t: t[1].method in ("rogue-method", "forged")) == []
        # the rogue's queryables were never declared to the others, so no query reached it
        assert calls == {"trusted": 5, "rogue": 0}

        # a queryable on a wider key is declared (the rule covers solve/* only) and
        # is asked, but its answer is dropped where it arrives
        def answer_anything(query: zenoh.Query) -> None:
            calls["rogue"] += 1
            query.reply(query.key_expr, encode(SolveResultMsg(method="rogue-method")))

        wide = rogue.zenoh.declare_queryable(rogue.key("**"), answer_anything)
        try:
            time.sleep(0.5)
            with pytest.raises(TimeoutError, match="no solver answered on .*solve/ghost"):
                client.solve(SolveRequestMsg(), solver="ghost", timeout=2.0)
            assert calls["rogue"] >= 1
        finally:
            wide.undeclare()
