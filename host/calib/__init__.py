"""Stage 5, calibration: records -> checks -> fit -> result -> report.

Data in: a session (the record files of one sitting, :mod:`host.session`). Out: the result
(JSON, v3) and the signed test report, and the result in other tools' formats.

- ``calibration`` — the calibration through the one fit, the closed form beside it.
- ``publish`` — compute and write: the one step from records to the published result (live and
  ``--from-dir``).
- ``values`` — the parts of a result: parameters, fit quality, residuals, verified values.
- ``result`` — the result: a frozen record of values.
- ``decision`` — the decision rule: a value's mark (+, −, ?) from its value, U and tolerance,
  by guarded or simple acceptance, and the rule in words.
- ``verdict`` — the verdict policy: which values pass, whether the result does (INCOMPLETE when
  records of the method are missing), when a PASS is conditional.
- ``result_text`` — the result's words: its verdict line, one-line summary and the list of the
  method's records.
- ``codec`` — the result's files: JSON v3 written, v1–v3 read (v1's §7 names among them).
- ``provenance`` — where the records came from: simulated or a unit, the equipment, the chip
  temperatures, the plan, when measured and in how many sittings (from the record headers).
- ``applying`` — ``apply`` to raw samples and held-out ``verify``.
- ``report`` — the test report (method.md §7) as sections, and the result files.
- ``report_lines`` — the text report's lines: 80 columns, wrapped, pages numbered.
- ``report_tables`` — the report's tables of numbers: residuals, noise, bias consistency,
  verification.
- ``certificate`` — what makes the report a certificate (ISO/IEC 17025 §7.8): the report
  number, laboratory, customer, method, dates, traceability, signatory.
- ``bench_file`` — the laboratory's bench file (TOML, data only), checked on load.
- ``commands`` — the shell commands a report or a screen names, laid out to be pasted.
- ``report_pdf`` — the certificate as a typeset PDF: tables and residual plots (``calibrate
  --pdf``).
- ``thermal`` — bias against temperature: the thermal result, ``apply_thermal``, corrected records.
- ``thermal_fit`` — the bias(T) fit from warm-up, static and chamber records.
- ``exporting`` — the result as other tools' parameters and files.
- ``kalibr`` — Kalibr's IMU noise configuration from a noise file (not from a result).
"""
