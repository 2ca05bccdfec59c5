"""Stage 1, the port: a board on a serial port or URL, and what runs on it.

Data in: bytes from a port. Out: timestamped reads and decoded frames, HELLO, measurements.

- ``link`` — open a port by URL (a device, ``sim://``, ``emu://``, ``replay://``), timestamped
  reads, every byte into a capture, commands out.
- ``hello`` — the one wait for HELLO and the one check of the spec fingerprint.
- ``driver`` — the board driver (:class:`~host.board.driver.Board`): HELLO, commands, clock
  feeding, reconnects, counts to SI units.
- ``acquisition`` — one measurement on device time: the window cut at the start beep's PONG,
  losses, resets, a stalled sensor, the operator's Esc.
- ``flash`` — flash the firmware (built by :mod:`host.bench.build`) with avrdude through the
  bootloader, on the port its transport serves, and check its HELLO.
"""
