"""Stage 4b, records from elsewhere: foreign files become the project's records.

Data in: a logger's columns, an imucal session, a capture. Out: record files with timing quality.

- ``importing`` — column files, imucal sessions and captures as one stream of SI samples.
- ``segmentation`` — cutting a stream into the plan's records by stillness and turns; timing
  quality; the labels file that corrects the cut.
"""
