"""The library a program calls: the names ``import host`` gives (docs/python-api.md).

- ``functions`` — one function per job, each taking what a user has in hand (a directory, a
  result file, numpy arrays) and returning the bench's own objects: ``read_session``,
  ``calibrate``, ``write_result``, ``load_result``, ``apply``, ``diagnose``, ``export``.

``host/__init__.py`` imports them only when one is first used, so ``python3 -m host`` starts
without them.
"""
