"""Record, recover, replay and compare couture sessions (MCAP, msgpack payloads).

record:  couture.recording.recorder.main(RecordConfig(out=..., bus=...))
         (never over an existing file: the next numbered part, couture.recording.parts)
read:    for m in read_session(path, ["drape/*"]): decode(m.data)
         (path's numbered parts too; rejected payloads only with which="rejected"/"all")
recover: recover(src, dst) -> messages kept (a cut-short file or a set of parts into one)
replay:  couture.recording.replay.main(ReplayConfig(path=..., bus=...))
compare: compare(golden, actual, rtol=..., atol=...) -> CompareReport
"""

from couture.recording.compare import CompareReport, TopicReport, compare
from couture.recording.mcapio import (
    Recorded,
    SessionWriter,
    check_payload,
    read_session,
    recover,
    split_key,
    topic_matches,
)
from couture.recording.parts import expand, resolve

__all__ = [
    "CompareReport",
    "TopicReport",
    "compare",
    "Recorded",
    "SessionWriter",
    "check_payload",
    "expand",
    "resolve",
    "read_session",
    "recover",
    "split_key",
    "topic_matches",
]
