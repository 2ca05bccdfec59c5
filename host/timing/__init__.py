"""Stage 3, time: device counters -> host time.

Data in: each frame's ``seq`` and each sample's ``t_us`` with arrival times, split into
segments between board resets by the wire's counter rules (:mod:`host.wire.segments`). Out:
device time unwrapped and mapped to host time.

- ``clock`` — unwrap, and the minimum-delay device->host clock map (live and offline),
  method.md eq. 1.
"""
