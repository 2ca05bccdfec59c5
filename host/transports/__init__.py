"""Port URL schemes beyond pyserial's own, one thin adapter per scheme (``protocol_<scheme>.py``).

- ``protocol_sim`` — ``sim://``: the virtual bench's firmware (:mod:`host.bench`) behind a port.
- ``protocol_emu`` — ``emu://``: the emulated board (:mod:`host.bench.emulator`) behind a port.
- ``protocol_replay`` — ``replay://``: a capture file played back.
- ``flashing`` — the device a flasher opens for a port name or URL (a scheme's adapter serves
  one: ``emu://?flash=PATH``), so that flashing never names a scheme.

pyserial finds them through ``serial.protocol_handler_packages``; importing
:mod:`host.board.link` registers this package there.
"""
