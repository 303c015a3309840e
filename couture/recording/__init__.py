"""Record, recover, replay and compare couture sessions (MCAP, msgpack payloads).

record:  couture.recording.recorder.main(RecordConfig(out=..., bus=...))
read:    for m in read_session(path, ["drape/*"]): decode(m.data)
recover: recover(src, dst) -> messages kept
replay:  couture.recording.replay.main(ReplayConfig(path=..., bus=...))
compare: compare(golden, actual, rtol=..., atol=...) -> CompareReport
"""

from couture.recording.compare import CompareReport, TopicReport, compare
from couture.recording.mcapio import Recorded, SessionWriter, read_session, recover, split_key, topic_matches

__all__ = [
    "CompareReport",
    "TopicReport",
    "compare",
    "Recorded",
    "SessionWriter",
    "read_session",
    "recover",
    "split_key",
    "topic_matches",
]
