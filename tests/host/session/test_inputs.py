"""The serial rule and bounded JSON (host/session/inputs.py).

The property: a serial of random characters, given by every path a serial comes in by (the
``--serial`` option, a record file's name, a result JSON, the archive), is either refused with
one line or obeys the rule; and a serial that breaks it, put into a result by a program (the
library allows it), goes into every export format, the report and the archive's page without
starting a line of any of them.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.archive.checks import LotReport, TrendPoint
from host.archive.entry import entry_from_directory
from host.archive.page import PageData, render
from host.calib.codec import read_result, result_from_json
from host.calib.exporting import FORMATS, export
from host.calib.kalibr import export_kalibr
from host.calib.report import format_report
from host.calib.result import CalibrationResult
from host.errors import UserError
from host.session.directory import read_session
from host.session.inputs import (
    SERIAL_RE,
    check_serial,
    json_depth,
    load_json,
    parse_serial,
    written_serial,
)
from tests.host.issue31_sweep import _calibrated
from tests.host.issue44_sweep import EVIL, EVIL_NAME, MARKUP

#: the characters that end a line for some reader (Python's splitlines, C, HTML, YAML)
BREAKS = "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
serials = st.one_of(
    st.text(min_size=0, max_size=40),
    st.text(alphabet=st.sampled_from("Q1_-\n\r\x85\u2028 */#<>\"'{};ARMING"), max_size=30),
    st.binary(max_size=30).map(lambda b: b.decode("latin-1")),
)
SLOW = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A session with its result files (one fit for the whole module)."""
    return _calibrated(tmp_path_factory.mktemp("cal"))


@pytest.fixture(scope="module")
def result(calibrated: Path) -> CalibrationResult:
    return read_result(calibrated / "Q1_result.json")


def one_line_error(exc: BaseException) -> bool:
    return len(str(exc).splitlines()) == 1


# --------------------------------------------------------------------------- the rule


@given(serials)
def test_the_option_obeys_the_rule_or_says_why_in_one_line(serial: str) -> None:
    try:
        got = parse_serial(serial)
    except ValueError as exc:
        assert one_line_error(exc), str(exc)
        assert "use 1 to 12 characters" in str(exc) or "mandatory" in str(exc)
        return
    assert SERIAL_RE.fullmatch(got) and got == serial.strip()


@given(serials)
def test_a_written_serial_is_one_plain_line(serial: str) -> None:
    w = written_serial(serial)
    assert not any(c in w for c in BREAKS) and "*/" not in w
    assert not any(c in w for c in "<>&\"' /#")
    assert w == serial or not SERIAL_RE.fullmatch(serial)  # a serial of the rule as it is
    if not SERIAL_RE.fullmatch(serial):
        with pytest.raises(ValueError):
            check_serial(serial)


# --------------------------------------------------------------------------- every path in


@SLOW
@given(serial=serials)
def test_record_names_obey_the_rule_or_are_refused(
    serial: str, calibrated: Path, tmp_path: Path
) -> None:
    name = serial + "_x_up.txt"
    if "/" in serial or "\0" in serial or len(os.fsencode(name)) > 255 or serial in ("", "."):
        return  # no file can have this name
    d = Path(tempfile.mkdtemp(dir=tmp_path))
    text = (calibrated / "Q1_x_up.txt").read_text().replace("# serial: Q1\n", "")
    (d / name).write_text(text)
    try:
        s = read_session(d)
    except UserError as exc:
        assert one_line_error(exc), str(exc)
        return
    assert s.serial == serial and SERIAL_RE.fullmatch(serial)


@SLOW
@given(serial=serials)
@pytest.mark.slow
def test_a_result_json_and_the_archive_obey_the_rule(
    serial: str, calibrated: Path, tmp_path: Path
) -> None:
    doc = json.loads((calibrated / "Q1_result.json").read_text())
    text = json.dumps({**doc, "serial": serial})
    try:
        r = result_from_json(text)
    except UserError as exc:
        assert one_line_error(exc), str(exc)
    else:
        assert SERIAL_RE.fullmatch(r.serial)
        return
    d = Path(tempfile.mkdtemp(dir=tmp_path))  # the archive reads it by the same rule
    (d / "U_result.json").write_text(text)
    (d / "U_result.txt").write_text("report\n")
    with pytest.raises(UserError) as exc_info:
        entry_from_directory(d)
    assert one_line_error(exc_info.value)


# --------------------------------------------------------------------------- every file out


#: a serial that obeys the rule, for the files every other serial's are compared with
MARK = "ZZMARK01"


def texts_of(result: CalibrationResult, serial: str) -> dict[str, str]:
    """Every file a serial is written into, for ``result`` given ``serial``."""
    r = dataclasses.replace(result, serial=serial)  # a program may build any result
    texts = {fmt: export(r, fmt, allow_fail=True) for fmt in FORMATS}
    texts["report"] = format_report(r)
    texts["html"] = render(_page(serial))
    texts["kalibr"] = export_kalibr(_noise_doc(serial))
    return texts


@pytest.mark.slow
@SLOW
@given(serial=serials)
def test_no_file_written_has_a_line_the_serial_started(
    serial: str, result: CalibrationResult
) -> None:
    _same_lines_but_the_serial(serial, result)


@pytest.mark.parametrize("serial", [EVIL, EVIL_NAME, MARKUP, "", "\u2028x\x85y\rz", "a" * 300])
def test_the_issues_serials_start_no_line(serial: str, result: CalibrationResult) -> None:
    _same_lines_but_the_serial(serial, result)
    evil = export(dataclasses.replace(result, serial=EVIL), "ardupilot", allow_fail=True)
    assert "ARMING_CHECK" not in evil and "Q1\\x20\\x2a\\x2f" in evil


def _same_lines_but_the_serial(serial: str, result: CalibrationResult) -> None:
    """Each file has the lines it has with a plain serial, and only the lines that hold the
    serial differ: none is added, split or started by it (the report: the same words, its
    paragraphs wrapped anew)."""
    base = texts_of(result, MARK)
    for fmt, text in texts_of(result, serial).items():
        if fmt == "report":  # its paragraphs are wrapped at 80 columns: the same words
            words = " ".join(base[fmt].replace(MARK, written_serial(serial)).split())
            assert " ".join(text.split()) == words, (fmt, serial)
            continue
        lines, before = text.splitlines(), base[fmt].splitlines()
        assert len(lines) == len(before), (fmt, serial)
        for ln, was in zip(lines, before, strict=True):
            assert ln == was or MARK in was or MARK in was.upper(), (fmt, serial, ln)
    header = texts_of(result, serial)["c-header"]
    assert header.count("*/") == base["c-header"].count("*/")  # no comment the serial ended
    json.loads(texts_of(result, serial)["imucal"])


def _page(serial: str) -> PageData:
    point = TrendPoint("2026-01-01T00:00:00", "B1", 1.0, 0.1)
    return PageData(
        title="t", archive="a", generated="g", alpha=0.01,
        lot=LotReport(rows=[], units=1, failing=((serial, "why"),), conditional=((serial, 2.0),)),
        repeat=[], drift=[], drift_k=3.0, benches=[], bench_k=3.0, reference=serial, charts=[],
        trends={serial: {"Kxx": [point, point]}},
    )  # fmt: skip


def _noise_doc(serial: str) -> dict[str, object]:
    fig = {"value": 1e-3, "ci": [1e-3, 2e-3]}
    quantities = ("white_noise_density", "bias_instability", "rate_random_walk")
    chans = {c: dict.fromkeys(quantities, fig) for c in ("ax", "ay", "az", "gx", "gy", "gz")}
    return {"source": f"{serial}_z_up.txt", "duration_s": 3600.0, "rate_hz": 50.0,
            "channels": chans, "warnings": [serial]}  # fmt: skip


# --------------------------------------------------------------------------- JSON bounds


@given(st.recursive(st.none() | st.integers() | st.text(alphabet='[]{}"\\ab'),
                    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(), c, max_size=3),
                    max_leaves=20))  # fmt: skip
@pytest.mark.slow
def test_the_depth_is_the_nesting_of_the_document(doc: object) -> None:
    def depth(x: object) -> int:
        if isinstance(x, list):
            return 1 + max(map(depth, x), default=0)
        if isinstance(x, dict):
            return 1 + max(map(depth, x.values()), default=0)
        return 0

    text = json.dumps(doc, ensure_ascii=False)
    assert json_depth(text) == depth(doc)
    assert load_json(text) == doc


def test_deep_and_large_json_are_refused_in_one_line() -> None:
    for text, words in (("[" * 100_000, "nested 100000 deep"), ('"' + "x" * 17 * 2**20 + '"',
                                                                  "17.0 MiB")):  # fmt: skip
        with pytest.raises(UserError) as exc_info:
            load_json(text, "f.json")
        assert words in str(exc_info.value) and one_line_error(exc_info.value)
