"""Stage 4a, records measured live: the calibration dialogue (method.md §5).

Data in: a board (:mod:`host.board.driver`) and the operator's answers. Out: record files, then
the results through :mod:`host.calib.publish`.

- ``live`` — the dialogue: the operator guided through the poses and turns, each measurement
  checked and written when accepted; resume, redo, reconnect.
- ``console`` — the terminal the operator answers at (and a scripted one for tests), and the
  questions asked on it.
"""
