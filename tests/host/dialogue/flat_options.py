"""The dialogue's options from one flat set of keywords (tests name what they set, not which
part of :class:`host.dialogue.options.DialogueOptions` holds it): each keyword goes to the part
that has a field of its name (``noise`` is the compute settings' ``noise_file``)."""

from __future__ import annotations

import dataclasses
import shlex
from types import SimpleNamespace
from typing import Any

from host.dialogue.options import DialogueOptions

#: the parts of DialogueOptions, by the name of their field
PARTS = ("files", "schedule", "planning", "compute", "provenance", "link")
RENAMED = {"noise": "noise_file"}
#: fields no test sets by their flat name (the dialogue's turns are its schedule's)
HIDDEN = {("compute", "turns")}


def _names(o: DialogueOptions, part: str) -> list[str]:
    fields = dataclasses.fields(getattr(o, part))
    return [f.name for f in fields if (part, f.name) not in HIDDEN]


def flat_options(**kw: Any) -> DialogueOptions:
    """DialogueOptions with ``kw`` set, wherever each lives."""
    top = {f.name for f in dataclasses.fields(DialogueOptions)} - set(PARTS)
    base = DialogueOptions()
    parts: dict[str, dict[str, Any]] = {p: {} for p in PARTS}
    direct: dict[str, Any] = {}
    for key, value in kw.items():
        key = RENAMED.get(key, key)
        if key in top:
            direct[key] = value
            continue
        owner = [p for p in PARTS if key in _names(base, p)]
        assert len(owner) == 1, f"{key}: no part of DialogueOptions has it"
        parts[owner[0]][key] = value
    made = {p: dataclasses.replace(getattr(base, p), **v) for p, v in parts.items() if v}
    return dataclasses.replace(base, **direct, **made)


def flat_fields(o: DialogueOptions) -> dict[str, Any]:
    """Every value of ``o`` by its flat keyword."""
    flat: dict[str, Any] = {}
    for p in PARTS:
        flat |= {name: getattr(getattr(o, p), name) for name in _names(o, p)}
    flat |= {f: getattr(o, f) for f in ("port", "yes", "json")}
    flat["noise"] = flat.pop("noise_file")
    return flat


def flat(o: DialogueOptions) -> SimpleNamespace:
    """``o``'s values by their flat names (``flat(o).redo``), to read."""
    return SimpleNamespace(**flat_fields(o))


def with_options(o: DialogueOptions, **kw: Any) -> DialogueOptions:
    """``o`` with ``kw`` set, wherever each lives."""
    return flat_options(**{**flat_fields(o), **kw})


def options_of(command: str) -> DialogueOptions:
    """The DialogueOptions a printed ``python3 -m host calibrate ...`` command line gives, read
    as a POSIX shell would split it (by the command's own reading of its arguments)."""
    from host.__main__ import build_parser
    from host.cli.calibrate import dialogue_options

    argv = shlex.split(command)
    assert argv[:4] == ["python3", "-m", "host", "calibrate"], command
    parser, _ = build_parser()
    return dialogue_options(parser.parse_args(argv[3:]))
