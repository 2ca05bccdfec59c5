"""imu-bench host package: port -> frames -> timestamped samples -> records -> fit -> report.

One subpackage per stage of the data's journey (docs/layout.md):

- :mod:`host.wire` — the spec table (generated), frame codecs and decoders, capture files, counts
- :mod:`host.timing` — device time: unwrap, the device→host clock map
- :mod:`host.board` — ports and URLs (link), flashing and the firmware build
- :mod:`host.dialogue` — the live calibration dialogue (method.md §5) and its console
- :mod:`host.ingest` — foreign data in: column files, imucal sessions, captures -> records
- :mod:`host.session` — records, the session directory, the method's constants, record checks
- :mod:`host.calib` — the closed-form calibration and its result, the report, export
- :mod:`host.model` — the engine: terms, dataset, noise model, the fit, statistics
- :mod:`host.workbench` — the model workbench: candidates, scan, verdict, ladder
- :mod:`host.bench` — the virtual bench: truth, physics, simulator, link simulator, emulator
- :mod:`host.transports` — pyserial URL adapters (``sim://``, ``emu://``, ``replay://``)
- :mod:`host.cli` — the commands of ``python -m host``
"""

__version__ = "0.1.0"
