"""Secured sessions: TLS with client certificates (mTLS) and access control,
all through Zenoh's own configuration.

A *secure directory* (made by ``couture certs``) holds

- ``ca.pem`` / ``ca.key``: a development certificate authority;
- ``<name>.pem`` / ``<name>.key``: one certificate and key per node, signed by
  that CA, common name = the node's name (``remesher``, ``solver-newton``,
  ``ui``, ``router`` for the supervisor, a client's ``--name``), valid for the
  hosts given (127.0.0.1 and localhost by default) for both serving and
  connecting;
- ``policy.json``: which common names may change the design (put on
  ``pattern`` and ``edit``) and which may answer ``solve`` queries.

Keys are written with mode 0600. A node joins a secured session with
``--tls DIR`` (its certificate is ``DIR/<its name>.pem``): it then speaks TLS
only (``transport/link/protocols: ["tls"]``: a ``tcp/`` endpoint is refused),
requires a certificate from the CA of every peer (``enable_mtls``), and
applies the policy to what it receives (``access_control``, ingress):

- ``put``/``delete``/``reply`` on ``couture/*/pattern`` and ``couture/*/edit``
  (and their sub-keys) from writers only;
- ``declare_queryable`` and ``reply`` on ``couture/*/solve/*`` and ``put`` on
  the mirror ``couture/*/solve/result/*`` from solvers only;
- everything else from any node of the CA.

Zenoh matches a rule when the message's key expression is *included* in one
of the rule's (Zenoh's access control RFC): a queryable declared on a wider
key (``couture/<s>/**``) is not caught by the ``declare_queryable`` rule and
is asked, but its replies, on ``solve/<name>`` keys, are dropped where they
arrive (tests/test_secure_bus.py shows both).

Every node applies the same rules to its own links, so a message is checked
by whoever receives it first from its sender: the router (whose forwarding
the others trust: ``router`` is a writer and a solver) or a peer connected
directly by gossip. Zenoh decides per remote subject: a deny rule of a subject
the sender matches denies unless another subject it matches allows (see
``acl_config``).

Not covered: the UI's web page (HTTP on its own port), and the other topics
(meshes, drapes, status, liveliness), which any node of the CA may publish.
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
POLICY_FILE = "policy.json"
ROUTER_NAME = "router"
"""common name of the supervisor's router session"""

DEFAULT_HOSTS = ("127.0.0.1", "localhost")
"""names every node certificate is valid for (subject alternative names)"""

STANDARD_NODES = (
    ROUTER_NAME,
    "remesher",
    "solver-kinetic",
    "solver-newton",
    "solver-verlet",
    "sensitivity",
    "adjust",
    "ui",
    "recorder",
)
"""what ``couture up`` may start: the default node set of ``couture certs``"""

DEFAULT_WRITERS = ("ui", "sensitivity", "adjust")
"""nodes that publish designs in a standard ``couture up`` (the UI; the 3D tug; adjusted patterns)"""

PATTERN_KEYS = [
    f"couture/*/{t}{suffix}" for t in ("pattern", "edit", "tryon", "adjust") for suffix in ("", "/**", "/@adv/**")
]
"""what only writers may put, and reply with: a zenoh-ext history cache
answers a late joiner with the sample's own key (``couture/<s>/pattern``),
so denying ``reply`` there keeps an unlisted node's cached design from late
joiners. The sub-keys are closed too (``**`` does not match the verbatim
``@adv`` chunk, hence its own entry)."""
SOLVE_KEYS = ["couture/*/solve/*"]
"""the solve queryables: only solvers may declare one or reply"""
SOLVE_RESULT_KEYS = ["couture/*/solve/result/*"]
"""the solve results' mirror: only solvers may put there"""


class SecureError(ValueError):
    """A secure directory that is missing, incomplete or inconsistent."""


@dataclass
class Policy:
    """Who may do what (common names)."""

    writers: list[str] = field(default_factory=list)
    """may put on pattern, edit, tryon and adjust"""
    solvers: list[str] = field(default_factory=list)
    """may answer solve queries (and publish their results)"""

    def to_json(self) -> str:
        return json.dumps({"writers": sorted(self.writers), "solvers": sorted(self.solvers)}, indent=2) + "\n"

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Policy":
        try:
            raw = json.loads(Path(path).read_text())
        except FileNotFoundError:
            raise SecureError(f"{path}: no policy file (make one with `couture certs --out DIR`)") from None
        except json.JSONDecodeError as e:
            raise SecureError(f"{path}: not JSON: {e}") from None
        if not isinstance(raw, dict):
            raise SecureError(f"{path}: expected an object with 'writers' and 'solvers'")
        out = {}
        for k in ("writers", "solvers"):
            v = raw.get(k, [])
            if not isinstance(v, list) or not all(isinstance(n, str) and n.strip() for n in v):
                raise SecureError(f"{path}: {k!r} must be a list of node names, got {v!r}")
            out[k] = list(v)
        unknown = set(raw) - {"writers", "solvers"}
        if unknown:
            raise SecureError(f"{path}: unknown keys {sorted(unknown)} (expected 'writers' and 'solvers')")
        return cls(**out)


# -- certificates (development CA) -------------------------------------------


def _write_private(path: Path, data: bytes) -> None:
    """Write a key readable by its owner only (0600 from the start, not chmod after)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.chmod(path, 0o600)  # an existing file keeps its old mode through O_CREAT


def _check_name(name: str) -> None:
    if not name or "/" in name or name.startswith(".") or name in ("ca",) or not name.isprintable():
        raise SecureError(f"invalid node name {name!r} for a certificate (no '/', not 'ca', not hidden)")


def make_certs(
    out: str | os.PathLike,
    nodes: list[str],
    *,
    writers: list[str] | None = None,
    solvers: list[str] | None = None,
    hosts: list[str] | None = None,
    days: int = 365,
) -> list[Path]:
    """Make (or reuse) a development CA in ``out`` and one key and certificate
    per node (also for every name in ``writers``/``solvers``, and ``router``);
    add the writers and solvers to ``out/policy.json`` (``writers`` defaults to
    the nodes among DEFAULT_WRITERS, ``solvers`` to the nodes named solver-*).
    An existing CA is kept, so certificates issued before stay valid. Returns
    the files written."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    if writers is None:
        writers = [n for n in nodes if n in DEFAULT_WRITERS]
    if solvers is None:
        solvers = [n for n in nodes if n.startswith("solver-")]
    names = list(dict.fromkeys([ROUTER_NAME, *nodes, *writers, *solvers]))
    for n in names:
        _check_name(n)
    hosts = list(hosts or DEFAULT_HOSTS)
    sans: list[x509.GeneralName] = []
    for h in hosts:
        try:
            sans.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            sans.append(x509.DNSName(h))
    now = datetime.datetime.now(datetime.timezone.utc)
    not_before = now - datetime.timedelta(minutes=5)
    not_after = now + datetime.timedelta(days=days)
    written: list[Path] = []

    ca_cert_path, ca_key_path = out_dir / CA_CERT, out_dir / CA_KEY
    if ca_cert_path.exists() and ca_key_path.exists():
        ca_cert = x509.load_pem_x509_certificate(ca_cert_path.read_bytes())
        loaded = serialization.load_pem_private_key(ca_key_path.read_bytes(), password=None)
        if not isinstance(loaded, ec.EllipticCurvePrivateKey):
            raise SecureError(f"{ca_key_path}: not an EC private key")
        ca_key = loaded
    else:
        ca_key = ec.generate_private_key(ec.SECP256R1())
        ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "couture development CA")])
        ca_cert = (
            x509.CertificateBuilder()
            .subject_name(ca_name)
            .issuer_name(ca_name)
            .public_key(ca_key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(not_before)
            .not_valid_after(now + datetime.timedelta(days=max(days, 3650)))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(
                x509.KeyUsage(
                    digital_signature=False,
                    content_commitment=False,
                    key_encipherment=False,
                    data_encipherment=False,
                    key_agreement=False,
                    key_cert_sign=True,
                    crl_sign=True,
                    encipher_only=False,
                    decipher_only=False,
                ),
                critical=True,
            )
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()), critical=False)
            .sign(ca_key, hashes.SHA256())
        )
        _write_private(
            ca_key_path,
            ca_key.private_bytes(
                serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
            ),
        )
        ca_cert_path.write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
        written += [ca_cert_path, ca_key_path]

    for name in names:
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (
            x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
            .issuer_name(ca_cert.subject)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(not_before)
            .not_valid_after(not_after)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.SubjectAlternativeName(sans), critical=False)
            .add_extension(
                x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]),
                critical=False,
            )
            .add_extension(
                x509.KeyUsage(
                    digital_signature=True,
                    content_commitment=False,
                    key_encipherment=False,
                    data_encipherment=False,
                    key_agreement=False,
                    key_cert_sign=False,
                    crl_sign=False,
                    encipher_only=False,
                    decipher_only=False,
                ),
                critical=True,
            )
            .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False)
            .sign(ca_key, hashes.SHA256())
        )
        key_path, cert_path = out_dir / f"{name}.key", out_dir / f"{name}.pem"
        _write_private(
            key_path,
            key.private_bytes(
                serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
            ),
        )
        cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        written += [cert_path, key_path]

    policy_path = out_dir / POLICY_FILE
    old = Policy.load(policy_path) if policy_path.exists() else Policy()
    policy = Policy(
        writers=list(dict.fromkeys([*old.writers, *writers])),
        solvers=list(dict.fromkeys([*old.solvers, *solvers])),
    )
    policy_path.write_text(policy.to_json())
    written.append(policy_path)
    return written


# -- Zenoh configuration -----------------------------------------------------


def node_files(tls_dir: str | os.PathLike, name: str) -> tuple[Path, Path, Path]:
    """(CA certificate, node certificate, node key) of ``name`` in ``tls_dir``;
    SecureError naming what is missing."""
    d = Path(tls_dir)
    if not name:
        raise SecureError("a secured session needs a node name to pick its certificate (--name)")
    _check_name(name)
    files = (d / CA_CERT, d / f"{name}.pem", d / f"{name}.key")
    missing = [str(p) for p in files if not p.is_file()]
    if missing:
        raise SecureError(
            f"no certificate for node {name!r} in {d}: missing {', '.join(missing)} "
            f"(add it with `couture certs --out {d} --nodes {name}`)"
        )
    return files


def tls_config(tls_dir: str | os.PathLike, name: str) -> dict[str, Any]:
    """``transport/link/tls``: this node's certificate both ways, the CA's, mTLS on."""
    ca, cert, key = (str(p.resolve()) for p in node_files(tls_dir, name))
    return {
        "root_ca_certificate": ca,
        "listen_private_key": key,
        "listen_certificate": cert,
        "enable_mtls": True,
        "connect_private_key": key,
        "connect_certificate": cert,
        "verify_name_on_connect": True,
    }


def acl_config(policy: Policy) -> dict[str, Any]:
    """``access_control`` for ``policy``, applied to what a node receives.

    Zenoh 1.x evaluates each subject a remote matches on its own (a deny rule
    of that subject denies; otherwise the default permission, here allow) and
    allows a message when any subject allows it. So the restricted messages
    are denied for the subject every node matches (``anyone``), and each
    privileged subject denies the *other* privilege, since it would otherwise
    grant everything through the default."""
    writers = sorted({*policy.writers, ROUTER_NAME})
    solvers = sorted({*policy.solvers, ROUTER_NAME})
    pattern_rule = dict(messages=["put", "delete", "reply"], flows=["ingress"], key_exprs=PATTERN_KEYS)
    solve_rules = [
        dict(messages=["declare_queryable", "reply"], flows=["ingress"], key_exprs=SOLVE_KEYS),
        dict(messages=["put", "delete"], flows=["ingress"], key_exprs=SOLVE_RESULT_KEYS),
    ]
    rules = [
        {"id": "deny-design", "permission": "deny", **pattern_rule},
        {"id": "allow-design", "permission": "allow", **pattern_rule},
        {"id": "deny-solve", "permission": "deny", **solve_rules[0]},
        {"id": "deny-solve-result", "permission": "deny", **solve_rules[1]},
        {"id": "allow-solve", "permission": "allow", **solve_rules[0]},
        {"id": "allow-solve-result", "permission": "allow", **solve_rules[1]},
    ]
    return {
        "enabled": True,
        "default_permission": "allow",
        "rules": rules,
        "subjects": [
            {"id": "anyone"},
            {"id": "writers", "cert_common_names": writers},
            {"id": "solvers", "cert_common_names": solvers},
        ],
        "policies": [
            {"id": "restricted", "rules": ["deny-design", "deny-solve", "deny-solve-result"], "subjects": ["anyone"]},
            {
                "id": "writers",
                "rules": ["allow-design", "deny-solve", "deny-solve-result"],
                "subjects": ["writers"],
            },
            {"id": "solvers", "rules": ["allow-solve", "allow-solve-result", "deny-design"], "subjects": ["solvers"]},
        ],
    }


def check_endpoints(endpoints: list[str], what: str) -> None:
    """A secured session speaks TLS only: a tcp/udp/... endpoint is an error."""
    bad = [e for e in endpoints if not e.startswith("tls/")]
    if bad:
        raise SecureError(f"--tls: {what} endpoints must be tls/HOST:PORT, got {', '.join(bad)}")


def apply(conf: Any, tls_dir: str | os.PathLike, name: str) -> None:
    """Set TLS (mTLS, TLS only) and the access control of ``tls_dir`` on a
    ``zenoh.Config`` for node ``name``."""
    policy = Policy.load(Path(tls_dir) / POLICY_FILE)
    conf.insert_json5("transport/link/protocols", json.dumps(["tls"]))
    conf.insert_json5("transport/link/tls", json.dumps(tls_config(tls_dir, name)))
    conf.insert_json5("access_control", json.dumps(acl_config(policy)))
