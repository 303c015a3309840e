"""``couture bench gmls`` on the small meshes: the JSON it writes, and what it shows
(consistent derivatives fix GMLS where friction makes the columns wrong and leave it
where they are right)."""

from __future__ import annotations

import json

import pytest

from bench import gmls


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("gmls")
    assert gmls.main(["--cases", "sheet,skirt5", "--size", "small", "--repeats", "3", "--out", str(out)]) == 0
    return json.loads((out / "gmls.json").read_text())


def _case(results, name):
    return next(c for c in results["cases"] if c["case"] == name)


def test_json_has_every_answer_and_the_latencies(results):
    for c in results["cases"]:
        assert set(c["answers"]) == set(gmls.ANSWERS)
        for a in gmls.ANSWERS[1:]:
            assert c["answers"][a]["latency_s"] > 0 and c["answers"][a]["rms_mm"] >= 0
        assert len(c["trapezoid_defect"]) == 1  # the press sample and the half-edit sample
    lat = results["latency_full_cache"]
    assert lat["samples"] == 6 and lat["gmls_s"] > 0 and lat["gmls_plain_s"] > 0


def test_consistent_gmls_fixes_the_friction_case_and_keeps_the_sheet(results):
    skirt, sheet = _case(results, "skirt5"), _case(results, "sheet")
    # friction: the stick columns explain a small part of the value change between the samples
    assert skirt["trapezoid_defect"][0]["relative"] > 0.3
    a = skirt["answers"]
    assert a["gmls"]["rms_mm"] < 0.5 * a["gmls_plain"]["rms_mm"]
    assert a["gmls"]["rms_mm"] < 0.3 * a["none"]["rms_mm"]
    # frictionless sheet: the columns explain the values; GMLS as it was
    assert sheet["trapezoid_defect"][0]["relative"] < 0.1
    b = sheet["answers"]
    assert b["gmls"]["rms_mm"] <= 1.1 * b["gmls_plain"]["rms_mm"]
