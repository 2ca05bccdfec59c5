"""The virtual bench: a known truth to test against (our own simulator is not evidence).

Beside the stages, not in the data's path: it produces what a real board and operator would.

- ``truth`` — every sensor error term, and the sensor model.
- ``physics`` — the cube, hand turns, gravity, Earth rate, room, clocks.
- ``sim`` — the simulator: a running sensor, hand turns, motion schedules, frame streams.
- ``operator`` — the virtual operator: carries out the program's hints (place, turn), faults.
- ``cube`` — a cube that carries several boards: one operator's hand for all of them, each
  board's place (its lever arm and mounting) from the cube and its slot.
- ``plan`` — simulated sessions: a plan of records, simulated as the program records them.
- ``firmware`` — the virtual firmware: host command bytes in, device frame bytes out (what
  ``sim://`` runs behind its port).
- ``options`` — the simulator's URL options, one parser for ``sim://`` and ``emu://``.
- ``linksim`` — USB/UART latency, for the clock estimator.
- ``emulator`` — the real firmware ELF in simavr against an MPU-6000 model, and its logs.
- ``stimulus`` — what the emulated MPU-6000 senses: stimulus files, and the simulator feeding
  a running emulator.
- ``build`` — the one firmware build (``make -C firmware``: flashing and the emulator use it)
  and the emulator's own build, with the toolchain check.
- ``noise`` — long static recordings with known noise.
"""
