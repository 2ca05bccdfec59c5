"""Stage 2, time: device timestamps -> host time.

``clock``: unwrap of the 32-bit device microsecond counter, the minimum-delay device->host clock
map (live and offline), method.md eq. 1.
"""
