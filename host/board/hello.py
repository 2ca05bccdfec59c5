"""HELLO: waiting for the frame a board sends when it starts, and checking the spec it speaks.

The firmware sends HELLO after every reset (opening the port resets an APM 2.6) and again when
asked with GET_CONFIG (protocol/messages.md). Every part of the host that needs a board's HELLO
waits with :func:`wait_for_hello` — the flash command after flashing, the live board driver at
connect and reconnect — and checks its spec fingerprint (and a hex file's, before flashing)
with :func:`check_spec`.
"""

from __future__ import annotations

from collections.abc import Callable

from serial.serialutil import Timeout

from host.board.link import Link, LinkTimeout
from host.errors import UserError
from host.wire.frames import Frame
from host.wire.protocol_gen import PROTOCOL_VERSION, SPEC_FINGERPRINT

#: without HELLO for this long, ask for it once with GET_CONFIG, s
ASK_AFTER_S = 1.0


class SpecMismatch(UserError):
    """The firmware (or a firmware file) speaks another protocol spec than this host."""


def check_spec(
    fingerprint: int, *, who: str, remedy: str, protocol_version: int | None = None
) -> None:
    """SpecMismatch unless ``fingerprint`` is this host's spec fingerprint. ``who`` names the
    speaker ("firmware", a hex file's path), ``remedy`` what to do; ``protocol_version`` is
    named beside the spec when known (HELLO states it)."""
    if fingerprint == SPEC_FINGERPRINT:
        return
    if protocol_version is None:
        theirs, ours = f"spec {fingerprint:#010x}", f"spec {SPEC_FINGERPRINT:#010x}"
    else:
        theirs = f"protocol {protocol_version} (spec {fingerprint:#010x})"
        ours = f"protocol {PROTOCOL_VERSION} (spec {SPEC_FINGERPRINT:#010x})"
    raise SpecMismatch(f"{who} speaks {theirs}, this host {ours}: {remedy}")


def wait_for_hello(
    link: Link,
    timeout_s: float,
    *,
    read: Callable[[], list[tuple[int, Frame]]] | None = None,
    ask_after_s: float | None = ASK_AFTER_S,
    port_name: str | None = None,
) -> tuple[int, Frame, bool]:
    """Read until a HELLO frame arrives: ``(arrival ns, HELLO, anything heard)``.

    ``read``: one read of the port as ``[(arrival_ns, frame), ...]`` (default: the link's own;
    the board driver passes its reader, which also feeds the clock). Silence shorter than
    ``timeout_s`` is waited out (a bootloader says nothing for ~1 s). ``ask_after_s``: send
    GET_CONFIG once if no HELLO came by then (None: never ask — right after flashing, bytes
    sent to the bootloader could keep it from starting the firmware). LinkTimeout after
    ``timeout_s`` wall seconds (naming ``port_name`` if given); LinkLost if the port vanishes.
    """
    if read is None:

        def read() -> list[tuple[int, Frame]]:
            t_ns, data = link.read_chunk()
            return [(t_ns, f) for f in link.decoder.feed(data)] if data else []

    timeout = Timeout(timeout_s)
    ask = Timeout(ask_after_s) if ask_after_s is not None else None
    heard = False
    while not timeout.expired():
        try:
            batch = read()
        except LinkTimeout:  # silent for a while: a bootloader, or no firmware
            batch = []
        else:
            heard = heard or bool(batch)
        for t_ns, f in batch:
            if f.name == "HELLO":
                return t_ns, f, heard
        if ask is not None and ask.expired():
            link.send("GET_CONFIG")
            ask = None
    where = f" on {port_name}" if port_name else ""
    raise LinkTimeout(
        f"no HELLO from the board{where} within {timeout_s:g} s"
        + ("" if heard else " (it sends nothing)")
    )
