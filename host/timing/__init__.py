"""Stage 3, time: device counters -> segments -> host time.

Data in: each frame's ``seq`` and each sample's ``t_us`` with arrival times. Out: segments
between board resets, losses, device time unwrapped and mapped to host time.

- ``segments`` — the one owner of the counters' rules: wrap, reset and loss of ``seq`` and
  ``t_us`` (frame by frame, and a numpy twin proven equal).
- ``clock`` — unwrap, and the minimum-delay device->host clock map (live and offline),
  method.md eq. 1.
"""
