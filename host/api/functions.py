"""The functions ``import host`` gives (docs/python-api.md).

One function per job, each taking what a user has in hand (a directory, a result file, numpy
arrays) and returning the bench's own objects: :func:`read_session`, :func:`calibrate`,
:func:`write_result`, :func:`load_result`, :func:`apply` (that of
:mod:`host.calib.applying`), :func:`diagnose`, :func:`export`. Their errors are
:class:`host.errors.UserError`\\ s, and the ones about bad input are also ``ValueError``\\ s
(:class:`host.errors.InputError`). ``host/__init__.py`` imports this package only when one of
these names is first used, so ``python3 -m host`` starts without it.

The examples below run as tests (``tests/host/api/test_functions.py``), ``directory`` a
session's records.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable
from pathlib import Path

from host.calib.applying import apply
from host.calib.codec import read_result
from host.calib.decision import DEFAULT_RULE, check_rule
from host.calib.result import CalibrationResult
from host.errors import InputError
from host.session.directory import Session
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG
from host.workbench.verdict import Diagnosis

__all__ = [
    "apply",
    "calibrate",
    "diagnose",
    "export",
    "load_result",
    "read_session",
    "write_result",
]

PathLike = str | os.PathLike[str]


def read_session(directory: PathLike, serial: str | None = None) -> Session:
    """Read the records of one unit from a directory.

    Parameters
    ----------
    directory : str or path-like
        The directory of the record files ``SERIAL_name.txt`` (what ``calibrate --out`` or
        ``import --out`` wrote).
    serial : str, optional
        The unit's serial number; by default the one the file names share.

    Returns
    -------
    Session
        ``serial``, and ``records``: record name (``x_up``, ``x_ccw``, …) -> record with its
        samples ``accel`` (N, 3) m/s², ``gyro`` (N, 3) °/s, ``temp`` (N,) °C, ``t_ms`` (N,)
        ms and its header ``meta``.

    Raises
    ------
    host.errors.InputError
        No such directory, no records, several serials, or a record that cannot be read.

    Examples
    --------
    >>> session = host.read_session(directory)
    >>> session.serial, len(session.records), session.records["x_up"].accel.shape[1]
    ('DEMO01', 12, 3)
    """
    from host.session.directory import read_session as read

    return read(directory, serial)


def _session(session: Session | PathLike) -> Session:
    return session if isinstance(session, Session) else read_session(session)


def calibrate(
    session: Session | PathLike,
    *,
    model: str = "base",
    term_files: Iterable[PathLike] = (),
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    decision_rule: str = DEFAULT_RULE,
) -> CalibrationResult:
    """Calibrate a unit from its records: check them, fit the model, return every parameter.

    Parameters
    ----------
    session : Session or str or path-like
        The records (:func:`read_session`), or the directory that holds them.
    model : str
        The model spec, ``base`` (method.md §2) or with further terms, e.g.
        ``"base,temperature_bias:gyro:y"`` (``python3 -m host model terms`` lists them).
    term_files : iterable of path-like
        Python files of your own terms named in ``model``.
    latitude_deg, height_m : float
        The site, degrees and metres: local gravity by the Helmert formula.
    decision_rule : str
        How each value's mark is decided (docs/calibration.md): ``"guarded"`` (default: a
        pass only where value ± U lies within the tolerance) or ``"simple"`` (the value
        alone).

    Returns
    -------
    CalibrationResult
        Every parameter with its standard error (``result.parameter("Gxx")``), the pass
        flags against method.md §7's tolerances by the decision rule
        (``result.all_passed``), the fit quality and
        where the records came from (``result.provenance``).

    Raises
    ------
    host.errors.InputError
        A record fails a check of the method, or the model spec is not one.

    Examples
    --------
    >>> result = host.calibrate(directory)
    >>> result
    <CalibrationResult DEMO01: model base, 33 parameters, ..., SIMULATED>
    >>> abs(result.parameter("A0x").value) < 0.5
    True
    """
    from host.calib.calibration import CalibrationOptions, calibrate_from_records

    options = CalibrationOptions(model=model, term_files=tuple(str(f) for f in term_files),
                                 latitude_deg=latitude_deg, height_m=height_m)  # fmt: skip
    result = calibrate_from_records(_session(session), options)
    return dataclasses.replace(result, decision_rule=check_rule(decision_rule))


def write_result(result: CalibrationResult, directory: PathLike) -> tuple[Path, Path]:
    """Write the signed-off report and the result file, together or not at all.

    Parameters
    ----------
    result : CalibrationResult
        What :func:`calibrate` returned.
    directory : str or path-like
        Where: ``SERIAL_result.txt`` and ``SERIAL_result.json`` are written there (the
        directory is made if missing).

    Returns
    -------
    tuple of Path
        The report's path and the result file's path.

    Examples
    --------
    >>> report, path = host.write_result(host.calibrate(directory), out)
    >>> report.name, path.name
    ('DEMO01_result.txt', 'DEMO01_result.json')
    """
    from host.calib.report import write_results
    from host.errors import write_error

    try:
        Path(directory).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_error(directory, exc, "nothing is written") from exc
    return write_results(result, directory)


def load_result(path: PathLike) -> CalibrationResult:
    """Read a result file (``SERIAL_result.json``, any format version this program reads).

    Nothing in a result file is run: it is data (custom terms are passed to :func:`apply`).

    Parameters
    ----------
    path : str or path-like
        The result file.

    Returns
    -------
    CalibrationResult
        The result, as :func:`calibrate` returned it.

    Raises
    ------
    host.errors.ResultFileError
        Not readable, not JSON, not a result, or a format version this program does not read.

    Examples
    --------
    >>> result = host.load_result(out / "DEMO01_result.json")
    >>> result.serial, result.model, result.simulated
    ('DEMO01', 'base', True)
    """
    return read_result(path)


def diagnose(
    session: Session | PathLike,
    model: str = "base",
    *,
    term_files: Iterable[PathLike] = (),
) -> Diagnosis:
    """Test a model against the records: does it explain them down to the noise, and if not,
    which term would (what ``python3 -m host model diagnose DIR`` prints).

    Parameters
    ----------
    session : Session or str or path-like
        The records (:func:`read_session`), or the directory that holds them.
    model : str
        The model spec to test (see :func:`calibrate`).
    term_files : iterable of path-like
        Python files of your own terms, for ``model`` and as candidates.

    Returns
    -------
    Diagnosis
        ``verdict`` (one of ``host.workbench.verdict.VERDICTS``: ``adequate``,
        ``missing_effect``, ``unexplained``, ``untestable``), ``fit`` (χ², RMS z, parameters),
        ``candidates`` (each further term tested) and ``recommended_spec``, the model to ship.

    Examples
    --------
    >>> d = host.diagnose(directory)
    >>> from host.workbench.verdict import VERDICTS
    >>> d.fit.dof > 0 and d.verdict in VERDICTS
    True
    """
    from host.model.catalogue import CATALOGUE
    from host.model.dataset import build_dataset
    from host.model.loader import load_term_file
    from host.model.spec import parse_model
    from host.workbench.verdict import diagnose as run

    cat = dict(CATALOGUE)
    for f in term_files:
        cat = load_term_file(Path(f), cat)
    return run(build_dataset(_session(session)), parse_model(model, cat), cat)


def export(
    result: CalibrationResult,
    to: str,
    *,
    axes: str = "x,y,z",
    allow_fail: bool = False,
) -> str:
    """The result in another tool's parameters or file (docs/import-export.md).

    Parameters
    ----------
    result : CalibrationResult
        What :func:`calibrate` or :func:`load_result` returned.
    to : str
        ``ardupilot`` (.parm), ``px4`` (.params), ``imucal`` (JSON) or ``c-header``.
    axes : str
        The target's axes from ours with signs, e.g. ``"x,-y,-z"``.
    allow_fail : bool
        Export a result whose verdict is not a pass (a value outside tolerance, undecided or
        not determined, a failed self-test, records of the method missing); the text then
        says FAILED. Default: refused.

    Returns
    -------
    str
        The file's text; its first lines say what the target cannot hold, and SIMULATED
        when the records came from a simulated board.

    Raises
    ------
    host.errors.FailedResultError
        The result failed and ``allow_fail`` is False (the message names what failed).
    host.errors.InputError
        An unknown format or axes, or constants that are not numbers.

    Examples
    --------
    >>> host.export(host.calibrate(directory), "ardupilot")  # its U reaches past the limits
    Traceback (most recent call last):
    host.errors.FailedResultError: result of DEMO01 FAILED (undecided under guarded acceptance: ...
    >>> text = host.export(host.calibrate(directory, decision_rule="simple"), "ardupilot")
    >>> text.splitlines()[1]
    '# *** SIMULATED BOARD simulator (source: sim): not a measurement of a unit ***'
    >>> [ln.split()[0] for ln in text.splitlines() if ln.startswith("INS_ACCSCAL")]
    ['INS_ACCSCAL_X', 'INS_ACCSCAL_Y', 'INS_ACCSCAL_Z']
    """
    from host.calib.exporting import export as write
    from host.ingest.importing import parse_axes

    if not isinstance(to, str):
        raise InputError(f"export: the format is a name such as 'ardupilot', not {to!r}")
    return write(result, to, parse_axes(axes), axes, allow_fail=allow_fail)
