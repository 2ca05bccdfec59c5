"""Stage 4a, records measured live: the calibration dialogue (method.md §5).

Data in: a board (:mod:`host.board.driver`) and the operator's answers. Out: record files, then
the results through :mod:`host.calib.publish`.

- ``flow`` — the dialogue's sequence: the faces, the turns, the closing check, the results;
  resume, redo, reconnect (:func:`host.dialogue.flow.run_dialogue`).
- ``recorder`` — the faces, the closing check and the turns: each record's prompt, acquisition,
  checks and Save/repeat, and waiting for a board that vanished.
- ``options`` — the dialogue's options and the operator's answers: parsed, checked before any
  I/O, and written back as the command line that continues a session.
- ``boards`` — the boards of a sitting, one unit each (its board, serial, directory and
  records), and what a sitting of several shows and decides about them.
- ``sitting`` — the sitting's output directory: one process writes it at a time, and the files
  of an earlier sitting are moved aside, never replaced.
- ``measurement`` — one measurement: its acquisition through the board driver, the record and
  its header, the checks of that record.
- ``adaptive`` — ``--plan adaptive``: the records the workbench's adaptive engine asks for
  (faces and turn pairs axis by axis, each until it has enough, then the planner's) until every
  value's σ/tolerance meets the target.
- ``poses`` — ``--plan poses`` / ``poses16``: no cube, the unit held still in the attitudes the
  planner (or the 16-position scheme) asks for, each move and rest cut into a move and a pose
  record, until every value the poses determine meets the target.
- ``screens`` — what is shown: prompts, the progress line, the summaries of records and stages.
- ``console`` — the terminal the operator answers at (and a scripted one for tests), and the
  questions asked on it.
"""
