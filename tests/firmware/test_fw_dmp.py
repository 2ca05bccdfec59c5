"""DMP mode: a user-supplied image is embedded at build time (never committed)."""

from __future__ import annotations

import os
import subprocess

import pytest
from fwbuild import FIRMWARE, ROOT, Build, make

#: the described images (firmware/src/dmp_descriptions.h) and their sizes in bytes
DMP_SIZES = {"motionapps20": 1929, "emd6": 3062}


@pytest.mark.parametrize("kind", sorted(DMP_SIZES))
@pytest.mark.slow
def test_dmp_build_embeds_image(avr_toolchain, default_build: Build, tmp_path, kind) -> None:
    image = os.urandom(DMP_SIZES[kind])  # stand-in for InvenSense's image: random, right size
    path = tmp_path / "dummy_dmp.bin"
    path.write_bytes(image)
    build = make(tmp_path / "dmp", f"DMP_IMAGE={path}", f"DMP_KIND={kind}")
    assert build.ok, build.output
    text = build.section(".text")
    assert image in text, "image bytes not found contiguous in flash"
    assert image not in default_build.section(".text")
    assert build.identity()["mode"] == 1  # HELLO.mode = DMP
    flash, ram = build.sizes()
    default_flash, _ = default_build.sizes()
    assert flash >= default_flash + len(image)
    assert flash < 16 * 1024 and ram < 4 * 1024
    # The generated header goes to the build directory, never into the source tree.
    assert (tmp_path / "dmp" / "dmp_image.h").exists()
    assert not list((FIRMWARE / "src").glob("dmp_image*"))


def test_dmp_image_of_the_wrong_kind_or_an_unknown_kind_is_refused(avr_toolchain, tmp_path):
    image = tmp_path / "ma20.bin"
    image.write_bytes(os.urandom(DMP_SIZES["motionapps20"]))
    r = make(tmp_path / "a", f"DMP_IMAGE={image}", "DMP_KIND=emd6")
    assert not r.ok and "DMP_IMAGE is not the size of the DMP_KIND image" in r.output
    r = make(tmp_path / "b", f"DMP_IMAGE={image}", "DMP_KIND=motionapps41")
    assert not r.ok and "DMP_KIND must be motionapps20 or emd6" in r.output


def test_dmp_image_problems_are_refused(avr_toolchain, tmp_path) -> None:
    missing = make(tmp_path / "a", f"DMP_IMAGE={tmp_path / 'nope.bin'}")
    assert not missing.ok
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    assert not make(tmp_path / "b", f"DMP_IMAGE={empty}").ok
    huge = tmp_path / "huge.bin"
    huge.write_bytes(bytes(5000))
    r = make(tmp_path / "c", f"DMP_IMAGE={huge}")
    assert not r.ok and "4096" in r.output


def test_no_dmp_image_is_tracked() -> None:
    tracked = subprocess.run(
        ["git", "ls-files", "firmware"], cwd=ROOT, capture_output=True, text=True
    ).stdout.split()
    assert not [f for f in tracked if f.endswith(".bin") or f.endswith("dmp_image.h")]
    assert (FIRMWARE / "dmp" / "README.md").exists()
