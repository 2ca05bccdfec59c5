"""Stage 4b, records from elsewhere: foreign files become the project's records.

Data in: a logger's columns, an imucal session, a capture. Out: record files with timing quality
(:mod:`host.session.spacing`).

- ``importing`` — column files, imucal sessions and captures as one stream of SI samples.
- ``stillness`` — where the stream rests (noise floors from the data, sample-exact rests) and
  the attitude of a rest.
- ``reading`` — the session read as a person would: visits to faces, whole turns, the plan's
  choice of statics, the warm-up apart, each choice with its reason.
- ``poses`` — a session that is not the method's read as poses and moves: every rest a pose,
  the motion between two a move.
- ``gaps`` — where a stream is not read across: gaps in its time, values out of any sensor's
  range.
- ``segmentation`` — unit checks, the found segments, and the records built from them.
- ``labels`` — the printed table and the labels file that corrects the cut.
"""
