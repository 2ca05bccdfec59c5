"""imu-bench host package: port -> frames -> timestamped samples -> records -> fit -> report.

One subpackage per stage of the data's journey (README, "What is here"):

- :mod:`host.wire` — the spec table (generated), frame codecs and decoders, capture files, counts
- :mod:`host.timing` — device time: unwrap, the device→host clock map
- :mod:`host.board` — ports and URLs (link), flashing and the firmware build
- :mod:`host.dialogue` — the live calibration dialogue (method.md §5) and its console
- :mod:`host.ingest` — foreign data in: column files, imucal sessions, captures -> records
- :mod:`host.session` — records, the session directory, the method's constants, record checks
- :mod:`host.calib` — the closed-form calibration and its result, the report, export
- :mod:`host.modelling` — the model workbench: terms, fit, diagnosis
- :mod:`host.bench` — the virtual bench: truth, physics, simulator, link simulator, emulator
- :mod:`host.transports` — pyserial URL adapters (``sim://``, ``emu://``, ``replay://``)
- :mod:`host.cli` — the commands of ``python -m host``

The flat module names of earlier versions (``host.calibration``, ``host.frames``, ...) still
import, as the same module objects, with a :class:`DeprecationWarning` naming the new place
(:data:`MOVED`).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from types import CodeType, ModuleType

__version__ = "0.1.0"

#: old module name -> its new place (the layout by stages; issue 14)
MOVED: dict[str, str] = {
    "host.protocol_gen": "host.wire.protocol_gen",
    "host.frames": "host.wire.frames",
    "host.capture": "host.wire.capture",
    "host.sensor": "host.wire.sensor",
    "host.clock": "host.timing.clock",
    "host.link": "host.board.link",
    "host.flash": "host.board.flash",
    "host.records": "host.session.records",
    "host.calibration": "host.calib.calibration",
    "host.report": "host.calib.report",
    "host.model": "host.modelling.model",
    "host.sim": "host.bench.sim",
    "host.sim_physics": "host.bench.physics",
    "host.sim_truth": "host.bench.truth",
    "host.linksim": "host.bench.linksim",
    "host.emulator": "host.bench.emulator",
    "host.operator": "host.dialogue.console",
    "host.calibrate_cli": "host.cli.calibrate",
    "host.model_cli": "host.cli.model",
    "host.importing": "host.ingest.importing",
    "host.segmentation": "host.ingest.segmentation",
    "host.import_cli": "host.cli.importing",
    "host.exporting": "host.calib.exporting",
    "host.export_cli": "host.cli.exporting",
}

#: old module entry points (``python -m OLD``) -> the ``python -m host`` command they were
MOVED_COMMANDS: dict[str, str] = {}


class _MovedModuleLoader(importlib.abc.Loader):
    """Imports the module's new name and puts that very module under the old name too."""

    def __init__(self, new: str) -> None:
        self.new = new

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None  # a throwaway module; exec_module replaces it in sys.modules

    def exec_module(self, module: ModuleType) -> None:
        old = module.__name__
        warnings.warn(
            f"{old} has moved to {self.new}; import it from there (the old name will go)",
            DeprecationWarning,
            stacklevel=2,  # warnings skips importlib's frames: this points at the importer
        )
        # importlib returns sys.modules[old] after exec_module: the real module, one object
        sys.modules[old] = importlib.import_module(self.new)

    def get_code(self, fullname: str) -> CodeType | None:
        """For ``python -m OLD_NAME``: the new module's code, or the command it was."""
        print(f"note: python -m {fullname} is deprecated; use python -m host", file=sys.stderr)
        if fullname in MOVED_COMMANDS:
            run = "import sys\nfrom host.__main__ import main\n"
            run += f"sys.exit(main([{MOVED_COMMANDS[fullname]!r}, *sys.argv[1:]]))\n"
            return compile(run, fullname, "exec")
        spec = importlib.util.find_spec(self.new)
        loader = spec.loader if spec is not None else None
        get_code = getattr(loader, "get_code", None)
        return get_code(self.new) if get_code is not None else None


class _MovedModuleFinder(importlib.abc.MetaPathFinder):
    """Finds the old flat module names of :data:`MOVED`.

    First on ``sys.meta_path``, so that a stale file of an old name (an editable install mapping
    ``host`` to an older checkout) is never imported beside the moved module.
    """

    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        new = MOVED.get(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _MovedModuleLoader(new))


if not any(isinstance(f, _MovedModuleFinder) for f in sys.meta_path):
    sys.meta_path.insert(0, _MovedModuleFinder())
