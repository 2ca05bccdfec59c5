"""Stage 3, time: device counters -> host time.

Data in: each frame's ``seq`` and each sample's ``t_us`` with arrival times, split into
segments between board resets by the wire's counter rules (:mod:`host.wire.segments`). Out:
device time unwrapped and mapped to host time.

- ``clock`` — unwrap, and the minimum-delay device->host clock map (method.md eq. 1), live on
  a sliding window.
- ``timeline`` — a capture's samples mapped: segments between resets, each with its clock map
  fitted in windows (whole or streaming, the same map), losses and missed samples.
"""
