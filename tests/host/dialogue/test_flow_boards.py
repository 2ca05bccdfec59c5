"""A sitting of several boards (host/dialogue/flow.py, recorder.py, boards.py): one dialogue,
every record measured on every board at once, each board's session of its own; a board that
leaves the sitting; --resume of a sitting. In-process against ``sim://`` at ``speed=max``
(see test_flow.py), each port its own virtual operator given the same hints."""

from __future__ import annotations

import dataclasses
import json
import shlex
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import serial

from host.board.link import open_port
from host.dialogue import options
from host.dialogue.console import ScriptedConsole
from host.errors import ResumableError
from host.session.directory import read_record
from host.session.records import STATIC_NAMES, TURN_NAMES
from tests.host.cli.cli_run import command_after
from tests.host.dialogue.flat_options import options_of
from tests.host.dialogue.test_flow import LINEAR, run
from tests.host.dialogue.test_flow import opts as live_opts

ALL = (*STATIC_NAMES, *TURN_NAMES, options.CLOSING_NAME)


class Ports:
    """port_factory that remembers each port it opened by URL; ``vanish`` (URL → simulated
    s): that board's port fails for good once its simulated time passes (a cable pulled, a
    hub gone): reads raise and it cannot be opened again."""

    def __init__(self, vanish: dict[str, float] | None = None) -> None:
        self.opened: dict[str, Any] = {}
        self.vanish = vanish or {}
        self.gone: set[str] = set()

    def __call__(self, url: str) -> Any:
        if url in self.gone:
            raise serial.SerialException(f"could not open port {url}: no such device")
        p = open_port(url)
        self.opened[url] = p
        return _Vanishing(p, self, url) if url in self.vanish else p


class _Vanishing:
    def __init__(self, port: Any, ports: Ports, url: str) -> None:
        self._port, self._ports, self._url = port, ports, url

    def __getattr__(self, name: str) -> Any:
        return getattr(self._port, name)

    def _check(self) -> None:
        if self._url in self._ports.gone or self._port.sim_time > self._ports.vanish[self._url]:
            self._ports.gone.add(self._url)
            raise serial.SerialException("device disconnected")

    @property
    def in_waiting(self) -> int:
        self._check()
        return int(self._port.in_waiting)

    def read(self, size: int = 1) -> bytes:
        self._check()
        return bytes(self._port.read(size))

    def write(self, data: bytes) -> int:
        self._check()
        return int(self._port.write(data))

    def open(self) -> None:  # the device is gone: it cannot be opened again
        self._check()
        self._port.open()


def urls(seeds: list[int], noise: int = 0) -> list[str]:
    """One unit per seed, its noise drawn from ``noise_seed`` = seed + ``noise``."""
    return [f"sim://?seed={s}&noise_seed={s + noise}&{LINEAR}" for s in seeds]


def sitting(tmp: Path, seeds: list[int], noise: int = 0, **kw: Any) -> options.DialogueOptions:
    """Options of a sitting of one board per seed, serials U<seed>, all under ``tmp``."""
    u = urls(seeds, noise)
    more = tuple((url, f"U{s}") for url, s in zip(u[1:], seeds[1:], strict=True))
    base: dict[str, Any] = dict(serial=f"U{seeds[0]}", out=tmp, static_seconds=3.0, turns=1)
    return dataclasses.replace(live_opts(tmp, u[0], **{**base, **kw}), more_boards=more)


def result(d: Path, serial: str) -> dict[str, Any]:
    return dict(json.loads((d / serial / f"{serial}_result.json").read_text()))


def pulls(got: dict[str, Any], truth: dict[str, float]) -> list[tuple[str, float]]:
    """(name, (fitted − truth)/σ) of every determined parameter the truth names."""
    out = []
    for p in got["parameters"]:
        if p["name"] in truth and p["stderr"] and p["stderr"] > 0:
            out.append((p["name"], (p["value"] - truth[p["name"]]) / p["stderr"]))
    return out


# --------------------------------------------------------------------------- four boards


@pytest.fixture(scope="module")
def four(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("four")
    ports = Ports()
    con = ScriptedConsole()  # --yes: no key at all
    rc, _ = run(sitting(tmp, [21, 22, 23, 24]), con, ports)
    return dict(rc=rc, con=con, ports=ports, out=tmp, seeds=[21, 22, 23, 24])


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_four_boards_write_four_complete_sessions(four: dict[str, Any]) -> None:
    """Each board: every record of the method and the closing check, its report, result
    and capture in its own directory; every record carries its own serial and port; the
    dialogue asked each placement once (one prompt, four boards)."""
    for s, url in zip(four["seeds"], urls(four["seeds"]), strict=True):
        d: Path = four["out"] / f"U{s}"
        names = sorted(p.name for p in d.iterdir())
        assert names == sorted(
            [f"U{s}_{n}.txt" for n in ALL] + [f"U{s}_result.txt", f"U{s}_result.json",
                                               f"U{s}_session.cap"]
        )  # fmt: skip
        for n in ALL:
            m = read_record(d / f"U{s}_{n}.txt").meta
            assert (m["serial"], m["port"]) == (f"U{s}", url)
    text = four["con"].text
    assert text.count("Put the cube") == len(ALL)  # each face, turn and the closing: once
    for s in four["seeds"]:
        assert f"Results of U{s}:" in text


@pytest.mark.slow
def test_four_boards_each_recover_their_own_unit(four: dict[str, Any]) -> None:
    """Each board's constants against its own simulated unit, in units of their σ: a record
    of one board filed under another's serial would be many σ off (the units differ by
    far more than their σ)."""
    all_pulls = []
    for s in four["seeds"]:
        url = urls(four["seeds"])[four["seeds"].index(s)]
        truth = four["ports"].opened[url].truth.constants()
        got = pulls(result(four["out"], f"U{s}"), truth)
        assert len(got) >= 20
        worst = max(got, key=lambda p: abs(p[1]))
        assert abs(worst[1]) < 5.0, (s, worst)
        all_pulls += [z for _, z in got]
    assert 0.4 < float(np.std(all_pulls)) < 1.8, np.std(all_pulls)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_board_of_the_sitting_agrees_with_a_sitting_of_its_own(
    four: dict[str, Any], tmp_path: Path
) -> None:
    """The third unit calibrated alone (its own noise): its constants and those of the
    sitting of four agree within their σ (√(σ₁² + σ₂²), 4.5 of it at most over every parameter)."""
    s = four["seeds"][2]
    o = sitting(tmp_path, [s], noise=100, out=tmp_path / f"U{s}")  # the unit, other noise
    rc, _ = run(o, ScriptedConsole(), Ports())
    alone = {p["name"]: p for p in result(tmp_path, f"U{s}")["parameters"]}
    sat = {p["name"]: p for p in result(four["out"], f"U{s}")["parameters"]}
    z = [
        (n, (sat[n]["value"] - a["value"]) / np.hypot(sat[n]["stderr"], a["stderr"]))
        for n, a in alone.items()
        if a["stderr"] and sat[n]["stderr"]
    ]
    assert len(z) >= 20
    assert max(abs(v) for _, v in z) < 4.5, max(z, key=lambda p: abs(p[1]))


# --------------------------------------------------------------------------- options


def test_several_ports_need_a_serial_each(tmp_path: Path) -> None:
    from host.__main__ import build_parser
    from host.cli.calibrate import dialogue_options
    from host.errors import UserError

    parser, _ = build_parser()
    for argv, words in (
        (["--port", "sim://", "--port", "sim://?seed=2", "--serial", "A"], "2 --port but 1"),
        (["--serial", "A", "--serial", "B"], "2 --serial but 0 --port"),
    ):
        ns = parser.parse_args(["calibrate", *argv])
        with pytest.raises(UserError, match=words):
            dialogue_options(ns)
    o = options_of("python3 -m host calibrate --port sim:// --serial A --port sim:// --serial A")
    with pytest.raises(UserError, match="--serial A is given twice"):
        o.check()
    o = options_of(
        "python3 -m host calibrate --port P1 --serial A --port P2 --serial B --plan adaptive"
    )
    with pytest.raises(UserError, match="--plan adaptive takes one --port"):
        o.check()


# --------------------------------------------------------------------------- dropping out


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_board_that_vanishes_leaves_the_others_complete(tmp_path: Path) -> None:
    """The second of three boards is unplugged for good during the turns: it is named with
    the record it was lost at and its own resume command; its accepted records stay; the
    other two sessions are complete; the exit status is 1 (a session is incomplete)."""
    u = urls([31, 32, 33])
    ports = Ports(vanish={u[1]: 40.0})  # simulated s: past the statics (6 × 3 s + waits)
    con = ScriptedConsole()
    o = sitting(tmp_path, [31, 32, 33], reconnect_timeout_s=1.0)
    rc, _ = run(o, con, ports)
    assert rc == 1
    text = con.text
    lost = [ln for ln in text.splitlines() if "board U32 lost at record" in ln]
    assert len(lost) == 1, text[-2000:]
    at = lost[0].split("lost at record ")[1].split()[0]
    assert at in ALL
    said = " ".join(text.replace("\\\n", " ").split())  # the command, over its \\ lines
    alone = said.split("resume it with: ")[1]
    assert alone.startswith("python3 -m host calibrate --port") and "--resume" in alone
    assert "--serial U32" in alone and f"--out {tmp_path / 'U32'}" in alone
    kept = sorted(p.name for p in (tmp_path / "U32").glob("U32_*.txt"))
    assert f"U32_{at}.txt" not in kept and "U32_x_up.txt" in kept
    assert not (tmp_path / "U32" / "U32_result.json").exists()
    for s in (31, 33):
        got = result(tmp_path, f"U{s}")
        assert len(got["records"]) == len(ALL)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_board_lost_during_the_self_test_leaves_the_others_complete(tmp_path: Path) -> None:
    """The second of three boards is unplugged for good during its self-test: it is waited
    for (1 s), then named as lost during the self-test with its own resume command; the third
    board's self-test still runs, and the first and third sessions are complete, every record
    saying the self-test passed; the exit status is 1 (a session is incomplete)."""
    u = urls([35, 36, 37])
    ports = Ports(vanish={u[1]: 0.8})  # simulated s: its HELLO by 0.2 s, its self-test to 1.6 s
    con = ScriptedConsole()
    rc, _ = run(sitting(tmp_path, [35, 36, 37], reconnect_timeout_s=1.0), con, ports)
    assert rc == 1
    said = " ".join(con.text.replace("\\\n", " ").split())
    assert "U36: the board on " in said and "is gone" in said  # waited for, as in a record
    why = "the board did not come back within 1 s"
    assert f"board U36 lost during the self-test ({why})" in said, con.text[:3000]
    assert said.count("board U36 lost") == 1 and "lost at record" not in said
    alone = said.split("resume it with: ")[1]
    assert alone.startswith("python3 -m host calibrate --port") and "--serial U36" in alone
    assert said.index("U37: MPU-6000 self-test") > said.index("board U36 lost")
    assert not list((tmp_path / "U36").glob("U36_*.txt"))
    assert not (tmp_path / "U36" / "U36_result.json").exists()
    for s in (35, 37):
        assert len(result(tmp_path, f"U{s}")["records"]) == len(ALL)
        for n in ALL:
            assert read_record(tmp_path / f"U{s}" / f"U{s}_{n}.txt").meta["self_test"] == "pass"
    assert "left the sitting, their sessions incomplete: U36" in said


@pytest.mark.slow
def test_a_board_back_during_its_self_test_runs_it_again_and_stays(tmp_path: Path) -> None:
    """The second board's cable is pulled during its self-test and the board comes back
    (``fault=pull_cable``): it alone is waited for, its self-test is run again and passes,
    and both sessions are complete."""
    o = sitting(tmp_path, [38, 39], reconnect_timeout_s=10.0)
    o = dataclasses.replace(o, more_boards=((urls([39])[0] + "&fault=pull_cable@0.8", "U39"),))
    con = ScriptedConsole()
    rc, _ = run(o, con, Ports())
    assert rc in (0, 1)
    mine = con.text.split("U39:\n", 1)[1].split("Measure the 6 static")[0]
    assert "!!! the self-test is not recorded" in mine and "The board is back" in mine
    assert mine.count("MPU-6000 self-test: PASS") == 1 and "lost" not in con.text
    for s in (38, 39):
        got = result(tmp_path, f"U{s}")
        assert len(got["records"]) == len(ALL) and got["self_test"] == "pass"


@pytest.mark.slow
def test_a_sitting_whose_every_board_is_lost_in_the_self_test_ends_naming_each(
    tmp_path: Path,
) -> None:
    """Both boards unplugged for good during their self-tests: each is named as lost during
    the self-test, then the sitting ends with an error that says so, no result written."""
    u = urls([45, 46])
    ports = Ports(vanish={u[0]: 0.8, u[1]: 0.8})
    con = ScriptedConsole()
    o = sitting(tmp_path, [45, 46], reconnect_timeout_s=1.0)
    with pytest.raises(ResumableError, match="every board left the sitting during the self-test"):
        run(o, con, ports)
    said = " ".join(con.text.split())
    for s in (45, 46):
        assert f"board U{s} lost during the self-test" in said
    assert not list(tmp_path.rglob("*_result.json"))


def test_a_board_that_cannot_be_opened_leaves_the_sitting_at_the_start(tmp_path: Path) -> None:
    """The second board's port does not exist: it is named at the start with the reason and
    its own command, it leaves no directory of records, the first board's session is
    complete and the exit status is 1 (a session is incomplete)."""
    o = sitting(tmp_path, [41, 42])
    missing = str(tmp_path / "no-such-port")
    o = dataclasses.replace(o, more_boards=((missing, "U42"),))
    con = ScriptedConsole()
    rc, _ = run(o, con, Ports())
    assert rc == 1
    said = " ".join(con.text.replace("\\\n", " ").split())
    assert "board U42 lost at the start (cannot open" in said and missing in said
    alone = said.split("resume it with: ")[1]
    assert alone.startswith("python3 -m host calibrate --port") and "--serial U42" in alone
    assert not list(tmp_path.glob("U42/U42_*"))
    assert len(result(tmp_path, "U41")["records"]) == len(ALL)
    assert "left the sitting, their sessions incomplete: U42" in said


def test_a_sitting_whose_every_board_cannot_be_opened_ends_naming_each(tmp_path: Path) -> None:
    """No port of the sitting opens: each board is named, then the sitting ends with an
    error that says so, no result written."""
    o = sitting(tmp_path, [43, 44])
    gone = [str(tmp_path / f"no-port-{k}") for k in (1, 2)]
    o = dataclasses.replace(o, port=gone[0], more_boards=((gone[1], "U44"),))
    con = ScriptedConsole()
    with pytest.raises(ResumableError, match="every board left the sitting at the start"):
        run(o, con, Ports())
    said = " ".join(con.text.split())
    assert "board U43 lost at the start" in said and "board U44 lost at the start" in said
    assert not list(tmp_path.rglob("*_result.json"))


# --------------------------------------------------------------------------- resume


class CtrlCAfter(ScriptedConsole):
    """--yes, and Ctrl+C once ``line`` has been said (between two boards' saves)."""

    def __init__(self, line: str) -> None:
        super().__init__()
        self.line = line

    def say(self, text: str = "") -> None:
        super().say(text)
        if text == self.line:
            raise KeyboardInterrupt


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_resume_of_an_interrupted_sitting_completes_every_board(tmp_path: Path) -> None:
    """Ctrl+C after the first board saved y_dn and before the second did: the printed
    command (read back as a shell would) resumes the sitting, which measures y_dn on both
    boards but saves it only on the board that lacked it, then the rest: both complete."""
    o = sitting(tmp_path, [41, 42])
    con = CtrlCAfter(f"Saved {tmp_path / 'U41' / 'U41_y_dn.txt'}")
    rc, _ = run(o, con, Ports())
    assert rc == 130
    assert (tmp_path / "U41" / "U41_y_dn.txt").exists()
    assert not (tmp_path / "U42" / "U42_y_dn.txt").exists()
    first_y_dn = (tmp_path / "U41" / "U41_y_dn.txt").read_bytes()
    assert "continue the sitting" in " ".join(con.text.split())
    resumed = options_of(shlex.join(command_after(con.text)))
    assert resumed.files.resume and [p for p, _ in resumed.more_boards] == urls([42])
    con2 = ScriptedConsole()
    rc, _ = run(resumed, con2, Ports())
    assert rc in (0, 1)
    assert (tmp_path / "U41" / "U41_y_dn.txt").read_bytes() == first_y_dn  # kept, not redone
    for s in (41, 42):
        got = result(tmp_path, f"U{s}")
        assert sorted(got["records"]) == sorted(ALL), (s, got["records"])


# --------------------------------------------------------------------------- one cube


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_boards_in_one_cube_each_calibrate_their_own_mounting(tmp_path: Path) -> None:
    """Two boards at two places of one virtual cube (one operator's motion, each its own
    mounting misalignment): each board's constants recover its own unit and mounting within
    5σ, and their accelerometer misalignments differ by far more than their σ — nothing of
    one board's fit is shared with the other's."""
    u = [f"sim://?seed={s}&noise_seed={s}&cube=3&slot={k}&{LINEAR}" for k, s in enumerate((61, 62))]
    o = dataclasses.replace(
        live_opts(tmp_path, u[0], serial="C61", out=tmp_path, static_seconds=3.0, turns=1),
        more_boards=((u[1], "C62"),),
    )
    ports = Ports()
    rc, _ = run(o, ScriptedConsole(), ports)
    assert rc in (0, 1)
    fitted = []
    for url, s in zip(u, ("C61", "C62"), strict=True):
        got = result(tmp_path, s)
        z = pulls(got, ports.opened[url].truth.constants())
        assert len(z) >= 20 and max(abs(v) for _, v in z) < 5.0, (
            s,
            max(z, key=lambda p: abs(p[1])),
        )
        fitted.append({p["name"]: p for p in got["parameters"]})
    a, b = (f["Axy"] for f in fitted)
    assert abs(a["value"] - b["value"]) > 5 * np.hypot(a["stderr"], b["stderr"])
