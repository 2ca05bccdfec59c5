"""Compute and write: the one step from a directory of records to the published result.

Both ways to a result end here — the live calibration (:mod:`host.dialogue.flow`, after the
last record) and ``python3 -m host calibrate --from-dir DIR`` (:mod:`host.cli.calibrate`):
:func:`compute_and_write` checks the records, fits the model, verifies held-out records if asked
and writes ``SERIAL_result.txt`` and ``SERIAL_result.json`` together (method.md §7);
:func:`show_result` prints the report (or the JSON) on stdout. Each caller adds its own lines
around them (where the files went, the verdict), in its own voice. ``--from-dir`` takes the
locks a live session takes (:func:`directory_locks`) and moves an earlier result of other
records aside (:func:`set_aside_other_result`), so no result is replaced silently.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from host.calib.applying import verify_directory
from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.calib.certificate import Issue, issue_now
from host.calib.codec import read_result, result_to_json
from host.calib.decision import DEFAULT_RULE
from host.calib.report import format_report, result_paths, write_results
from host.calib.result import CalibrationResult
from host.calib.thermal import ThermalCalibration
from host.errors import UserError
from host.model.noise import NoiseModel
from host.model.signals import SENSORS
from host.session.directory import Session, lock_directory, set_aside
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG


def _stderr(text: str) -> None:
    print(text, file=sys.stderr)


def parse_floor(text: str | None) -> NoiseModel:
    """``--floor accel=A,gyro=G`` (m/s², °/s; either may be left out) -> the fit's
    :class:`~host.model.noise.NoiseModel`; no text: the floor is measured from the records."""
    nm = NoiseModel()
    if not text:
        return nm
    floor: dict[str, float] = {}
    for item in text.split(","):
        key, _, val = item.partition("=")
        key = key.strip()
        try:
            v = float(val)
        except ValueError:
            v = math.nan
        if key not in SENSORS or not math.isfinite(v) or v < 0:
            raise UserError(f"--floor: expected accel=VALUE,gyro=VALUE (≥ 0), got {item!r}")
        floor[key] = v
    return dataclasses.replace(nm, floor=floor)


def session_noise(session: Session, floor: str | None, noise_file: str | None) -> NoiseModel:
    """The fit's noise model: ``--floor`` (:func:`parse_floor`) names the sensors it sets;
    the others come from the noise file ``noise_file`` (``noise FILE --save``) when given —
    :func:`host.model.recording.workbench_floor` at the median length of the session's static
    records — and are otherwise measured from the records themselves."""
    nm = parse_floor(floor)
    if not noise_file:
        return nm
    from host.model.recording import load_noise_file, workbench_floor

    doc = load_noise_file(noise_file)
    lengths = [r.duration_s for r in session.records.values() if r.kind == "static"]
    if not lengths:
        raise UserError(f"--noise {noise_file}: the session has no static records to size it")
    out = workbench_floor(doc, float(sorted(lengths)[len(lengths) // 2]))
    out.update(nm.floor)  # --floor names the sensors it overrides
    return dataclasses.replace(nm, floor=out)


@dataclass(frozen=True)
class ComputeSettings:
    """How to compute a result; units in the names. ``turns``: n for turn records whose
    header does not say it (None: inferred); ``model``: the model spec
    (:func:`host.model.spec.parse_model`); ``floor``: the ``--floor`` text (None: measured);
    ``verify``: a directory of held-out records to predict (None: no verification);
    ``thermal``: the ``--thermal`` option (:func:`thermal_of`); ``noise_file``: the
    ``--noise`` file (:func:`session_noise`); ``pdf``: also the PDF report
    (:mod:`host.calib.report_pdf`); ``issue``: the certificate's facts beyond the result —
    bench file, customer, where the site came from (:class:`host.calib.certificate.Issue`;
    its time of issue is set when the report is written)."""

    turns: int | None = None
    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = DEFAULT_HEIGHT_M
    model: str = "base"
    term_files: Sequence[str] = field(default_factory=tuple)
    floor: str | None = None
    verify: str | None = None
    thermal: str | None = None
    noise_file: str | None = None
    #: also write the report as ``SERIAL_result.pdf`` with its residual plots
    pdf: bool = False
    #: how each value's mark is decided (:mod:`host.calib.decision`: guarded or simple)
    decision_rule: str = DEFAULT_RULE
    issue: Issue = field(default_factory=Issue)


@dataclass(frozen=True)
class Published:
    """A result and the files it was written to (``pdf_path``: None when not asked);
    ``records_dir``: the directory its records were read from (the report's next command
    names it; None: not known); ``issue``: the certificate's facts the report was issued
    with (its number among them)."""

    result: CalibrationResult
    report_path: Path
    json_path: Path
    pdf_path: Path | None = None
    records_dir: Path | None = None
    issue: Issue = field(default_factory=Issue)


def thermal_of(
    session: Session, option: str | None, note: Callable[[str], None] = _stderr
) -> tuple[ThermalCalibration | None, str]:
    """The thermal calibration ``--thermal`` names, else SERIAL_thermal.json beside the
    records (None for 'none' or when there is none), and its path; ``note`` is told when the
    file beside the records is used."""
    if option is not None and option.lower() == "none":
        return None, ""
    if option is not None:
        return ThermalCalibration.load(option), option
    if session.directory is None:
        return None, ""
    path = Path(session.directory) / f"{session.serial}_thermal.json"
    if not path.is_file():
        return None, ""
    note(f"using the thermal calibration {path} (--thermal none ignores it)")
    return ThermalCalibration.load(path), str(path)


def compute_and_write(
    session: Session,
    out_dir: Path,
    settings: ComputeSettings,
    note: Callable[[str], None] = _stderr,
    before_write: Callable[[CalibrationResult], object] | None = None,
) -> Published:
    """Compute the calibration of ``session`` and write both result files into ``out_dir``
    (together or not at all, :func:`host.calib.report.write_results`). UserError for what the
    user can fix (a bad record, option or directory); nothing is written then. ``note``: where
    remarks go (default stderr). ``before_write``: called with the result once it is computed,
    before anything is written (``--from-dir`` sets an earlier result aside there)."""
    if settings.turns is not None and settings.turns < 1:
        raise UserError("--turns must be at least 1")
    thermal, source = thermal_of(session, settings.thermal, note)
    options = CalibrationOptions(
        model=settings.model,
        term_files=tuple(settings.term_files),
        noise=session_noise(session, settings.floor, settings.noise_file),
        turns=settings.turns,
        latitude_deg=settings.latitude_deg,
        height_m=settings.height_m,
        thermal=thermal,
        thermal_source=source,
    )
    result = calibrate_from_records(session, options)
    given = {"noise": settings.noise_file, "floor": settings.floor}
    result = dataclasses.replace(
        result,
        floor_source={k: v for k, v in given.items() if v},
        decision_rule=settings.decision_rule,
    )
    if settings.verify:
        result = verify_directory(result, settings.verify, term_files=settings.term_files)
    if not out_dir.is_dir():
        raise UserError(f"{out_dir}: no such directory{_why_not_a_directory(out_dir)}")
    records_dir = Path(session.directory) if session.directory is not None else out_dir
    if before_write is not None:
        before_write(result)
    issue = dataclasses.replace(settings.issue, issued=issue_now())
    txt, js = write_results(result, out_dir, records_dir, issue)
    pdf = None
    if settings.pdf:
        from host.calib.report_pdf import pdf_path, write_report_pdf

        pdf = write_report_pdf(result, pdf_path(txt), records_dir, issue)
    return Published(result, txt, js, pdf, records_dir, issue)


def _why_not_a_directory(path: Path) -> str:
    """What stands in the way of ``path`` being a directory, and what to do, for a message."""
    for p in (path, *path.parents):
        if p.exists() and not p.is_dir():
            return f" ({p} is a file); give --out a directory"
    return "; create it or give --out an existing directory"


def show_result(pub: Published, as_json: bool, out: TextIO | None = None) -> None:
    """Print the published report (method.md §7, as written) or, ``as_json``, the JSON
    result on ``out`` (stdout)."""
    stream = out if out is not None else sys.stdout
    result = pub.result
    text = result_to_json(result) if as_json else format_report(result, pub.records_dir, pub.issue)
    stream.write(text)
    stream.flush()


# --------------------------------------------------------------------------- --from-dir


@contextlib.contextmanager
def directory_locks(records_dir: Path, out_dir: Path, what: str) -> Iterator[None]:
    """The lock a live session takes (:func:`host.session.directory.lock_directory`), on
    ``out_dir`` and on ``records_dir`` when that is another directory this user may write (a
    live session there is still measuring): DirectoryBusy naming the other process's PID
    when one holds either, so two computations never write one result at once."""
    with contextlib.ExitStack() as stack:
        out = out_dir.resolve()
        for d in dict.fromkeys([out, records_dir.resolve()]):
            if d.is_dir() and (d == out or os.access(d, os.W_OK)):
                stack.enter_context(lock_directory(d, what))
        yield


def set_aside_other_result(
    out_dir: Path, result: CalibrationResult, note: Callable[[str], None] = _stderr
) -> Path | None:
    """Before ``result`` is written into ``out_dir``: an earlier result there fitted on other
    records (other names, or other bytes by their SHA-256; one that cannot be read or names
    none) is moved with its report and PDF into ``out_dir/earlier/SERIAL_<UTC time>/``, bytes
    unchanged, as a new live sitting moves an earlier one; ``note`` says where. A result of
    the same records is computed again in its place. Returns where it went (None: nowhere)."""
    txt, js = result_paths(out_dir, result.serial)
    files = [p for p in (txt, js, txt.with_suffix(".pdf")) if p.is_file()]
    if not files:
        return None
    try:
        earlier = read_result(js)
        same = earlier.records == result.records and _digests(earlier) == _digests(result)
    except UserError:
        same = False
    if same and _digests(result):
        return None
    aside = set_aside(out_dir, result.serial, files)
    note(f"the earlier result in {out_dir}, of other records, moved to {aside}")
    return aside


def _digests(result: CalibrationResult) -> dict[str, str]:
    return {} if result.provenance is None else dict(result.provenance.record_sha256)
