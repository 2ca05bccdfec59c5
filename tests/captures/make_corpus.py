#!/usr/bin/env python3
"""Write the golden corpus: one clean capture and deliberately damaged copies of it.

    python tests/captures/make_corpus.py [--source CLEAN.bin]

The clean source is ``emu_clean.bin``: bytes the real firmware sent through the emulated board
(re-recorded and checked by tests/emulator/test_emu_link.py); ``clean.bin`` is a copy of it.

Each BAD_*.bin is the clean stream damaged in one known way; ``corpus.json`` records what a
correct decoder must report for it, derived from the damage itself (which frames were hit,
how many bytes were added), never from running the decoder. tests/host/wire/test_frames_corpus.py
decodes every file with both decoder paths and checks them against it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from host.wire.frames import crc16, encode_frame  # noqa: E402
from host.wire.stream import StreamDecoder  # noqa: E402


def frames_of(clean: bytes) -> list[bytes]:
    """Split a clean stream into its frames (the clean stream must decode without loss)."""
    d = StreamDecoder()
    out = [raw for raw, _ in d.feed_raw(clean) + d.flush()]
    assert d.stats.bytes_discarded == 0 and d.stats.crc_errors == 0, d.stats
    return out


def with_seq(frame: bytes, seq: int) -> bytes:
    """The frame with another sequence number (and its CRC redone)."""
    f = bytearray(frame)
    f[4:6] = (seq & 0xFFFF).to_bytes(2, "little")
    f[-2:] = crc16(bytes(f[2:-2])).to_bytes(2, "little")
    return bytes(f)


def expect(frames: int, crc: int = 0, discarded: int = 0, unknown: int = 0, lost: int = 0,
           resets: int = 0) -> dict[str, int]:  # fmt: skip
    return {"frames": frames, "crc_errors": crc, "bytes_discarded": discarded,
            "unknown_types": unknown, "lost_frames": lost, "resets": resets}  # fmt: skip


def build(clean: bytes) -> dict[str, tuple[bytes, dict[str, int], str]]:
    fr = frames_of(clean)
    n = len(fr)
    out: dict[str, tuple[bytes, dict[str, int], str]] = {}
    out["clean.bin"] = (clean, expect(n), "the source stream, undamaged")

    hit = [10, 11, n // 2, n - 2]  # two adjacent frames, one in the middle, one at the end
    b = [bytearray(f) for f in fr]
    for k in hit:
        b[k][8] ^= 0x10  # a payload bit: CRC fails, nothing else changes
    out["BAD_bitflip.bin"] = (
        b"".join(b),
        expect(n - 4, crc=4, discarded=sum(len(fr[k]) for k in hit), lost=4),
        "one payload bit flipped in 4 frames",
    )

    b = [bytearray(f) for f in fr]
    del b[50][10:15]  # 5 bytes dropped inside frame 50: its CRC fails, frame 51 survives
    out["BAD_dropped_bytes.bin"] = (
        b"".join(b),
        expect(n - 1, crc=1, discarded=len(fr[50]) - 5, lost=1),
        "5 bytes dropped inside one frame",
    )

    junk = bytes([0x00, 0x13, 0x37, 0xA5, 0x00, 0xFF, 0x42] * 4)  # holds no A5 5A pair
    b = list(fr)
    b.insert(n // 5, junk)
    out["BAD_inserted_garbage.bin"] = (
        b"".join(b),
        expect(n, discarded=len(junk)),
        "28 bytes of line noise between two frames",
    )

    start = bytes(range(0x10, 0x10 + 40))
    out["BAD_garbage_start.bin"] = (
        start + clean,
        expect(n, discarded=len(start)),
        "the port opened mid-stream: 40 bytes",
    )

    # a false sync whose claimed frame swallows the next real frame: resync must not skip it
    trap = b"\xa5\x5a\x01\x13\x07\x00"
    b = list(fr)
    b.insert(n * 3 // 5, trap)
    out["BAD_false_sync.bin"] = (
        b"".join(b),
        expect(n, crc=1, discarded=len(trap)),
        "a stray sync + plausible header right before a real frame",
    )

    # a newer firmware's frame type: it takes the next seq, and every later frame shifts by one
    k = n * 4 // 5
    unknown = with_seq(b"\xa5\x5a\x70\x03\x00\x00xyz\x00\x00", int.from_bytes(fr[k][4:6], "little"))
    b = fr[:k] + [unknown] + [with_seq(f, int.from_bytes(f[4:6], "little") + 1) for f in fr[k:]]
    out["BAD_unknown_type.bin"] = (
        b"".join(b),
        expect(n + 1, unknown=1),
        "a valid frame of a type this host does not know",
    )

    # the board reset: the stream restarts from its beginning after 500 frames
    reset = b"".join(fr[: n // 2]) + clean
    out["BAD_reset_mid.bin"] = (reset, expect(n // 2 + n, resets=1), "a device reset mid-stream")

    cut = b"".join(fr[:-1]) + fr[-1][:-5]
    out["BAD_truncated_tail.bin"] = (
        cut,
        expect(n - 1, discarded=len(fr[-1]) - 5),
        "the last frame cut short",
    )
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--source", type=Path, default=HERE / "emu_clean.bin")
    args = ap.parse_args()
    clean = args.source.read_bytes()
    table = {}
    for name, (data, counts, what) in build(clean).items():
        (HERE / name).write_bytes(data)
        table[name] = {"damage": what, "expect": counts}
    (HERE / "corpus.json").write_text(json.dumps(table, indent=1) + "\n")
    print(f"wrote {len(table)} files to {HERE}")


if __name__ == "__main__":
    _ = encode_frame  # the clean stream comes from a board; encode_frame builds stand-ins
    main()
