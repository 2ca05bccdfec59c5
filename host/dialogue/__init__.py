"""The live calibration dialogue (method.md §5): the operator guided through the poses and
turns on a board, the records written as they are measured.

``live`` (the dialogue and, for now, the board driver it uses), ``console`` (the terminal the
operator answers at, and a scripted one for tests).
"""
