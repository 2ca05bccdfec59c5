"""The model workbench: the error model as named physical terms.

``model`` (terms, dataset and noise model, the least-squares fit), ``diagnose`` (where the model
fails and which missing term explains it), ``scenarios`` (a simulated session with one hidden
effect, and what the workbench makes of it).
"""
