"""Records, below the model: the record files of one session, the method's constants and the
record checks, and each record's observation of the §2 model (method.md §2-§6).

Data in: record files (``SERIAL_name.txt``). Out: :class:`~host.session.records.Record`,
:class:`~host.session.directory.Session`, checked observations. Imports only ``host.errors``
(and nothing above it): the model, the calibration and the workbench read records from here.

- ``records`` — the record and its text format (parse, format), record names and header keys.
- ``rowtext`` — a record's data rows as text, all at once: printed, read, their time spacing.
- ``directory`` — the session directory: file names, reading and writing record files.
- ``atomic`` — publishing several files together or not at all.
- ``inputs`` — what comes in from outside: the serial rule, JSON read within bounds.
- ``method`` — the method's constants, sign layout, local gravity and per-record quantities.
- ``spacing`` — sample spacing: timing quality, the timing table, integrals over true times.
- ``checks`` — each record checked against the method (orientation, range, turn angle).
- ``observations`` — each record's observation of the §2 model (means, turn integrals, σ).
"""
