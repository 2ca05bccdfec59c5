"""imu-bench: calibrate an IMU (the APM 2.6's MPU-6000) on a levelled plate with a cube.

Use it from Python (docs/python-api.md); each name has its own help, e.g. ``help(host.apply)``:

- ``host.read_session(directory)`` — the records of one unit (a :class:`Session`)
- ``host.calibrate(session_or_directory, model="base")`` — fit the model: a
  :class:`CalibrationResult` (every parameter ± σ, pass flags, fit quality, provenance)
- ``host.write_result(result, directory)`` — the signed-off report and the result file
- ``host.load_result(path)`` — read ``SERIAL_result.json`` (data: nothing in it is run)
- ``host.apply(result, accel, gyro, temp_c=None, t_s=None)`` — correct raw samples
- ``host.diagnose(session_or_directory, model="base")`` — does the model explain the records?
- ``host.export(result, "ardupilot" | "px4" | "imucal" | "c-header")`` — another tool's file
- errors: ``host.UserError`` (one line a user can act on) and ``host.InputError`` (bad input,
  also a ``ValueError``), in :mod:`host.errors`

These are imported when first used, so ``python3 -m host`` starts light. The command line:
``python3 -m host --help``. The packages, one per stage of the data's journey (docs/layout.md):

- :mod:`host.version` — the version (``host.__version__``), at the bottom: it imports nothing
- :mod:`host.wire` — the spec table (generated), frame codecs and decoders, capture files, counts
- :mod:`host.timing` — device time: unwrap, the device→host clock map
- :mod:`host.board` — ports and URLs (link), the board driver, one measurement, flashing
- :mod:`host.dialogue` — the live calibration dialogue (method.md §5) and its console
- :mod:`host.ingest` — foreign data in: column files, imucal sessions, captures -> records
- :mod:`host.session` — records, the session directory, the method's constants, record checks
- :mod:`host.calib` — the calibration and its result, the report, export
- :mod:`host.model` — the engine: terms, dataset, noise model, the fit, statistics
- :mod:`host.workbench` — the model workbench: candidates, scan, verdict, ladder
- :mod:`host.bench` — the virtual bench: truth, physics, simulator, link simulator, emulator,
  and the firmware and emulator builds (:mod:`host.bench.build`)
- :mod:`host.transports` — pyserial URL adapters (``sim://``, ``emu://``, ``replay://``)
- :mod:`host.api` — the functions above (:mod:`host.api.functions`)
- :mod:`host.cli` — the commands of ``python3 -m host``
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import TYPE_CHECKING, Any

from host.version import __version__

if TYPE_CHECKING:  # for type checkers and readers; at run time __getattr__ imports them
    from host.api.functions import (
        apply,
        calibrate,
        diagnose,
        export,
        load_result,
        read_session,
        write_result,
    )
    from host.calib.result import CalibrationResult
    from host.errors import InputError, UserError
    from host.session.directory import Session

#: public name -> the module that defines it (imported on first use)
_API = {
    "read_session": "host.api.functions",
    "calibrate": "host.api.functions",
    "write_result": "host.api.functions",
    "load_result": "host.api.functions",
    "apply": "host.api.functions",
    "diagnose": "host.api.functions",
    "export": "host.api.functions",
    "CalibrationResult": "host.calib.result",
    "Session": "host.session.directory",
    "UserError": "host.errors",
    "InputError": "host.errors",
}

__all__ = [
    "__version__",
    "read_session",
    "calibrate",
    "write_result",
    "load_result",
    "apply",
    "diagnose",
    "export",
    "CalibrationResult",
    "Session",
    "UserError",
    "InputError",
]


def __getattr__(name: str) -> Any:
    if name in _API:
        value = getattr(importlib.import_module(_API[name]), name)
        globals()[name] = value  # once imported, an ordinary attribute
        return value
    raise AttributeError(f"module 'host' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names, the module's own dunders and the subpackages imported so far (not
    the helpers this file imports for itself: importlib, typing's names)."""
    own = {n for n in globals() if n.startswith("__") and n.endswith("__")}
    packages = {
        n
        for n, v in globals().items()
        if isinstance(v, ModuleType) and v.__name__.startswith("host.")
    }
    return sorted({*__all__, *own, *packages})
