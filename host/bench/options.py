"""The virtual bench's URL options: one parser for ``sim://`` and ``emu://``.

Both schemes drive the same physics simulator (:mod:`host.bench.sim`), so the options that set it
up are read here, once, with the same meaning and checks:

``seed`` (draws the unit: its truth and its room; same seed, same sensor on both schemes; not
given, a ``serial=`` draws it: :func:`unit_seed`, else 0), ``noise_seed`` (draws the noise and the
operator's hand; not given, every session draws them afresh, as a real unit's repeat would),
``serial`` (the unit's serial number, which the dialogue adds from ``--serial``), ``speed``
(``realtime`` | ``N`` | ``max``; the default differs: ``realtime`` on ``sim://``, ``max`` on
``emu://``), ``truth`` (``random`` | ``ideal``), ``effects``,
``operator`` (``auto`` | ``manual``), ``latitude``, ``tilt``, ``earth_rate``,
``operator_fault=NAME[@K]`` (may repeat: the K-th ``place`` or ``turn`` goes wrong on purpose)
``revision`` (the MPU-6000's PRODUCT_ID: ``D8`` by default, ``C4``/``C5`` count half the
accelerometer LSB/g; a name or a number such as ``0x55``; :func:`parse_revision`) and
``self_test`` (``pass`` by default: the part's self-test response is within a few % of its
factory trim; ``fail``: accelerometer Y 35 % above, gyroscope Z 45 % below it), ``cube=C`` and
``slot=K`` (the board is at place K, 0–7, of cube C, held by one operator with the other boards
of that cube: :mod:`host.bench.cube`; without ``cube`` the bench is the board's alone).

``fault=`` keeps the meaning it always had on each scheme: on ``sim://`` the operator's (and
``pull_cable@S``, the cable's) faults — the old spelling of ``operator_fault`` —, on ``emu://``
the *sensor's* faults (``protocol_emu``). Options only one scheme has stay in its module.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from host.wire.sensor import DEFAULT_PRODUCT_ID, product_id_of

if TYPE_CHECKING:
    from host.bench.physics import Bench, Environment
    from host.bench.truth import SensorTruth

#: ``speed=N`` bounds: slower starves the session of samples, faster only spins the CPU
#: (``speed=max`` is the fast mode: time advances as bytes are read)
SPEED_RANGE = (0.1, 1000.0)
#: ``clock_ppm`` bound: a ceramic resonator is off by ±5000 ppm, a crystal by ±100
CLOCK_PPM_MAX = 10_000.0
#: ``sample_clock`` bound (relative): the MPU-6000's own oscillator is within ±5 %
SAMPLE_CLOCK_MAX = 0.05
#: ``cube=`` bound (a seed's word)
CUBE_MAX = 2**32 - 1
#: the options read here (a scheme adds its own)
KEYS = (
    "seed", "noise_seed", "serial", "speed", "truth", "effects", "operator", "latitude", "tilt",
    "earth_rate", "operator_fault", "chamber", "revision", "self_test", "cube", "slot",
)  # fmt: skip
#: ``sim://``'s cable fault (``fault=pull_cable@S``: S simulated s after opening, default 5)
CABLE_FAULT = "pull_cable"


class OptionError(ValueError):
    """A bad option value; ``key`` names the option (its text is the message)."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key


def bounded(name: str, text: str, lo: float, hi: float) -> float:
    """``text`` as a finite float in [lo, hi]; ValueError naming the option otherwise."""
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{name}={text!r} is not a number") from None
    if not lo <= v <= hi:  # also false for nan
        raise ValueError(f"{name}={text!r} is outside {lo:g} … {hi:g}")
    return v


def unit_seed(serial: str) -> int:
    """The unit seed of a serial number: the first 8 bytes of its UTF-8 SHA-256 (the same on
    every run and machine, unlike Python's ``hash``), so that each serial is its own unit."""
    return int.from_bytes(hashlib.sha256(serial.encode()).digest()[:8], "big")


def with_serial(url: str, serial: str | None) -> str:
    """A ``sim://`` or ``emu://`` URL naming the unit ``serial`` (``serial=``), unless it names
    a ``seed`` or a serial already or is another port; other URLs are returned as they are."""
    import urllib.parse as urlparse

    parts = urlparse.urlsplit(url)
    if serial is None or parts.scheme.lower() not in ("sim", "emu"):
        return url
    opts = urlparse.parse_qs(parts.query, keep_blank_values=True)
    if "seed" in opts or "serial" in opts:
        return url
    query = urlparse.urlencode({"serial": serial})
    return f"{url}&{query}" if parts.query else f"{url.rstrip('?')}?{query}"


def _int(text: str) -> int:
    """Decimal (``007`` too), or with a base prefix (``0x10``)."""
    return int(text, 0) if text[1:2].lower() in ("x", "o", "b") else int(text)


@dataclass(frozen=True)
class SimOptions:
    """The simulator's options of a ``sim://`` or ``emu://`` URL."""

    seed: int = 0  # the unit: its truth and room
    speed: float | None = None  # None: max; else simulated s per wall s
    truth: str = "random"  # random | ideal
    effects: tuple[str, ...] | None = None
    operator: str = "auto"  # auto | manual
    latitude_deg: float = 55.75
    tilt_deg: float = 0.0
    earth_rate: bool = True
    operator_faults: tuple[tuple[str, float], ...] = ()  # (name, K) for operator.CubeOperator
    chamber: tuple[tuple[str, float], ...] = ()  # Environment chamber fields (parse_chamber)
    cable_pull_s: float | None = None  # sim:// only: fault=pull_cable@S
    product_id: int = DEFAULT_PRODUCT_ID  # the chip's PRODUCT_ID (revision=)
    self_test_fail: bool = False  # the part fails its self-test (self_test=fail)
    cube: int | None = None  # the cube the board is in (cube=); None: a bench of its own
    slot: int = 0  # its place in the cube (slot=)
    noise_seed: int | None = None  # the noise and the operator; None: fresh in every session

    def draw(self) -> BenchDraw:
        """The sensor, room and bench of these options, and the seeds of the noise and the
        operator (the same draw on both schemes)."""
        from host.bench.physics import Bench, Environment
        from host.bench.truth import SensorTruth

        truth_ss, env_ss, _, _ = np.random.SeedSequence(self.seed).spawn(4)
        # noise_seed == seed draws what one seed drew before the two were told apart
        _, _, noise_ss, op_ss = np.random.SeedSequence(self.noise_seed).spawn(4)
        truth = (
            SensorTruth.random(np.random.default_rng(truth_ss))
            if self.truth == "random"
            else SensorTruth.ideal()
        )
        if self.effects is not None:
            truth = truth.only(*self.effects)
        cube_ss = None
        if self.cube is not None:  # the cube's geometry is there whatever the unit's effects
            from host.bench.cube import hand_seed, in_cube

            truth, cube_ss = in_cube(truth, self.cube, self.slot), hand_seed(self.cube)
        env = Environment.random(np.random.default_rng(env_ss))
        if self.chamber:
            c = dict(self.chamber)
            env = dataclasses.replace(
                env,
                chamber_from_c=c["chamber_from_c"],
                chamber_to_c=c["chamber_to_c"],
                chamber_minutes=c["chamber_minutes"],
                chamber_start_s=c["chamber_start_s"],
            )
        return BenchDraw(
            truth,
            env,
            Bench(
                latitude_deg=self.latitude_deg, tilt_deg=self.tilt_deg, earth_rate=self.earth_rate
            ),
            noise_ss,
            op_ss,
            cube_ss,
        )


@dataclass(frozen=True)
class BenchDraw:
    """What :meth:`SimOptions.draw` draws from the seed."""

    truth: SensorTruth
    environment: Environment
    bench: Bench
    noise_ss: np.random.SeedSequence
    operator_ss: np.random.SeedSequence
    #: the hand of the cube's operator (``cube=``; :func:`host.bench.cube.hand_seed`), else None
    cube_ss: np.random.SeedSequence | None = None


_T = TypeVar("_T")


def _option(key: str, parse: Callable[[], _T]) -> _T:
    """``parse()``'s value; its ValueError as an :class:`OptionError` naming option ``key``."""
    try:
        return parse()
    except ValueError as exc:
        raise OptionError(key, str(exc)) from None


def _speed(text: str) -> float | None:
    """``speed=``: ``realtime`` (1), ``max`` (None) or simulated s per wall s."""
    speed = text.lower()
    if speed == "realtime":
        return 1.0
    return None if speed == "max" else bounded("speed", speed, *SPEED_RANGE)


def _choice(key: str, text: str, allowed: tuple[str, str]) -> str:
    """``text`` lowercased, one of the two ``allowed``; ValueError otherwise."""
    value = text.lower()
    if value not in allowed:
        raise ValueError(f"{key} must be {allowed[0]} or {allowed[1]}, not {value!r}")
    return value


def _faults(
    opts: Mapping[str, Sequence[str]], fault_is_operator: bool
) -> tuple[tuple[tuple[str, float], ...], float | None]:
    """(the operator's faults (name, K), the cable's pull time s or None) of ``operator_fault=``
    (and of ``fault=`` where it is the operator's, ``fault_is_operator``)."""
    from host.bench.operator import OPERATOR_FAULTS

    faults: list[tuple[str, float]] = []
    cable: float | None = None
    sources: list[tuple[str, tuple[str, ...]]] = [("operator_fault", OPERATOR_FAULTS)]
    if fault_is_operator:
        sources.insert(0, ("fault", (*OPERATOR_FAULTS, CABLE_FAULT)))
    for key, known in sources:
        for text in opts.get(key, []):
            name, _, arg = text.partition("@")
            if name not in known:
                raise OptionError(key, f"unknown fault {name!r}; known: {', '.join(known)}")
            try:
                k = bounded(f"{key}={name}@", arg, 0.0, 1e6) if arg else None
            except ValueError as exc:
                raise OptionError(key, str(exc)) from None
            if name == CABLE_FAULT:
                cable = 5.0 if k is None else k
            else:
                faults.append((name, 1.0 if k is None else k))
    return tuple(faults), cable


def _seeds(opts: Mapping[str, Sequence[str]]) -> tuple[int, int | None]:
    """(the unit seed: ``seed``, else :func:`unit_seed` of ``serial``, else 0; the noise seed:
    ``noise_seed``, else None, fresh noise); :class:`OptionError` naming a bad one."""
    serial = opts.get("serial", [""])[-1]
    seeds: list[int | None] = []
    for key in ("seed", "noise_seed"):
        try:
            seeds.append(_int(opts[key][-1]) if key in opts else None)
        except ValueError as exc:
            raise OptionError(key, str(exc)) from None
    unit, noise = seeds
    if unit is None:
        unit = unit_seed(serial) if serial else 0
    return unit, noise


def parse_sim_options(
    opts: Mapping[str, Sequence[str]], speed_default: str, fault_is_operator: bool
) -> SimOptions:
    """:data:`KEYS` of parsed query ``opts`` (``urllib.parse.parse_qs``; the last value of a key
    wins) -> :class:`SimOptions`; :class:`OptionError` naming the bad option (the first, in the
    order read here).

    ``speed_default``: ``realtime`` or ``max``. ``fault_is_operator``: ``fault=`` is the old
    spelling of ``operator_fault=`` plus the cable fault (``sim://``).
    """

    def one(key: str, default: str) -> str:
        return opts.get(key, [default])[-1]

    seed, noise_seed = _seeds(opts)
    speed = _option("speed", lambda: _speed(one("speed", speed_default)))
    truth = _option("truth", lambda: _choice("truth", one("truth", "random"), ("random", "ideal")))
    operator = _option(
        "operator", lambda: _choice("operator", one("operator", "auto"), ("auto", "manual"))
    )
    effects = tuple(e for e in one("effects", "").split(",") if e) if "effects" in opts else None
    latitude = _option("latitude", lambda: bounded("latitude", one("latitude", "55.75"), -90, 90))
    tilt = _option("tilt", lambda: bounded("tilt", one("tilt", "0"), -90.0, 90.0))
    chamber = (
        _option("chamber", lambda: tuple(parse_chamber(one("chamber", "")).items()))
        if "chamber" in opts
        else ()
    )
    product_id = _option("revision", lambda: parse_revision(one("revision", "D8")))
    self_test_fail = _option("self_test", lambda: parse_self_test(one("self_test", "pass")))
    faults, cable = _faults(opts, fault_is_operator)
    earth = one("earth_rate", "1").lower() not in ("0", "false", "no")
    cube, slot = _cube(opts)
    return SimOptions(seed, speed, truth, effects, operator, latitude, tilt, earth, faults, chamber,
                      cable, product_id, self_test_fail, cube, slot, noise_seed)  # fmt: skip


def _whole(key: str, text: str, lo: int, hi: int) -> int:
    """``text`` as a whole number in [lo, hi]; :class:`OptionError` naming ``key`` otherwise."""
    try:
        value = _int(text)
    except ValueError:
        raise OptionError(key, f"{key}={text!r} is not a whole number") from None
    if not lo <= value <= hi:
        raise OptionError(key, f"{key}={text!r} is outside {lo} … {hi}")
    return value


def _cube(opts: Mapping[str, Sequence[str]]) -> tuple[int | None, int]:
    """(``cube=``: the cube's number, None without one; ``slot=``: the board's place in it, 0
    by default) -> :class:`OptionError` for a bad one, or a slot without a cube."""
    from host.bench.cube import SLOTS

    cube = _whole("cube", opts["cube"][-1], 0, CUBE_MAX) if "cube" in opts else None
    if "slot" not in opts:
        return cube, 0
    slot = _whole("slot", opts["slot"][-1], 0, SLOTS - 1)
    if cube is None:
        raise OptionError("slot", f"slot={slot} needs a cube: add cube=C, the cube it is in")
    return cube, slot


def parse_self_test(text: str) -> bool:
    """``self_test=pass|fail`` -> whether the part fails its self-test; ValueError otherwise."""
    value = text.lower()
    if value not in ("pass", "fail"):
        raise ValueError(f"self_test must be pass or fail, not {text!r}")
    return value == "fail"


def parse_revision(text: str) -> int:
    """``revision=``: ``C4``, ``C5``, ``D6`` … ``D10`` (``ES C4`` … for engineering samples) or a
    PRODUCT_ID number (``0x55``) -> the PRODUCT_ID the virtual chip reads; ValueError otherwise."""
    return product_id_of(text)


def parse_chamber(text: str) -> dict[str, float]:
    """'FROM:TO:MINUTES[@START_S]' -> the chamber fields of :class:`Environment`."""
    ramp, _, start = text.partition("@")
    parts = ramp.split(":")
    if len(parts) != 3:
        raise ValueError(
            f"chamber: expected FROM:TO:MINUTES[@START_S] (e.g. -10:50:60), not {text!r}"
        )
    lo = bounded("chamber FROM", parts[0], -60.0, 130.0)
    hi = bounded("chamber TO", parts[1], -60.0, 130.0)
    minutes = bounded("chamber MINUTES", parts[2], 0.01, 10000.0)
    t0 = bounded("chamber START_S", start, 0.0, 1e7) if start else 0.0
    return {
        "chamber_from_c": lo,
        "chamber_to_c": hi,
        "chamber_minutes": minutes,
        "chamber_start_s": t0,
    }
