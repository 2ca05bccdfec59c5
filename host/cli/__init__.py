"""The commands of ``python -m host`` (thin: parse, call the library, print).

``calibrate`` (``calibrate``: live or ``--from-dir``), ``importing`` (``import``),
``exporting`` (``export``), ``model`` (``model`` and ``demo``).
"""
