"""Stage 6, the model: the error model as named physical terms, and how well it explains the data.

Data in: a session's records. Out: fits, residuals, noise figures (the diagnosis on top of
them is :mod:`host.workbench`).

- ``model`` — terms, dataset and noise model, the least-squares fit.
- ``turning`` — the accelerometer while the cube turns: the lever arm, the moving blocks, the hand.
- ``allan`` — Allan deviation and the noise figures read from it.
- ``noise`` — a recording's noise, the planner and the noise file.
"""
