"""``python3 -m host capture`` (host/cli/capture.py): what it says it recorded is what the file
holds, however Ctrl+C falls."""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
from pathlib import Path

import pytest

from host.board.link import Link
from host.wire.bulk import decode_bulk


@pytest.mark.timeout(60)
@pytest.mark.parametrize("after_reads", [3, 7, 20])
def test_ctrl_c_right_after_a_chunk_is_written_still_counts_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, after_reads: int
) -> None:
    """Ctrl+C landing between writing a chunk to the file and counting its samples made the
    printed count one chunk short of the file (seen as 325 counted, 326 in the file)."""
    from host.__main__ import main

    real = Link.read_chunk
    reads = {"n": 0}

    def read_then_ctrl_c(self: Link) -> tuple[int, bytes]:
        t_ns, data = real(self)  # the chunk is in the capture file now
        if data:
            reads["n"] += 1
            if reads["n"] == after_reads:
                os.kill(os.getpid(), signal.SIGINT)  # the worst moment for it
        return t_ns, data

    monkeypatch.setattr(Link, "read_chunk", read_then_ctrl_c)
    cap = tmp_path / "s.cap"
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["capture", "--port", "sim://?speed=max", str(cap), "--seconds", "30"])
    assert rc == 130, err.getvalue()  # Ctrl+C: 130, as in calibrate
    stats = json.loads(out.getvalue())
    in_file = len(decode_bulk(cap.read_bytes()).samples)
    assert stats["samples"] == in_file > 0, (stats, in_file)
    assert f"holds {in_file} samples" in err.getvalue()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored
