"""The archive: every calibration kept by serial, and the statistics of many calibrations.

- ``entry`` — one archived calibration (:class:`~host.archive.entry.Entry`), read from the files
  ``calibrate`` writes (``SERIAL_result.json``, the report, the records) with their hashes.
- ``schema`` — the tables and the versioned migrations (one schema for SQLite and PostgreSQL).
- ``store`` — :class:`~host.archive.store.Archive`: open by URL, add (idempotent, never an
  update), list, show, the parameter tables the statistics read.
"""
