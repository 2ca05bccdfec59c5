"""Port URL schemes beyond pyserial's own, one module per scheme (``protocol_<scheme>.py``).

pyserial finds them through ``serial.protocol_handler_packages``; importing ``host.link``
registers this package there.
"""
