"""The commands of ``python -m host``, one module each (thin: parse, call the library, print).

- ``calibrate`` — ``calibrate``: live (the dialogue) or ``--from-dir``.
- ``capture`` — ``capture``: record a port's bytes with host read times.
- ``decode`` — ``decode``: a capture or raw bytes as samples, CSV/JSON lines, statistics.
- ``flash`` — ``flash``: build, flash and check the firmware.
- ``importing`` — ``import``: foreign data into records.
- ``exporting`` — ``export``: the result in another tool's format.
- ``model`` — ``model`` and ``demo``: the workbench.
- ``noise`` — ``noise``: Allan deviation and noise figures of a recording.
- ``thermal`` — ``thermal``: bias against temperature.
"""
