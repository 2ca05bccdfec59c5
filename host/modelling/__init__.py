"""Stage 6, the model: the error model as named physical terms, and how well it explains the data.

Data in: a session's records. Out: fits, residuals, diagnoses, noise figures.

- ``model`` — terms, dataset and noise model, the least-squares fit.
- ``diagnose`` — where the model fails and which missing term explains it.
- ``turning`` — the accelerometer while the cube turns: the lever arm, the moving blocks, the hand.
- ``scenarios`` — simulated sessions each hiding one effect, and what the workbench finds.
- ``allan`` — Allan deviation and the noise figures read from it.
- ``noise`` — a recording's noise, the planner and the noise file.
"""
