"""The model workbench: how well the error model explains the records, and what it misses.

Data in: a fitted model and its dataset (:mod:`host.model`). Out: candidates, the
residual scan, the verdict, the refits and their words. Never imports the calibration.

- ``candidates`` — every catalogue term not in the model tried on top of the fit, Holm-corrected,
  confounded and explained-by groups.
- ``absorbed`` — the yardstick for a candidate whose signal a variance component takes up (a gyro
  scale asymmetry in the turn angle): the component estimated without it.
- ``scan`` — the residuals against every signal (temperature, time, inputs, their squares).
- ``steps`` — a step in time placed to the sample with its ± and size; two steps on a channel.
- ``equals`` — groups of equals: candidates and signals the records cannot tell apart, and the
  records that would.
- ``evidence`` — a term against the best step on its channel, each fitted with the other: a
  catalogue term is recommended only when it explains what the step does not.
- ``sinks`` — an implausible variance component is a finding: what it absorbed, found on the
  yardstick without it; the gyro at the turns' rests, where a bias change is read directly.
- ``verdict`` — the whole diagnosis: compare, where it fails, what is missing, the verdict.
- ``nuisance`` — the records' own unknowns tested against the shared parameter they stand for
  (each static's own view of the plate's tilt against the plate's one tilt).
- ``ladder`` — add a term (before → after) and the stepwise ladder of models, which prunes.
- ``text`` — the words for people: diagnosis, addition, ladder, the catalogue, a demo's outcome.
- ``planner`` — the record to measure next: every candidate added as it would be measured, the
  fit's σ/tolerance it leaves, ranked per minute of the operator's time.
- ``adaptive`` — measure until enough: a first plan, then the planner's next record until every
  value's σ/tolerance meets a target, through one measuring callable.
- ``stopping`` — records that stop when they have enough: a face when the σ of its mean (serial
  correlation counted) meets a target, turn pairs when the gyro scale does.
- ``least_time`` — the least operator time any plan of faces, 45° attitudes and turns needs for
  a precision: the rest the g-sensitivities need, from the fit's own information.
- ``separate`` — the record that tells two explanations apart: the Δχ² (noncentrality) it buys
  between them per minute of the operator's time.
- ``scenarios`` — simulated sessions each hiding one effect, and what the workbench finds.
"""
