"""The live calibration dialogue (host/dialogue/flow.py) in-process, against the virtual board.

The operator is a :class:`host.dialogue.console.ScriptedConsole` (keys in order; Esc/Ctrl+C are
seen during a measurement) or ``--yes``. The board is ``sim://`` at ``speed=max`` (simulated time
advances as fast as the host reads). Truth comparisons use ``effects=linear,noise`` and
``earth_rate=0``: the other effects (temperature, drift, nonlinearity, lever arm, Earth rate)
are deliberately outside the linear model of method.md §2 and would bias the comparison.
"""

from __future__ import annotations

import contextlib
import io
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from host.board import driver
from host.board.link import open_port
from host.dialogue import flow, options
from host.dialogue.console import CTRL_C, ESC, ScriptedConsole
from host.errors import UserError
from host.session.directory import read_record, read_session
from host.session.records import STATIC_NAMES, TURN_NAMES
from host.wire import protocol_gen as gen
from tests.host.dialogue.flat_options import flat_options

#: every record a default session writes, in the order measured: the closing check last
ALL = (*STATIC_NAMES, *TURN_NAMES, options.CLOSING_NAME)

LINEAR = "speed=max&effects=linear,noise&earth_rate=0"


class Ports:
    """port_factory that remembers the ports it opened (for truth and hints)."""

    def __init__(self, wrap: Any = None) -> None:
        self.opened: list[Any] = []
        self.wrap = wrap

    def __call__(self, url: str) -> Any:
        p = open_port(url)
        self.opened.append(p)
        return self.wrap(p) if self.wrap else p

    @property
    def sim(self) -> Any:
        return self.opened[0]


def opts(tmp_path: Path, url: str, **kw: Any) -> options.DialogueOptions:
    base: dict[str, Any] = dict(
        port=url, serial="S1", out=tmp_path / "S1", static_seconds=10.0, turns=2,
        warmup_s=0.0, yes=True, ready_s=0.0,
    )  # fmt: skip
    base.update(kw)
    return flat_options(**base)


def run(o: options.DialogueOptions, console: ScriptedConsole, ports: Ports) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = flow.run_dialogue(o, console, ports)
    return rc, out.getvalue()


def no_temp_files(d: Path) -> bool:
    return not [p for p in d.iterdir() if p.name.endswith(".tmp") or p.name.startswith(".")]


# --------------------------------------------------------------------------- --yes session


@pytest.fixture(scope="module")
def yes_session(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("yes")
    ports = Ports()
    con = ScriptedConsole()  # no keys at all: --yes must not ask for one
    rc, stdout = run(opts(tmp, f"sim://?seed=3&noise_seed=3&{LINEAR}", json=True), con, ports)
    return dict(rc=rc, stdout=stdout, con=con, ports=ports, out=tmp / "S1")


@pytest.mark.slow
def test_yes_session_writes_every_file(yes_session: dict[str, Any]) -> None:
    out: Path = yes_session["out"]
    names = sorted(p.name for p in out.iterdir())
    expected = sorted(
        [f"S1_{n}.txt" for n in ALL] + ["S1_result.txt", "S1_result.json", "S1_session.cap"]
    )
    assert names == expected
    assert yes_session["rc"] == 0
    assert no_temp_files(out)
    # --json: the result object on stdout, nothing else; the closing check is one more
    # static record of the fit
    d = json.loads(yes_session["stdout"])
    assert d["serial"] == "S1" and d["turns"] == 2 and len(d["records"]) == 13
    # a virtual board never passes for a unit: the JSON, the report's second line and every
    # record's header say so
    assert d["notes"][0].startswith("SIMULATED BOARD sim://")
    # the session ends on the report's path and its verdict, whatever passed or failed
    # (this board's URL is too long for the mark's line: it follows whole on its own)
    url = f"sim://?seed=3&noise_seed=3&{LINEAR}"
    shown = yes_session["con"].text.rstrip("\n").splitlines()
    mark, board, last = shown[-3:]
    assert last == d["verdict"] and last.startswith("PASS" if yes_session["rc"] == 0 else "FAIL")
    assert f"Report: {out / 'S1_result.txt'}" in shown[-5:]
    assert mark == "*** SIMULATED BOARD: not a measurement of a unit ***"
    assert board == f"    {url}"
    report = (out / "S1_result.txt").read_text().splitlines()
    # the verdict heads the report too (the RESULT block sits below the table)
    head = report[: report.index("-" * 80)]  # the report's head: before its first rule
    assert [ln for ln in head if ln.startswith("Verdict: ")] == [f"Verdict: {last} (RESULT below)"]
    assert report[1:3] == [mark, board]
    for name in ALL:
        assert read_record(out / f"S1_{name}.txt").meta["board"].startswith("SIMULATED BOARD sim")


def test_yes_session_records_are_readable_with_metadata(yes_session: dict[str, Any]) -> None:
    out: Path = yes_session["out"]
    for name in STATIC_NAMES + TURN_NAMES:
        rec = read_record(out / f"S1_{name}.txt")
        m = rec.meta
        assert rec.name == name and m["serial"] == "S1"
        assert m["spec_fingerprint"] == f"{driver.HOST_SPEC_FINGERPRINT:#010x}"
        assert m["firmware"] == "0.1.0" and m["gyro_range_dps"] == "250"
        assert m["smplrt_div"] == "19" and m["accel_range_g"] == "2"
        # which sensor: HELLO's identity (the virtual board is a rev D8 unless told otherwise)
        assert (m["who_am_i"], m["product_id"], m["sensor_revision"]) == ("0x68", "0x58", "D8")
        assert m["lost_frames"] == "0" and m["missed_samples"] == "0"
        assert m["self_test"] == "pass" and len(m["self_test_change_pct"].split()) == 6
        assert int(m["host_ns_start_beep"]) <= int(m["host_ns_first_sample"])
        assert 0 <= int(m["device_t_us_start"]) < 2**32
        assert rec.t_ms[0] == 0.0
        dt = np.diff(rec.t_ms)
        # device clock: the sim's sample clock is not exactly 50 Hz, and it shows
        assert np.all(dt > 15) and np.all(dt < 25)
        if name in TURN_NAMES:
            assert m["kind"] == "turn" and m["turns"] == "2" and m["window_s"] == "12"
            assert 11.9 < rec.duration_s < 12.0  # the fixed window, device time
        else:
            assert m["kind"] == "static"
            assert 9.9 < rec.duration_s < 10.0


def test_yes_session_recovers_truth(yes_session: dict[str, Any]) -> None:
    truth = yes_session["ports"].sim.truth.constants()
    got = json.loads(yes_session["stdout"])["constants"]
    tol = {"A0": 3e-3, "G0": 0.01, "GA": 0.005}
    for name, want in truth.items():
        t = tol.get(name[:2], 1e-3)  # scale errors and misalignments: 1e-3
        assert abs(got[name] - want) < t, (name, got[name], want)


def test_yes_session_capture_decodes_to_the_same_samples(yes_session: dict[str, Any]) -> None:
    from host.wire.bulk import decode_file

    result, arrivals = decode_file(yes_session["out"] / "S1_session.cap")
    assert arrivals is not None and result.stats.crc_errors == 0
    rec = read_record(yes_session["out"] / "S1_x_up.txt")
    t0 = int(rec.meta["device_t_us_start"])
    k = int(np.flatnonzero(result.samples["t_us"] == t0)[0])
    ax = result.samples["ax"][k : k + len(rec)] * (9.80665 / 16384.0)
    assert np.allclose(ax, rec.accel[:, 0], atol=6e-5)


def test_yes_session_hints_follow_the_dialogue(yes_session: dict[str, Any]) -> None:
    hints = [(a, kw) for _, a, kw in yes_session["ports"].sim.hints]
    # the closing check puts the cube back on the first attitude
    assert [kw["name"] for a, kw in hints if a == "place"] == [*STATIC_NAMES, STATIC_NAMES[0]]
    turns = [kw for a, kw in hints if a == "turn"]
    assert [(t["axis"], t["direction"]) for t in turns] == [
        (n.split("_")[0], n.split("_")[1]) for n in TURN_NAMES
    ]
    assert all(t["turns"] == 2 and t["window_s"] == 12.0 for t in turns)


@pytest.mark.slow
def test_yes_session_records_carry_session_time(yes_session: dict[str, Any]) -> None:
    """Every live record says when it started (records.TIME_KEYS), from the device clock: the
    start matches the simulated board's time of the operator hint that began it, and the
    workbench reads it (time terms see the whole session, not only each record's own span)."""
    from host.model.dataset import load_dataset

    out: Path = yes_session["out"]
    hint_t = [t for t, a, _ in yes_session["ports"].sim.hints if a in ("place", "turn")]
    names = list(ALL)
    starts = [float(read_record(out / f"S1_{n}.txt").meta["power_on_s"]) for n in names]
    session = [float(read_record(out / f"S1_{n}.txt").meta["session_s"]) for n in names]
    assert len(hint_t) == len(names)
    for n, t0, hint in zip(names, starts, hint_t, strict=True):
        assert hint - 0.05 <= t0 <= hint + 0.5, (n, t0, hint)  # the first sample after the beep
    assert np.all(np.diff(session) > 0) and session[0] >= 0.0
    ds = load_dataset(out)
    assert ds.time_known
    t_end = max(float(s.t_s[-1]) for s in ds.signals)
    assert abs(t_end - (starts[-1] + 10.0)) < 0.5  # the closing check: a 10 s static
    # time_drift on the records alone (no simulator metadata in them): identifiable
    from host.model.fit import fit_model
    from host.model.spec import parse_model
    from host.workbench.candidates import evaluate_candidates

    assert not any(k.startswith("sim") for k in read_record(out / "S1_x_up.txt").meta)
    cands, _ = evaluate_candidates(ds, fit_model(ds, parse_model("base")))
    drift = [c for c in cands if c.term == "time_drift"]
    assert len(drift) == 6 and all(c.identifiable for c in drift), [c.reason for c in drift]
    # the closing check repeats the first attitude at the end: what it adds is drift
    # information — without it the gyro drift is less well determined
    without = load_dataset_without(out, options.CLOSING_NAME)
    c2, _ = evaluate_candidates(without, fit_model(without, parse_model("base")))
    se = {c.label: c.stderr for c in drift}
    se2 = {c.label: c.stderr for c in c2 if c.term == "time_drift"}
    assert all(se[k] < se2[k] for k in se if k.startswith("time_drift:gyro")), (se, se2)
    # and the dialogue showed closing − opening
    assert "Closing − opening" in yes_session["con"].text


def load_dataset_without(directory: Path, name: str) -> Any:
    """The dataset of ``directory``'s session without record ``name``."""
    from host.model.dataset import build_dataset
    from host.session.directory import Session

    s = read_session(directory)
    return build_dataset(Session(s.serial, {k: v for k, v in s.records.items() if k != name}))


# --------------------------------------------------------------------------- scripted dialogue


@pytest.mark.slow
def test_scripted_dialogue_validates_and_repeats(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    keys = ["bad serial!\r", "S7\r", "y", "abc\r", "0.5\r", "3\r"]
    keys += [" ", "n", " ", "y"]  # x_up: repeat once, then save
    keys += [" ", "y"] * 5  # the other five statics
    keys += ["n"]  # no turns
    keys += [" ", "y"]  # the closing check (x_up again), saved; then the results
    con = ScriptedConsole(keys)
    ports = Ports()
    o = opts(tmp_path, f"sim://?seed=5&noise_seed=5&{LINEAR}", serial=None, out=None,
             static_seconds=None,
             turns=None, yes=False)  # fmt: skip
    rc, stdout = run(o, con, ports)
    assert con.keys == []
    text = con.text
    assert "serial number 'bad serial!' (not allowed: ' ' '!')" in text
    assert "give the accumulation time in seconds" in text
    assert "between 1 and 3600" in text
    assert text.count("Measuring x_up:") == 2 and text.count("Measuring x_dn") == 1
    assert text.count(f"Measuring {options.CLOSING_NAME}:") == 1
    assert "Stage 1 constants" in text
    # the default output directory is ./SERIAL/
    out = tmp_path / "S7"
    assert sorted(p.name for p in out.glob("S7_*.txt")) == sorted(
        [f"S7_{n}.txt" for n in (*STATIC_NAMES, options.CLOSING_NAME)] + ["S7_result.txt"]
    )
    assert "TEST REPORT" in stdout and "serial No. S7" in stdout
    # gyro scale was not measured (no turns): the unit fails, exit status 1
    assert rc == 1
    # the saved x_up is the second measurement: its mean is the one shown last
    shown = text.split("x_up:")[-1].split("mean")[1].split()[0]
    assert float(shown) == pytest.approx(read_record(out / "S7_x_up.txt").accel[:, 0].mean(),
                                         abs=1e-4)  # fmt: skip
    places = [kw["name"] for _, a, kw in ports.sim.hints if a == "place"]
    assert places == ["x_up", "x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn", "x_up"]
    assert con.beeps >= 16  # start and end of each of the 8 measurements


def test_esc_aborts_one_measurement_and_ctrl_c_keeps_accepted(tmp_path: Path) -> None:
    keys = ["y", " ", "y"]  # x_up measured and saved
    keys += [" ", ESC]  # x_dn aborted with Esc during the measurement
    keys += [" ", CTRL_C]  # x_dn again, Ctrl+C during the measurement
    con = ScriptedConsole(keys)
    o = opts(tmp_path, f"sim://?seed=6&noise_seed=6&{LINEAR}", yes=False, static_seconds=3.0)
    rc, _ = run(o, con, Ports())
    assert rc == 130
    assert con.text.count("Measuring x_dn") == 2
    assert "Measurement of x_dn aborted (Esc): nothing kept" in con.text
    assert "Aborted (Ctrl+C)" in con.text and "--resume" in con.text
    out = tmp_path / "S1"
    assert sorted(p.name for p in out.glob("*.txt")) == ["S1_x_up.txt"]
    assert read_record(out / "S1_x_up.txt").name == "x_up"
    assert no_temp_files(out)


@pytest.mark.slow
def test_resume_measures_only_the_missing_records(tmp_path: Path) -> None:
    url = f"sim://?seed=8&noise_seed=8&{LINEAR}"
    con = ScriptedConsole(["y", " ", "y", " ", "y", " ", CTRL_C])
    assert run(opts(tmp_path, url, yes=False, static_seconds=3.0), con, Ports())[0] == 130
    out = tmp_path / "S1"
    before = {p.name: p.read_bytes() for p in out.glob("S1_*.txt")}
    assert sorted(before) == ["S1_x_dn.txt", "S1_x_up.txt"]
    con2 = ScriptedConsole()
    ports = Ports()
    rc, _ = run(opts(tmp_path, url, static_seconds=3.0, turns=1, resume=True), con2, ports)
    assert rc in (0, 1)
    assert "Resuming: kept x_up, x_dn" in con2.text
    assert "Measuring x_up:" not in con2.text and "Measuring y_up" in con2.text
    places = [kw["name"] for _, a, kw in ports.sim.hints if a == "place"]
    assert places == ["y_up", "y_dn", "z_up", "z_dn", "x_up"]  # ... and the closing check
    for name, data in before.items():
        assert (out / name).read_bytes() == data
    assert len(list(out.glob("S1_*_*.txt"))) == 13 and (out / "S1_result.json").exists()
    # the first session's capture is kept; the resumed one gets its own file
    assert (out / "S1_session.cap").exists() and (out / "S1_session_2.cap").exists()


@pytest.mark.slow
def test_resume_refuses_other_turns(tmp_path: Path) -> None:
    url = f"sim://?seed=9&noise_seed=9&{LINEAR}"
    o = opts(tmp_path, url, static_seconds=2.0, turns=1)
    assert run(o, ScriptedConsole(), Ports())[0] in (0, 1)
    with pytest.raises(UserError, match="--turns 2 but the kept turn records have 1"):
        run(opts(tmp_path, url, static_seconds=2.0, turns=2, resume=True), ScriptedConsole(),
            Ports())  # fmt: skip


# --------------------------------------------------------------------------- link trouble


@pytest.mark.slow
def test_board_vanishing_mid_measurement(tmp_path: Path) -> None:
    ports = Ports()
    con = ScriptedConsole()
    url = f"sim://?seed=4&noise_seed=4&{LINEAR}&fault=pull_cable@25"
    rc, _ = run(opts(tmp_path, url, turns=1), con, ports)
    assert rc in (0, 1)
    text = con.text
    assert "the board disconnected" in text
    assert "The measurement in progress is discarded; accepted records are kept." in text
    assert "The board is back" in text
    before = text.split("the board disconnected")[0]
    saved_before = [n for n in STATIC_NAMES if f"S1_{n}.txt" in before]
    assert saved_before, "the cable should come out after some record was accepted"
    cut = STATIC_NAMES[len(saved_before)]  # the measurement the cable interrupted
    places = [kw["name"] for _, a, kw in ports.sim.hints if a == "place"]
    assert places[-1] == STATIC_NAMES[0]  # the closing check, last
    places = places[:-1]
    assert places.count(cut) == 2  # measured again after the reconnect
    assert all(places.count(n) == 1 for n in saved_before)  # accepted ones kept, not redone
    out = tmp_path / "S1"
    assert len(list(out.glob("S1_*_*.txt"))) == 13
    assert read_record(out / f"S1_{cut}.txt").duration_s > 9.9


class DroppingPort:
    """Wraps a sim port, reads at most one frame's bytes at a time and drops every 30th
    read: a link that loses a frame now and then, however the port chunks its output."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.reads = 0

    @property
    def in_waiting(self) -> int:
        return min(int(self.inner.in_waiting), driver.IMU_FRAME_BYTES)

    def read(self, n: int = 1) -> bytes:
        data = self.inner.read(n)
        self.reads += 1
        return b"" if self.reads % 30 == 0 else data

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def test_lost_samples_are_counted_and_offered_for_repeat(tmp_path: Path) -> None:
    con = ScriptedConsole(["y", " ", "n", CTRL_C])  # save anyway, then stop
    o = opts(tmp_path, f"sim://?seed=10&noise_seed=10&{LINEAR}", yes=False, static_seconds=5.0)
    rc, _ = run(o, con, Ports(wrap=DroppingPort))
    assert rc == 130
    assert "samples lost in x_up" in con.text
    assert "Repeat <Y> or save anyway <N>?" in con.text
    rec = read_record(tmp_path / "S1" / "S1_x_up.txt")
    lost = int(rec.meta["lost_frames"])
    assert lost > 0 and float(rec.meta["lost_percent"]) > 1.0
    # the device clock shows the holes the lost frames left
    assert int(np.sum(np.diff(rec.t_ms) > 30)) > 0


def test_yes_gives_up_after_repeated_losses(tmp_path: Path) -> None:
    o = opts(tmp_path, f"sim://?seed=10&noise_seed=10&{LINEAR}", static_seconds=2.0)
    with pytest.raises(UserError, match="still wrong after 3 attempts"):
        run(o, ScriptedConsole(), Ports(wrap=DroppingPort))
    assert not list((tmp_path / "S1").glob("*.txt"))


def test_wrong_firmware_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from host.board import hello

    monkeypatch.setattr(hello, "SPEC_FINGERPRINT", 0x12345678)  # this host, as another spec
    v = gen.PROTOCOL_VERSION
    with pytest.raises(
        UserError, match=rf"firmware speaks protocol {v} .*this host protocol {v} .*host flash"
    ):
        run(opts(tmp_path, f"sim://?seed=1&noise_seed=1&{LINEAR}"), ScriptedConsole(), Ports())


def test_silent_port_at_connect(tmp_path: Path) -> None:
    class Silent:
        timeout = 0.05
        in_waiting = 0

        def read(self, n: int = 1) -> bytes:
            time.sleep(0.05)
            return b""

        def write(self, data: bytes) -> int:
            return len(data)

        def close(self) -> None:
            pass

    t0 = time.monotonic()
    o = opts(tmp_path, "/dev/ttyFAKE", hello_timeout_s=1.5)
    with pytest.raises(UserError, match="no HELLO from the board on /dev/ttyFAKE within 1.5 s"):
        flow.run_dialogue(o, ScriptedConsole(), lambda url: Silent())  # type: ignore[arg-type,return-value]
    assert time.monotonic() - t0 < 3.0


class GoesSilent:
    """Wraps a sim port; after ``after`` frames' worth of bytes it sends nothing (firmware
    hung) until the port is opened again (the DTR reset of a re-open restarts the board)."""

    def __init__(self, inner: Any, after: int = 400) -> None:
        self.inner = inner
        self.after = after * driver.IMU_FRAME_BYTES  # bytes
        self.got = 0
        self.silent_since: float | None = None

    @property
    def in_waiting(self) -> int:
        return 0 if self.silent_since is not None else int(self.inner.in_waiting)

    def read(self, n: int = 1) -> bytes:
        if self.silent_since is None and self.after <= self.got < self.after + 10**9:
            self.silent_since = time.monotonic()
        if self.silent_since is not None:
            time.sleep(0.05)
            return b""
        data = bytes(self.inner.read(n))
        self.got += len(data)
        return data

    def open(self) -> None:
        self.inner.open()
        self.silent_since = None
        self.got = -(10**12)  # once is enough

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


@pytest.mark.slow
def test_silent_board_mid_session_is_reported_and_recovered(tmp_path: Path) -> None:
    seen: list[float] = []
    wrapped: list[GoesSilent] = []

    class Spy(ScriptedConsole):
        def say(self, text: str = "") -> None:
            if "no data from the board" in text and wrapped[0].silent_since is not None:
                seen.append(time.monotonic() - wrapped[0].silent_since)
            super().say(text)

    def wrap(p: Any) -> GoesSilent:
        wrapped.append(GoesSilent(p))
        return wrapped[0]

    con = Spy()
    rc, _ = run(opts(tmp_path, f"sim://?seed=12&noise_seed=12&{LINEAR}", static_seconds=3.0,
                turns=1), con,
                Ports(wrap=wrap))  # fmt: skip
    assert rc in (0, 1)
    assert len(seen) == 1 and 1.9 < seen[0] < 3.0  # the message within ~2 s of the silence
    assert "The board is back" in con.text
    assert len(list((tmp_path / "S1").glob("S1_*_*.txt"))) == 13  # with the closing check


# --------------------------------------------------------------------------- pieces


def test_yes_needs_serial_and_static_seconds(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="--yes needs --serial"):
        flow.run_dialogue(opts(tmp_path, "sim://", serial=None), ScriptedConsole())
    with pytest.raises(UserError, match="--yes needs --static-seconds"):
        run(opts(tmp_path, f"sim://?{LINEAR}", static_seconds=None), ScriptedConsole(), Ports())


# --------------------------------------------------------------------------- emulated board


def _emu_available() -> bool:
    import importlib.util
    import shutil

    try:
        spec = importlib.util.find_spec("host.transports.protocol_emu")
    except ImportError:
        spec = None
    return spec is not None and shutil.which("simavr") is not None


@pytest.mark.emulator
@pytest.mark.skipif(
    not _emu_available(), reason="emu:// (host/transports/protocol_emu.py) or simavr missing"
)
@pytest.mark.slow
def test_emulated_board(tmp_path: Path) -> None:
    """The real firmware in simavr: HELLO passes the spec check and a measurement has the
    firmware's rate and no losses; with a virtual operator, a whole --yes session."""
    board = driver.Board("emu://", hello_timeout_s=30.0)
    try:
        info = board.connect()
        assert info.spec_fingerprint == driver.HOST_SPEC_FINGERPRINT
        acq = board.acquire(2.0)
        assert acq.lost == 0
        assert abs(len(acq.t_us) - 2.0 * info.rate_hz) <= 0.02 * 2.0 * info.rate_hz + 2
        assert np.all(np.diff(acq.t_us) > 0)
        has_operator = board.has_operator
    finally:
        board.close()
    if not has_operator:
        return  # nobody to place the cube: the dialogue itself is covered with sim://
    rc, stdout = run(opts(tmp_path, "emu://", static_seconds=2.0, turns=1, json=True,
                          hello_timeout_s=30.0), ScriptedConsole(), Ports())  # fmt: skip
    assert rc in (0, 1)
    assert len(json.loads(stdout)["records"]) == 13
    # session time from the firmware's own clock, in measurement order
    starts = [float(read_record(tmp_path / "S1" / f"S1_{n}.txt").meta["power_on_s"]) for n in ALL]
    assert np.all(np.diff(starts) > 1.9), starts


@pytest.mark.slow
def test_the_warm_up_is_recorded_as_a_record_of_its_own(tmp_path: Path) -> None:
    ports = Ports()
    rc, stdout = run(
        opts(tmp_path, f"sim://?seed=5&noise_seed=5&{LINEAR}", warmup_s=3.0, static_seconds=3.0),
        ScriptedConsole(),
        ports,
    )
    assert rc in (0, 1), stdout
    warm = read_record(tmp_path / "S1" / "S1_warmup.txt")
    assert warm.meta["kind"] == "warmup" and warm.meta["serial"] == "S1"
    assert 2.5 < warm.duration_s < 3.5 and len(warm) > 100
    assert np.all(np.isfinite(warm.temp)) and "power_on_s" in warm.meta
    # not a calibration record: the session read back holds only the plan's twelve
    assert "warmup" not in read_session(tmp_path / "S1").records


@pytest.mark.slow
def test_no_closing_leaves_the_closing_check_out(tmp_path: Path) -> None:
    """--no-closing: no x_up_2, no closing prompt; the printed resume command keeps it."""
    url = f"sim://?seed=13&noise_seed=13&{LINEAR}"
    con = ScriptedConsole()
    rc, _ = run(opts(tmp_path, url, static_seconds=2.0, turns=1, closing=False), con, Ports())
    assert rc in (0, 1)
    out = tmp_path / "S1"
    assert sorted(p.stem.removeprefix("S1_") for p in out.glob("S1_*_*.txt")) == sorted(
        (*STATIC_NAMES, *TURN_NAMES)
    )
    assert "Closing check" not in con.text
    o = opts(tmp_path, url, closing=False)
    assert "--no-closing" in o.command("S1", static_seconds=2.0, turns=1, port=url)
    assert "--no-closing" not in opts(tmp_path, url).command(
        "S1", static_seconds=2.0, turns=1, port=url
    )
