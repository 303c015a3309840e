"""Loopback port helpers."""

from __future__ import annotations

import socket


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` right now (bind to 0, read, release)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def endpoint(port: int, host: str = "127.0.0.1") -> str:
    return f"tcp/{host}:{port}"


def port_is_free(port: int, host: str = "127.0.0.1") -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return False
        return True


def free_port_block(start: int, count: int = 3, host: str = "127.0.0.1", tries: int = 100) -> int:
    """The first port p = start + k·count (k = 0, 1, ...) with p .. p + count - 1
    all free on ``host`` right now (the UI's page, 3D view and pattern view);
    any free port after ``tries`` blocks."""
    for k in range(tries):
        p = start + k * count
        if p + count - 1 > 65535:
            break
        if all(port_is_free(p + i, host) for i in range(count)):
            return p
    return free_port(host)
