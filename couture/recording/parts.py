"""Numbered recording files: a recording is never opened for writing over an
existing file.

A recorder asked for ``session.mcap`` writes that file when it does not
exist; otherwise it writes the next numbered part ``session.<n>.mcap``
(n = 1 + the highest number present, created exclusively, so two recorders
never share a file). Every file a recorder writes starts with a ``couture``
metadata record that names its recording (``run_id``) and its ``part``
number. A recorder that ``couture up`` restarts keeps the run id, so its
parts continue one recording; a new ``couture record session.mcap`` beside
an old one starts a new recording (a new run id) in the next number.

The *set* of a file (:func:`expand`): the file and the numbered files after
it in its family (``<stem>.<n>.mcap``, n above its own part number) that
carry the same run id, in part order, which is the order they were started
in. ``couture replay session.mcap`` and ``couture compare`` read the set;
a file without the record (written by something else) is a set of one.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Iterable, Union

from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

INFO_NAME = "couture"
"""name of the metadata record at the start of every file a recorder writes"""

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class PartInfo:
    """What the ``couture`` metadata record at the start of a file says."""

    run_id: str
    """the recording this file belongs to ('' for files written before parts existed)"""
    part: int
    """0 for the file named as asked, n for ``<stem>.<n>.mcap``"""
    session: str


def _stem_suffix(name: str) -> tuple[str, str]:
    suffix = Path(name).suffix
    return (name[: -len(suffix)] if suffix else name), suffix


def part_path(base: PathLike, n: int) -> Path:
    """``session.mcap`` and 2 -> ``session.2.mcap``; n = 0 is the base itself."""
    b = Path(base)
    if n == 0:
        return b
    stem, suffix = _stem_suffix(b.name)
    return b.with_name(f"{stem}.{n}{suffix}")


def numbered(base: PathLike) -> dict[int, Path]:
    """The numbered files of ``base``'s family that exist now: n -> path."""
    b = Path(base)
    stem, suffix = _stem_suffix(b.name)
    pat = re.compile(re.escape(stem) + r"\.([1-9][0-9]*)" + re.escape(suffix))
    folder = b.parent
    try:
        names = os.listdir(folder)
    except FileNotFoundError:
        return {}
    out = {}
    for name in names:
        m = pat.fullmatch(name)
        if m:
            out[int(m.group(1))] = folder / name
    return out


def create_part(out: PathLike) -> tuple[BinaryIO, Path, int]:
    """Open a new file for a recording asked to go to ``out``: ``out`` itself
    when it does not exist, else the next numbered part. Never opens an
    existing file. Returns (file, path, part number)."""
    base = Path(out)
    try:
        return open(base, "xb"), base, 0
    except FileExistsError:
        pass
    while True:
        n = max(numbered(base), default=0) + 1
        path = part_path(base, n)
        try:
            return open(path, "xb"), path, n
        except FileExistsError:  # another recorder took this number first
            continue


def read_info(path: PathLike) -> PartInfo | None:
    """The ``couture`` record at the start of a recording, None when the file
    has none (another writer, or a recorder killed before its first flush).
    Reads only the first few records."""
    with open(path, "rb") as f:
        reader = StreamReader(f, record_size_limit=1 << 31)
        try:
            for i, rec in enumerate(reader.records):
                if isinstance(rec, Metadata) and rec.name == INFO_NAME:
                    md = rec.metadata
                    try:
                        part = int(md.get("part", "0"))
                    except ValueError:
                        part = 0
                    return PartInfo(run_id=md.get("run_id", ""), part=part, session=md.get("session", ""))
                if isinstance(rec, (Message, Channel, Schema)) or i > 16:
                    return None
        except Exception:  # empty or cut short before the record
            return None
    return None


def expand(path: PathLike) -> list[Path]:
    """The set of a recording file (module doc): the file, then its numbered
    continuations with the same run id, in part order."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such recording")
    info = read_info(p)
    if info is None or not info.run_id:
        return [p]
    base = p
    if info.part > 0:
        stem, suffix = _stem_suffix(p.name)
        m = re.fullmatch(r"(.*)\.([1-9][0-9]*)", stem)
        if m is None or int(m.group(2)) != info.part:
            return [p]  # renamed: its family is unknown
        base = p.with_name(m.group(1) + suffix)
    out = [p]
    for n, q in sorted(numbered(base).items()):
        if n > info.part:
            qi = read_info(q)
            if qi is not None and qi.run_id == info.run_id:
                out.append(q)
    return out


def first_of_run(base: PathLike, run_id: str, *, before: int) -> Path | None:
    """The lowest-numbered file of ``base``'s family below part ``before``
    that belongs to recording ``run_id``, None when none does."""
    candidates = {0: Path(base), **numbered(base)}
    for n in sorted(candidates):
        if n >= before:
            break
        p = candidates[n]
        if p.exists():
            info = read_info(p)
            if info is not None and info.run_id == run_id:
                return p
    return None


def resolve(paths: PathLike | Iterable[PathLike], *, parts: bool = True) -> list[Path]:
    """Files to read for one or several paths: each expanded to its set
    (``parts``) or taken as is, duplicates dropped, order kept."""
    items = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    if not items:
        raise ValueError("no recording given")
    out: list[Path] = []
    seen: set[Path] = set()
    for item in items:
        for p in expand(item) if parts else [Path(item)]:
            key = p.resolve()
            if key not in seen:
                seen.add(key)
                out.append(p)
    return out


def describe(files: list[Path]) -> str:
    """'a.mcap' or 'a.mcap (+ a.1.mcap, a.2.mcap)' for messages and reports."""
    if len(files) == 1:
        return str(files[0])
    return f"{files[0]} (+ {', '.join(f.name for f in files[1:])})"
