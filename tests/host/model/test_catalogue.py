"""The built-in terms (host/model/catalogue.py): each defined once, whole at its definition."""

from __future__ import annotations

import ast
from pathlib import Path

from host.model import catalogue

SOURCE = Path(catalogue.__file__)


def test_no_name_of_the_catalogue_is_bound_twice() -> None:
    """A term rebound after its definition (``face_error = replace(face_error, …)``) reads as
    one thing where it is defined and is another: every module-level name is bound once."""
    seen: dict[str, int] = {}
    twice = []
    for node in ast.parse(SOURCE.read_text()).body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names = [node.name]
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names = [t.id for t in targets if isinstance(t, ast.Name)]
        else:
            continue
        for name in names:
            if name in seen:
                twice.append(f"{name} (lines {seen[name]} and {node.lineno})")
            seen[name] = node.lineno
    assert twice == []


def test_the_terms_carry_what_their_definitions_give() -> None:
    """The decorator's twin, own unknowns and all-channel columns reach the catalogue's terms:
    a face's lean on the gyro, a turn's angle on the gyro, a pose's attitude on the
    accelerometer, the plate's tilt seen by
    a record at an unknown heading, and the lever arm and plate read three channels at once."""
    cat = catalogue.CATALOGUE
    assert cat["face_error"].twin_sensor == "gyro" and cat["face_error"].twin_columns
    assert cat["scale"].record_params == ("turn_angle",) and cat["scale"].record_sensor == "gyro"
    assert cat["misalignment"].record_params == ("attitude_a", "attitude_b")
    assert cat["misalignment"].record_sensor == "accel"
    assert cat["plate_tilt"].record_params == ("seen_ref", "seen_side", "heading")
    assert cat["plate_tilt"].record_params_of is not None
    assert cat["plate_tilt"].columns_all is not None and cat["lever_arm"].columns_all is not None
    assert all(not t.twin_sensor for n, t in cat.items() if n != "face_error")
