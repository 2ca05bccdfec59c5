"""The golden corpus: damaged captures decode to exactly the counters their damage implies."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from host.wire.bulk import decode_bulk
from host.wire.stream import StreamDecoder

CORPUS = Path(__file__).resolve().parents[2] / "captures"
TABLE = json.loads((CORPUS / "corpus.json").read_text())


@pytest.mark.parametrize("name", sorted(TABLE))
def test_corpus_file_decodes_to_its_expected_counters(name: str) -> None:
    data = (CORPUS / name).read_bytes()
    expected = TABLE[name]["expect"]
    assert decode_bulk(data).stats.as_dict() == expected, TABLE[name]["damage"]
    d = StreamDecoder()
    for i in range(0, len(data), 61):  # an awkward read size
        d.feed(data[i : i + 61])
    d.flush()
    assert d.stats.as_dict() == expected


def test_corpus_is_the_one_the_script_writes(tmp_path: Path) -> None:
    """corpus.json and the BAD files are regenerated from clean.bin by make_corpus.py."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_corpus", CORPUS / "make_corpus.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    built = mod.build((CORPUS / "clean.bin").read_bytes())
    assert sorted(built) == sorted(TABLE)
    for name, (data, counts, _) in built.items():
        assert (CORPUS / name).read_bytes() == data, name
        assert TABLE[name]["expect"] == counts
