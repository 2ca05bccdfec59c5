"""The examples of the README and docs/, run as written (issue 18: the decode example lost half
the frames of a file written by ``capture`` and called the result a numpy array; the plot advice
named a package on no index)."""

from __future__ import annotations

import contextlib
import io
import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def doc_pages() -> list[Path]:
    """Where the examples live: the README and the pages of docs/ it links."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def doc_block(after_heading: str, containing: str) -> tuple[str, str]:
    """The first ```python block below ``after_heading`` (in the README or a page of docs/)
    that contains ``containing``, and the page's name."""
    for page in doc_pages():
        text = page.read_text(encoding="utf-8")
        if f"\n{after_heading}\n" not in text:
            continue
        section = text.split(f"\n{after_heading}\n", 1)[1]
        for block in re.findall(r"```python\n(.*?)```", section, flags=re.S):
            if containing in block:
                return block, page.relative_to(ROOT).as_posix()
    raise AssertionError(f"no python block with {containing!r} under {after_heading!r}")


def test_every_python_example_is_valid_python_importing_what_exists() -> None:
    """A user copies these: each ```python block of the README and docs/ parses as written, and
    every ``from host… import name`` in it names a module and a name that are there."""
    import ast
    import importlib

    n = 0
    missing = []
    for page in doc_pages():
        for block in re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), re.S):
            for node in ast.walk(ast.parse(block, f"{page.name} example")):
                if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("host"):
                    mod = importlib.import_module(node.module or "")
                    missing += [
                        f"{page.name}: {node.module}.{a.name}"
                        for a in node.names
                        if not hasattr(mod, a.name)
                    ]
            n += 1
    assert n >= 4  # apply, thermal, decode, a term file
    assert missing == []


@pytest.mark.slow
def test_the_readmes_decode_example_reads_every_sample_of_a_capture(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from host.__main__ import main
    from host.wire import capture
    from host.wire.bulk import BulkResult
    from host.wire.stream import StreamDecoder

    monkeypatch.chdir(tmp_path)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["capture", "--port", "sim://?seed=5&noise_seed=5&speed=max", "--seconds", "4",
                     "session.cap"]) == 0  # fmt: skip
    # the samples in the file: the recorded bytes (capture headers taken off) decoded
    frames = StreamDecoder().feed(capture.read("session.cap").data)
    n = sum(f.name == "IMU_SAMPLE" for f in frames)
    assert n > 150
    code, page = doc_block("## Decoding captures", "decode_bulk(")
    names: dict[str, object] = {}
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        exec(compile(code, page, "exec"), names)  # noqa: S102 - the page's own code
    result = names["result"]
    assert isinstance(result, BulkResult)  # what the README says it is
    assert len(result.samples) == n  # none lost to the capture file's headers
    assert printed.getvalue().count("IMU_SAMPLE") == n  # FrameReader: the same frames


def test_plot_without_matplotlib_names_a_package_that_exists(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from host.__main__ import main
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.random(np.random.default_rng(1)), Plan(static_s=2.0,
                            turns=1), seed=1)  # fmt: skip
    write_session(tmp_path / "d", "P1", recs)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # not installed
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = main(["model", "diagnose", str(tmp_path / "d"), "--plot", str(tmp_path / "plots")])
    assert rc == 2
    assert "pip install matplotlib" in err.getvalue()
    assert "imu-bench[plot]" not in err.getvalue()  # on no package index
    # every command with --plot gives the same advice (one text: host.cli.NO_MATPLOTLIB)
    from host.cli import NO_MATPLOTLIB

    for argv in (
        ["model", "diagnose", str(tmp_path / "d"), "--plot", str(tmp_path / "plots")],
        ["noise", str(tmp_path / "d" / "P1_x_up.txt"), "--plot", str(tmp_path / "n.png")],
    ):
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            assert main(argv) == 2
        # the one error line; before it at most the log lines of a wait over 1 s (a loaded
        # machine): "diagnose: reading the records, … 1 s"
        *waiting, last = err.getvalue().strip().splitlines()
        assert last == f"error: {NO_MATPLOTLIB}", err.getvalue()
        assert all(re.fullmatch(r".+ … \d+ s", ln) for ln in waiting), err.getvalue()


def test_the_readmes_command_index_names_every_command_once() -> None:
    """The README's 'Commands' table has one row per command of ``python3 -m host``, and every
    ``python3 -m host WORD`` in the README and docs/ names a command that exists."""
    from host.__main__ import COMMANDS

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = readme.split("\n## Commands\n", 1)[1].split("\n## ", 1)[0]
    rows = [ln for ln in table.splitlines() if ln.startswith("| `")]
    firsts = [re.match(r"\| `([\w-]+)", ln).group(1) for ln in rows]  # type: ignore[union-attr]
    assert sorted(firsts) == sorted(COMMANDS)
    for page in doc_pages():
        for word in re.findall(r"python3? -m host ([a-z][\w-]*)", page.read_text(encoding="utf-8")):
            assert word in COMMANDS, f"{page.name}: python3 -m host {word}: no such command"


@pytest.mark.slow
def test_the_fit_example_gives_the_fit_line_of_model_diagnose(tmp_path: Path) -> None:
    """docs/python-api.md's fit, run as written on a session directory, gives the numbers the
    command prints for the same records and model (the example is the engine the command uses,
    with its defaults)."""
    import json

    from host.__main__ import main
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.random(np.random.default_rng(3)), Plan(static_s=3.0,
                            turns=1), seed=3)  # fmt: skip
    write_session(tmp_path / "DEMO01", "DEMO01", recs)
    code, page = doc_block("## Fit a model to a session", "fit_with_components(")
    code = code.replace('"DEMO01/"', repr(str(tmp_path / "DEMO01")))
    names: dict[str, object] = {}
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        exec(compile(code, page, "exec"), names)  # noqa: S102 - the page's own code
    fit = names["fit"]
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        main(["model", "diagnose", str(tmp_path / "DEMO01"), "--json",
              "--model", "base,temperature_bias:gyro:y"])  # fmt: skip
    cli = json.loads(out.getvalue())["fit"]
    assert fit.dof == cli["dof"] and fit.n_params == cli["n_params"]  # type: ignore[attr-defined]
    assert abs(fit.chi2 - cli["chi2"]) <= 1e-9 * cli["chi2"]  # type: ignore[attr-defined]
    assert f"RMS z {cli['rms_z']:.2f}," in printed.getvalue()
    assert printed.getvalue().count("±") == len(fit.parameters) > 20  # type: ignore[attr-defined]


def test_the_pages_name_the_result_format_that_is_written() -> None:
    """Was: docs/python-api.md said "format v2 or v1" where every result file written is v3.
    Each page that names the format a result JSON is written in names the codec's."""
    from host.calib.codec import FORMAT_VERSION

    api = (ROOT / "docs" / "python-api.md").read_text(encoding="utf-8")
    formats = (ROOT / "docs" / "formats.md").read_text(encoding="utf-8")
    assert f"written as format v{FORMAT_VERSION};" in api
    assert f"the JSON (format v{FORMAT_VERSION})" in api
    assert f"`SERIAL_result.json` (format v{FORMAT_VERSION}:" in formats
