"""The report lists which sitting each record came from (issue 31, item 1): a session stopped
with Ctrl+C and resumed is two sittings, a record measured again (``--redo``) a third; the
residual table's ``sit`` column gives each record's sitting as the PROCEDURE numbers them,
from the capture its header names, and the PROCEDURE names the records kept aside."""

from __future__ import annotations

import re
from pathlib import Path

from host.dialogue.console import CTRL_C, ScriptedConsole
from host.session.directory import read_session
from tests.host.dialogue.test_flow import LINEAR, Ports, run
from tests.host.dialogue.test_flow import opts as live_opts


def test_a_resumed_session_shows_each_records_sitting(tmp_path: Path) -> None:
    url = f"sim://?seed=5&noise_seed=5&{LINEAR}"
    # sitting 1: the statics asked for, 2 s, x_up and x_dn saved, Ctrl+C during y_up
    keys = ["y", "2\r", " ", "y", " ", "y", " ", CTRL_C]
    first = live_opts(tmp_path, url, serial="R1", out=tmp_path / "R1", yes=False,
                      static_seconds=None, turns=1)  # fmt: skip
    rc, _ = run(first, ScriptedConsole(keys), Ports())
    assert rc == 130
    # sitting 2: --resume measures the rest
    again = live_opts(tmp_path, url, serial="R1", out=tmp_path / "R1", static_seconds=2.0,
                      turns=1, resume=True)  # fmt: skip
    assert run(again, ScriptedConsole(), Ports())[0] in (0, 1)
    # sitting 3: x_dn measured again; the earlier x_dn is moved aside, bytes unchanged
    before = (tmp_path / "R1" / "R1_x_dn.txt").read_bytes()
    redo = live_opts(tmp_path, url, serial="R1", out=tmp_path / "R1", static_seconds=2.0,
                     turns=1, redo=("x_dn",))  # fmt: skip
    rc, report = run(redo, ScriptedConsole(), Ports())
    assert rc in (0, 1)
    assert report == (tmp_path / "R1" / "R1_result.txt").read_text(encoding="utf-8")
    (aside,) = (tmp_path / "R1" / "earlier").iterdir()
    assert (aside / "R1_x_dn.txt").read_bytes() == before

    recs = read_session(tmp_path / "R1").records
    caps = {n: r.meta["capture"] for n, r in recs.items()}
    assert caps["x_up"] == "R1_session.cap" and caps["x_dn"] == "R1_session_3.cap"
    assert set(caps.values()) == {"R1_session.cap", "R1_session_2.cap", "R1_session_3.cap"}

    lines = report.splitlines()
    # the PROCEDURE's legend: sitting number -> its capture
    text = " ".join(ln.strip() for ln in lines)
    legend = dict(re.findall(r"(\d): (R1_session(?:_\d)?\.cap)", text))
    assert "measured in 3 sittings" in text and set(legend.values()) == set(caps.values())
    number = {cap: int(i) for i, cap in legend.items()}
    assert [number[caps[n]] for n in ("x_up", "y_up", "x_dn")] == [1, 2, 3]
    # ... and the record the third sitting replaced, where it is kept
    kept = "Kept aside, not in this result (measured again, or an earlier sitting's):"
    assert f"{kept} earlier/{aside.name}: x_dn" in text

    # the table: one row per record, its sitting from its own header
    head = next(i for i, ln in enumerate(lines) if ln.split()[:3] == ["record", "sit", "at,s"])
    rows = {ln.split()[0]: ln.split() for ln in lines[head + 1 :] if ln.split()[:1] in
            [[n] for n in recs]}  # fmt: skip
    assert set(rows) == set(recs)
    for name, cells in rows.items():
        assert int(cells[1]) == number[caps[name]], (name, cells)
    # in the order measured: sitting by sitting
    order = [ln.split()[0] for ln in lines[head + 1 :] if ln.split()[:1] in [[n] for n in recs]]
    assert order[0] == "x_up" and order[-2:] == ["x_up_2", "x_dn"]
    table = lines[head - 3 : head + 1 + 2 * len(recs)]
    assert max(len(ln) for ln in table) <= 80
