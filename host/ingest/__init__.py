"""Foreign data in: files from elsewhere become the project's records.

``importing`` (column files, imucal sessions and captures as one stream of SI samples),
``segmentation`` (cutting a stream into the plan's records by stillness and turns; timing quality).
"""
