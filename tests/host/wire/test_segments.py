"""The counters' rules (host/wire/segments.py): wrap, reset, loss; the array twin equals the
frame-by-frame tracker on any sequence of frames."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.wire.frames import IMU_FIELDS, IMU_SAMPLE, TYPES
from host.wire.protocol_gen import ENUMS
from host.wire.segments import SEQ_MOD, T_US_MOD, SegmentTracker, segments

SPEC = Path(__file__).resolve().parents[3] / "protocol" / "spec.json"


def run_tracker(seq: list[int], t_us: list[int | None]) -> tuple[list[bool], list[int]]:
    tr = SegmentTracker()
    out = [tr.update(q, t) for q, t in zip(seq, t_us, strict=True)]
    return [r for r, _ in out], [g for _, g in out]


def run_twin(seq: list[int], t_us: list[int | None]) -> tuple[list[bool], list[int]]:
    imu_idx = np.array([i for i, t in enumerate(t_us) if t is not None], dtype=np.int64)
    t = np.array([x for x in t_us if x is not None], dtype=np.int64)
    reset, gaps = segments(np.array(seq, dtype=np.int64), imu_idx, t)
    return reset.tolist(), gaps.tolist()


def test_wraps_are_steps_forward_not_resets() -> None:
    seq = [SEQ_MOD - 2, SEQ_MOD - 1, 0, 1]
    t = [T_US_MOD - 40_000, T_US_MOD - 20_000, 0, 20_000]
    assert run_tracker(seq, t) == ([False] * 4, [0] * 4)
    assert run_twin(seq, t) == ([False] * 4, [0] * 4)


def test_a_gap_is_lost_frames_and_a_step_back_is_a_reset() -> None:
    # frames: first, next, 3 lost, seq repeated, seq back, t back, next
    seq = [10, 11, 15, 15, 7, 8, 9]
    t = [100, 200, 300, 400, 500, 50, 60]
    want = ([False, False, False, True, True, True, False], [0, 0, 3, 0, 0, 0, 0])
    assert run_tracker(seq, t) == want
    assert run_twin(seq, t) == want


def test_other_frames_have_no_time_and_a_seq_reset_forgets_the_last_time() -> None:
    # frame 2 is not a sample; after the seq reset at 3, t 100 is not compared with 900
    seq = [5, 6, 7, 0, 1]
    t: list[int | None] = [800, 900, None, 100, 200]
    want = ([False, False, False, True, False], [0] * 5)
    assert run_tracker(seq, t) == want
    assert run_twin(seq, t) == want


def test_the_tracker_counts_resets_and_losses() -> None:
    tr = SegmentTracker()
    for q, t in [(1, 10), (4, 20), (2, 30), (3, 5)]:
        tr.update(q, t)
    assert (tr.resets, tr.lost_frames) == (2, 2)


# steps chosen to hit every rule often: next, small gaps, repeats, huge jumps, wraps
_seq_steps = st.one_of(
    st.just(1), st.integers(0, 5), st.integers(SEQ_MOD // 2 - 2, SEQ_MOD // 2 + 2),
    st.integers(0, SEQ_MOD - 1),
)  # fmt: skip
_t_steps = st.one_of(
    st.just(20_000), st.integers(0, 100_000), st.integers(T_US_MOD // 2 - 2, T_US_MOD // 2 + 2),
    st.integers(0, T_US_MOD - 1),
)  # fmt: skip


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(
    st.integers(0, SEQ_MOD - 1),
    st.integers(0, T_US_MOD - 1),
    st.lists(st.tuples(_seq_steps, _t_steps, st.booleans()), max_size=60),
)
def test_the_array_twin_equals_the_tracker(seq0: int, t0: int, steps: list) -> None:
    seq, t_us = [seq0], [t0]
    q, t = seq0, t0
    for dq, dt, is_imu in steps:
        q = (q + dq) % SEQ_MOD
        seq.append(q)
        if is_imu:
            t = (t + dt) % T_US_MOD
            t_us.append(t)
        else:
            t_us.append(None)
    assert run_twin(seq, t_us) == run_tracker(seq, t_us)


@pytest.mark.slow
def test_flag_bits_come_from_the_spec() -> None:
    """No ``flags & 1`` in host/: a flag bit is a name from spec.json's sample_flags."""
    import ast
    from pathlib import Path

    host = Path(__file__).resolve().parents[3] / "host"
    found = []
    for path in host.rglob("*.py"):
        if path.name == "protocol_gen.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd | ast.BitOr):
                sides = (node.left, node.right)
                text = " ".join(ast.unparse(x) for x in sides)
                if "flag" in text and any(isinstance(x, ast.Constant) for x in sides):
                    found.append(f"{path.name}:{node.lineno}: {ast.unparse(node)}")
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant):
                names = [t.id for t in node.targets if isinstance(t, ast.Name)]
                spec_names = set(ENUMS["sample_flags"]) | set(TYPES)
                if spec_names & set(names):
                    found.append(f"{path.name}:{node.lineno}: {names[0]} = {node.value.value}")
    assert found == []


def test_message_types_and_sample_fields_come_from_the_spec() -> None:
    imu = next(m for m in json.loads(SPEC.read_text())["messages"] if m["name"] == "IMU_SAMPLE")
    assert IMU_SAMPLE == imu["type"] == TYPES["IMU_SAMPLE"]
    assert IMU_FIELDS == tuple(f[0] for f in imu["fields"] if f[0] not in ("t_us", "flags"))
