"""Three sessions of one virtual unit repeat like a real unit's (issue 45 item 3, its "Done
when"): each ``calibrate --serial`` of a ``sim://`` board measures the unit of that serial again
with fresh noise, so ``archive repeat`` sees the scatter the noise gives — over 20 units' triples
the χ² p of each parameter lies between 0.01 and 0.99 in at least 17 — and a session given the
noise seed of an earlier one is named as no repeat.

The sessions are short (2 s faces, one turn each way) and fitted on the linear model with the
effects outside it switched off (``effects=linear,noise&earth_rate=0``), so that the σ of each
fit is the σ the noise gives. Each session names a noise seed of its own (``noise_seed``, 60
different ones): the noise differs from session to session as fresh noise would, and the test
reads the same numbers on every run (with fresh noise, about 2 % of runs would see 4 of 20
triples outside for one of the 33 parameters by chance alone)."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from host.archive import checks
from host.archive.store import Archive, archive_directory
from host.board.link import open_port
from host.dialogue import flow
from host.dialogue.console import ScriptedConsole
from tests.host.dialogue.flat_options import flat_options

URL = "sim://?speed=max&effects=linear,noise&earth_rate=0"
UNITS = 20


def _calibrate(tmp: Path, db: str, serial: str, url: str = URL) -> Any:
    """One ``calibrate --yes`` session of ``serial`` on ``url``, archived in ``db``; the
    truth of the board it opened."""
    out = tmp / f"{serial}_{len(list(tmp.glob(serial + '_*')))}"
    opened: list[Any] = []

    def ports(u: str) -> Any:
        opened.append(open_port(u))
        return opened[-1]

    o = flat_options(port=url, serial=serial, out=out, static_seconds=2.0, turns=1,
                     warmup_s=0.0, yes=True, ready_s=0.0)  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()):
        assert flow.run_dialogue(o, ScriptedConsole(), ports) in (0, 1)
    archive_directory(out, db)
    return opened[0].truth


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_three_sessions_of_a_virtual_unit_scatter_as_the_noise_says(tmp_path: Path) -> None:
    db = str(tmp_path / "a.sqlite")
    p: dict[str, list[float]] = {}
    units = []
    for k in range(UNITS):
        serial = f"R{k:02d}"
        truths = [_calibrate(tmp_path, db, serial, f"{URL}&noise_seed={1000 + 3 * k + i}")
                  for i in range(3)]  # fmt: skip
        assert truths[0] == truths[1] == truths[2]  # one unit, three times
        units.append(repr(truths[0]))
        with Archive(db) as a:
            assert checks.identical_repeats(a, serial) == []
            for r in checks.repeat(a, serial):
                assert r.n == 3 and r.dof == 2
                p.setdefault(r.name, []).append(r.p)
    inside = {name: int(np.sum((np.array(ps) > 0.01) & (np.array(ps) < 0.99))) for name, ps in
              p.items()}  # fmt: skip
    below = sum(x <= 0.01 for ps in p.values() for x in ps)
    above = sum(x >= 0.99 for ps in p.values() for x in ps)
    print(f"p in (0.01, 0.99), of {UNITS} triples, per parameter: {inside}; p <= 0.01: "
          f"{below}, p >= 0.99: {above}")  # fmt: skip
    assert all(len(ps) == UNITS for ps in p.values())
    assert min(inside.values()) >= 17, inside
    assert len(set(units)) == UNITS  # twenty serials are twenty units, not one


@pytest.mark.slow
def test_a_session_with_an_earlier_ones_noise_is_named(tmp_path: Path) -> None:
    db = str(tmp_path / "a.sqlite")
    _calibrate(tmp_path, db, "N1", URL + "&noise_seed=3")
    _calibrate(tmp_path, db, "N1")
    with Archive(db) as a:
        assert checks.identical_repeats(a, "N1") == []
    _calibrate(tmp_path, db, "N1", URL + "&noise_seed=3")
    with Archive(db) as a:
        ids = [s.id for s in a.summaries()]
        found = checks.identical_repeats(a, "N1")
    assert [(r.earlier, r.later, r.what) for r in found] == [(ids[0], ids[2], "every value and σ")]
