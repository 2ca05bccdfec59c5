"""The bench file (issue 43): the example in docs/ reads back as written; every way a file
can break its format is one line naming the file and the key; any bytes at all give a bench
file or that one line, never a traceback; and where ``calibrate`` finds one."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from host.calib.bench_file import (
    BENCH_FILE_ENV,
    BenchFileError,
    find_bench_file,
    load_bench_file,
)

EXAMPLE = Path(__file__).resolve().parents[3] / "docs" / "examples" / "bench.toml"


def test_the_documented_example_reads_as_written() -> None:
    b = load_bench_file(EXAMPLE)
    text = EXAMPLE.read_text(encoding="utf-8")
    assert f'name = "{b.lab_name}"' in text and f'address = "{b.lab_address}"' in text
    assert f'id = "{b.bench_id}"' in text and f'name = "{b.signatory}"' in text
    assert f"level_mrad = {b.plate.value:g}" in text and f"checked = {b.plate.checked}" in text
    assert f"squareness_mrad = {b.cube.value:g}" in text and f'by = "{b.cube.by}"' in text
    assert f"latitude_deg = {b.site.latitude_deg:g}" in text
    assert f"height_m = {b.site.height_m:g}" in text
    # and the page users read shows the same file
    page = (EXAMPLE.parents[1] / "bench-file.md").read_text(encoding="utf-8")
    for line in ("[laboratory]", 'format = "imu-bench bench"', f'id = "{b.bench_id}"'):
        assert line in page


def _broken(tmp_path: Path, old: str, new: str) -> Path:
    text = EXAMPLE.read_text(encoding="utf-8")
    assert old in text
    p = tmp_path / "bench.toml"
    p.write_text(text.replace(old, new, 1), encoding="utf-8")
    return p


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("level_mrad = 0.2", 'level_mrad = "flat"', "[plate] level_mrad: give a number"),
        ("level_mrad = 0.2", "level_mrad = 250", "[plate] level_mrad = 250 is not within 0"),
        ("level_mrad = 0.2", "level_mrad = true", "[plate] level_mrad: give a number"),
        ("checked = 2026-10-02", "", "[cube] has no 'checked'"),
        ("checked = 2026-10-02", 'checked = "last week"', "[cube] checked: give a date"),
        ("checked = 2026-10-02", "checked = 2999-01-01", "is in the future"),
        ("latitude_deg = 52.52", "lat = 52.52", "[site] has no 'latitude_deg'"),
        ("latitude_deg = 52.52", "latitude_deg = 95", "latitude_deg = 95 is not within -90"),
        ('source = "survey', 'sauce = "survey', "[site] has no 'source'"),
        (
            "[signatory]\nname",
            "[signatory]\ntitle = 'Dr'\nname",
            "[signatory] 'title' is no key of it",
        ),
        ('id = "B1"', "id = 7", "[bench] id: give a text in quotes"),
        ('id = "B1"', 'id = "B1\\u001b[2J"', "[bench] id: give one line of printable text"),
        ('id = "B1"', 'id = "   "', "[bench] id: give a text in quotes"),
        ("version = 1", "version = 2", "not a bench file of this program"),
        ('format = "imu-bench bench"', 'format = "other"', "not a bench file of this program"),
        ("[cube]", "[cubes]", "unknown table or key 'cubes'"),
        ("[laboratory]", "[laboratory", "not TOML"),
    ],
)
def test_a_broken_file_is_one_line_naming_the_key(
    tmp_path: Path, old: str, new: str, words: str
) -> None:
    p = _broken(tmp_path, old, new)
    with pytest.raises(BenchFileError) as exc:
        load_bench_file(p)
    msg = str(exc.value)
    assert words in msg and msg.startswith(str(p)) and "\n" not in msg, msg


def test_unreadable_files_are_one_line(tmp_path: Path) -> None:
    for data, words in ((b"\xff\xfe[bench]", "not UTF-8"), (b"x" * 70_000, "over 64 KiB")):
        p = tmp_path / "b.toml"
        p.write_bytes(data)
        with pytest.raises(BenchFileError, match=words):
            load_bench_file(p)
    with pytest.raises(BenchFileError, match="cannot read the bench file"):
        load_bench_file(tmp_path / "missing.toml")
    with pytest.raises(BenchFileError, match="cannot read the bench file"):
        load_bench_file(tmp_path)  # a directory


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.binary(max_size=300) | st.text(max_size=300).map(lambda s: s.encode("utf-8")))
def test_any_bytes_give_a_bench_file_or_one_line(tmp_path: Path, data: bytes) -> None:
    p = tmp_path / "fuzz.toml"
    p.write_bytes(data)
    try:
        load_bench_file(p)
    except BenchFileError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(str(p))


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(value=st.one_of(st.integers(), st.floats(allow_nan=False), st.text(max_size=20),
                       st.booleans(), st.lists(st.integers(), max_size=3)))  # fmt: skip
@example(value="\x7f")  # not TOML: was expected to be named by its key
def test_any_value_of_a_key_is_read_or_refused_in_one_line(tmp_path: Path, value: object) -> None:
    import json

    literal = json.dumps(value, ensure_ascii=False)
    if isinstance(value, float):
        literal = repr(value) if "e" not in repr(value) and "inf" not in repr(value) else "1.0"
    import tomllib

    p = _broken(tmp_path, "level_mrad = 0.2", f"level_mrad = {literal}")
    try:
        tomllib.loads(p.read_text(encoding="utf-8"))
        toml = True
    except tomllib.TOMLDecodeError:  # e.g. a DEL (\x7f) in a string: TOML forbids it
        toml = False
    try:
        b = load_bench_file(p)
    except BenchFileError as exc:
        assert "\n" not in str(exc)
        # a value TOML reads is named by its key; a file TOML cannot read, by its place
        assert ("[plate] level_mrad" in str(exc)) if toml else ("not TOML" in str(exc))
    else:
        assert 0.0 <= b.plate.value <= 100.0


def test_where_calibrate_finds_the_bench_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(BENCH_FILE_ENV, raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    assert find_bench_file(None) is None  # no file in the user's config: none
    own = tmp_path / "config" / "imu-bench" / "bench.toml"
    own.parent.mkdir(parents=True)
    own.write_text(EXAMPLE.read_text(encoding="utf-8"), encoding="utf-8")
    assert find_bench_file(None) == own
    monkeypatch.setenv(BENCH_FILE_ENV, str(tmp_path / "lab.toml"))
    assert find_bench_file(None) == tmp_path / "lab.toml"  # the environment before the config
    assert find_bench_file("given.toml") == Path("given.toml")  # the option before both
    assert find_bench_file("none") is None
