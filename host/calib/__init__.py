"""Stage 4-5, calibration: records -> closed-form fit -> result -> report.

``records`` (the record files of a session directory), ``calibration`` (method constants, the
closed-form calibration, the versioned result), ``report`` (the test report and result files),
``exporting`` (the result as other tools' parameters and files).
"""
