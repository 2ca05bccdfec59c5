"""imu-bench host package: port -> frames -> timestamped samples -> records -> fit -> report."""

__version__ = "0.1.0"
