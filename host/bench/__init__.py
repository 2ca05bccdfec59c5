"""The virtual bench: a known truth to test against (our own simulator is not evidence).

``truth`` (every sensor error term), ``physics`` (the cube, hand turns, gravity, room, clocks),
``sim`` (the simulator: poses, turns, records), ``options`` (the simulator's URL options, one
parser for ``sim://`` and ``emu://``), ``linksim`` (USB/UART latency for the clock estimator),
``emulator`` (the real firmware ELF in simavr against an MPU-6000 model).
"""
