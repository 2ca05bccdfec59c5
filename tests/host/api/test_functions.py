"""The library a programmer calls (issue 28): ``import host`` gives the handful of names, each
with a numpydoc docstring whose example runs here; bad input is a ``ValueError``; a result's
``repr`` is one short line; ``help(host)`` lists the API; docs/python-api.md's "Use it from
Python" runs as written; and ``import host`` stays light (no numpy) until a name is used."""

from __future__ import annotations

import contextlib
import doctest
import inspect
import io
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import host
from host import errors
from host.api import functions
from tests.host.sim_sessions import write_sim_session

ROOT = Path(__file__).resolve().parents[3]
API = ["read_session", "calibrate", "write_result", "load_result", "apply", "diagnose", "export"]


@pytest.fixture(scope="module")
def directory(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("api") / "DEMO01"
    d.mkdir()
    write_sim_session(d, "DEMO01", seed=28)
    return d


def test_every_name_has_a_numpydoc_docstring_with_an_example() -> None:
    for name in API:
        doc = inspect.getdoc(getattr(host, name)) or ""
        for section in ("Parameters", "Returns", "Examples"):
            assert f"\n{section}\n{'-' * len(section)}\n" in doc, (name, section)
        assert ">>> " in doc, name
    assert host.apply is __import__("host.calib.applying", fromlist=["apply"]).apply  # one apply


@pytest.mark.slow
def test_the_examples_run(directory: Path, tmp_path: Path) -> None:
    globs = {"host": host, "directory": directory, "out": tmp_path}
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    runner = doctest.DocTestRunner(optionflags=flags)
    finder = doctest.DocTestFinder()
    tried = 0
    for name in API:  # in the order a user would: calibrate and write before load
        for test in finder.find(getattr(host, name), name, globs=dict(globs)):
            out = io.StringIO()
            result = runner.run(test, out=out.write)
            assert result.failed == 0, out.getvalue()
            tried += result.attempted
    assert tried >= 15


def test_bad_input_is_a_value_error(directory: Path, tmp_path: Path) -> None:
    assert issubclass(errors.InputError, ValueError) and issubclass(
        errors.InputError, host.UserError
    )
    for cls in (errors.RecordCheckError, errors.ResultFileError, errors.TermFileMismatch,
                errors.NotDeterminedError, errors.FailedResultError):  # fmt: skip
        assert issubclass(cls, host.InputError), cls
    from host.session.records import RecordError

    assert issubclass(RecordError, host.InputError)
    assert not issubclass(errors.ResumableError, ValueError)  # a stop, not bad input
    with pytest.raises(ValueError, match="no such directory"):
        host.read_session(tmp_path / "nope")
    bad = tmp_path / "bad.json"
    bad.write_text('{"format_version": 99}')
    with pytest.raises(ValueError, match="format v99"):
        host.load_result(bad)
    result = host.calibrate(directory)
    with pytest.raises(ValueError, match=r"must both be \(N,3\)"):
        host.apply(result, np.zeros((5, 2)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="unknown format"):
        host.export(result, "betaflight")
    failed = host.calibrate(directory, latitude_deg=0.0, height_m=9000.0)  # g off by 0.3 %
    if not failed.all_passed:
        with pytest.raises(ValueError, match="FAILED"):
            host.export(failed, "px4")


def test_the_result_says_itself_in_one_short_line(directory: Path) -> None:
    result = host.calibrate(directory)
    text = repr(result)
    assert len(text) < 120 and "\n" not in text
    assert re.fullmatch(
        r"<CalibrationResult DEMO01: model base, \d+ parameters, (PASS|FAIL), fit \w+, SIMULATED>",
        text,
    ), text


def _python(code: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PAGER": "cat", "TERM": "dumb"}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         cwd=ROOT, check=True, timeout=60)  # fmt: skip
    return run.stdout


@pytest.mark.slow
def test_import_host_is_light_and_help_lists_the_api() -> None:
    loaded = _python(
        "import sys, host; print(sorted(m for m in sys.modules if m.split('.')[0] == 'numpy' "
        "or m.startswith('host.')))"
    )
    assert loaded.strip() == "['host.version']", loaded  # the version: a module of one line
    text = _python("import host; help(host)")
    for name in API:
        assert f"host.{name}(" in text, name
    assert "host.InputError" in text and "ValueError" in text


@pytest.mark.slow
def test_the_docs_page_runs_as_written(directory: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    page = (ROOT / "docs" / "python-api.md").read_text(encoding="utf-8")
    section = page.split("\n## Use it from Python\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert blocks
    monkeypatch.chdir(directory.parent)  # the page's DEMO01/ is this session
    names: dict[str, object] = {}
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        for code in blocks:
            exec(compile(code, "docs/python-api.md", "exec"), names)  # noqa: S102 - the page's
    said = printed.getvalue()
    result = names["result"]
    assert isinstance(result, host.CalibrationResult) and repr(result) in said
    assert "INS_ACCOFFS_X" in said or "FAILED" in said
    assert (directory.parent / "out" / "DEMO01_result.json").is_file()


def test_the_functions_module_names_only_the_api() -> None:
    assert sorted(functions.__all__) == sorted(API)
    assert set(API) <= set(dir(host)) and set(host.__all__) == {"__version__", *host._API}
    # what ``dir(host)`` lists is the API, not the helpers host/__init__.py imports for itself
    assert not {"Any", "TYPE_CHECKING", "annotations", "importlib", "ModuleType"} & set(dir(host))
