"""The archive: every calibration kept by serial, and the statistics of many calibrations.

- ``entry`` — one archived calibration (:class:`~host.archive.entry.Entry`), read from the files
  ``calibrate`` writes (``SERIAL_result.json``, the report, the records) with their hashes.
- ``schema`` — the tables and the versioned migrations (one schema for SQLite and PostgreSQL).
- ``store`` — :class:`~host.archive.store.Archive`: open by URL, add (idempotent, never an
  update), list, show, the parameter tables the statistics read.
- ``stats`` — pure functions over numpy arrays: repeatability (χ² against the predicted σ),
  drift, lot summary and outliers, control-chart run rules, bench comparison by Eₙ, each with
  its stated family-wise false-alarm rate.
- ``checks`` — the questions of ``python3 -m host archive`` answered from the store with
  ``stats`` (trend, repeat, drift, lot, control charts, check-bench); their text on the
  command line is the command's (:mod:`host.cli.archive_text`).
- ``charts`` — the page's charts as inline SVG, a pure function of the points: time on x,
  the parameter in its unit on y, both axes titled, a trend's ± U band, control limits.
- ``page`` — the self-contained HTML page (``archive report --html``) with those charts.
- ``export`` — CSV (and Parquet when pyarrow is installed) for the user's own analysis.
"""
