"""The design's columns of a term that gives its three channels at once (host/model/design.py,
``Term.columns_all``): the same columns as one channel at a time, record by record."""

from __future__ import annotations

import dataclasses

import numpy as np

from host.model.catalogue import CATALOGUE
from host.model.dataset import build_dataset, session_from_records
from host.model.design import term_columns
from host.model.spec import ModelTerm
from host.workbench.scenarios import hidden_effect_case


def test_three_channels_at_once_are_each_channels_own_columns() -> None:
    """On turns and statics, the plate's tilt and the lever arm built from one computation per
    record equal the same terms built one channel at a time (a channel or a record mixed up
    would move a column)."""
    ds = build_dataset(session_from_records(hidden_effect_case("lever_arm", seed=2).records))
    at_once = [t for t in CATALOGUE.values() if t.columns_all is not None]
    assert {t.name for t in at_once} == {"plate_tilt", "lever_arm"}
    for t in at_once:
        mt = ModelTerm(t, "accel", (0, 1, 2))
        x, off = term_columns(ds, mt)
        one = ModelTerm(dataclasses.replace(t, columns_all=None), "accel", (0, 1, 2))
        y, off1 = term_columns(ds, one)
        assert np.any(x != 0.0)
        assert np.array_equal(x, y) and np.array_equal(off, off1)
