"""Stage 6, the model engine: the error model as named physical terms, the dataset a session
gives, the noise model and the one weighted least-squares fit (method.md §2, §4, §8).

Data in: a session's records (:mod:`host.session`). Out: fits, residuals, predictions and noise
figures, for the calibration (:mod:`host.calib`) and the workbench above it. Imports only
``host.errors``, ``host.wire`` and ``host.session``.

- ``geometry`` — placement: the cube's pose from its up vector, the plate's axes at a heading, the
  operator's words for a placement.
- ``plate`` — the plate's tilt from the circle the turns' rests (or their motion) draw; headings
  records lack.
- ``turn_motion`` — the tilt as each turn sees it from every sample of its motion, jointly with
  the lever arm, the seating and the hand as variance components (turns without inner rests).
- ``turn_axis`` — the axis each turn was made about (a tilted seat named and corrected).
- ``turn_angle`` — a turn's angle and reference rate: ±360°·n between two rests, an unknown of
  the fit when it starts or ends in motion.
- ``remeasured`` — a face measured twice: the accelerometer's bias change between the two, and
  whether the turns' leans are that change rather than tilted turn axes; without a static
  record after the turns, whether their leans are one step no static record sees.
- ``signals`` — a record's reference signals (force, rate, temperature, time, heading); units.
- ``terms`` — the :class:`Term` type and the ``@term`` / ``@nonlinear_term`` decorators.
- ``catalogue`` — the built-in terms (``base`` = method.md §2, and the §8 effects), plausibility.
- ``loader`` — users' term files joining the catalogue.
- ``spec`` — the model spec grammar (``base,temperature_bias:gyro:x``) and model terms.
- ``noise`` — the noise model: block noise, the bias-instability floor from the records' own
  samples, a step inside a static record that its samples show (an effect, not noise).
- ``variance`` — named variance components: the turns' angle error and wobble, each measured
  with its own degrees of freedom.
- ``components`` — the turn-angle and wobble components, and a hand-held pose's rate and hold,
  estimated jointly with a fit (REML-style, from its residuals, with their own degrees of
  freedom).
- ``dataset`` — the dataset of a session: the records' signals, rows, noise and whitening.
- ``rows`` — one builder per kind of row (block means, turn integrals, still moments, moving
  blocks) and the turn rows' own noise (seating, the hand).
- ``whitening`` — the rows' covariance per record and channel, whitened exactly.
- ``design`` — each term's columns of the design matrix.
- ``solve`` — the weighted least squares of a model over a dataset's rows; χ² alone.
- ``fit`` — the fit, its public result types and the residual tables.
- ``channels`` — the fit's per-channel statistics (the moves' rows a channel of their own) and
  the factor each parameter's standard error is widened by.
- ``stats`` — χ² tail probabilities, the uncertainty policy (``stderr_scale``).
- ``loo`` — leave-one-record-out prediction.
- ``turning`` — the accelerometer while the cube turns: lever arm, moving blocks, the hand.
- ``poses`` — poses without a cube: the first estimates of the accelerometer, the gyro and each
  pose's attitude, the frame's convention when no record has a set attitude, a move's exact
  kinematics and its rows.
- ``moves`` — the moves' rows in a dataset, each read by every gyro channel and two poses.
- ``allan`` — Allan deviation and the noise figures read from it.
- ``recording`` — a recording's noise, the planner and the noise file.
"""
