"""Every recordings/<case>.mcap replays into fresh nodes (real processes) and
their outputs match the golden ones within the case's tolerances: a design
session as a regression test (DESIGN §3)."""

from __future__ import annotations

import pytest

from couture.recording.golden import RECORDINGS, check, load_case

CASES = sorted(p.stem for p in RECORDINGS.glob("*.json"))


def test_there_are_golden_cases():
    assert CASES, "recordings/ holds no golden case"
    for name in CASES:
        assert load_case(name).mcap.exists(), f"{name}: golden .mcap missing (couture golden make {name})"


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("name", CASES)
def test_golden_replay_matches(name, tmp_path):
    report = check(load_case(name), actual=tmp_path / f"{name}.mcap")
    assert report.ok, report.text()
    for topic in ("mesh/coarse", "mesh/fine", "drape/coarse", "drape/fine"):
        assert report.topics[topic].matched >= len(load_case(name).designs), report.text()
